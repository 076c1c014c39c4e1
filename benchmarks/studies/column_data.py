"""The column data: a cobot hanging on the side of a lifting column, measured by a total station, as casadical files.

The data are Hilti's construction robot stationing datasets (github Hilti-Research/construction_robot_stationing_
datasets; CC BY-NC-SA 3.0: fetch them and convert them on your machine, never commit them or what this script
writes). Trailblazer, a prototype of the Hilti JaiBot: a tracked base, a lifting column, a Doosan 6-axis arm
(M1013 link lengths, 0.62 and 0.559 m) bolted to the column's top plate with its joint 1 axis horizontal, a prism on
its tool, a total station (Hilti PLT 300, levelled: its z up) and two ADXL355 accelerometers, one on the column's
rigid base and one at its tip. ``flat.yaml`` is their calibration set: about 450 waypoints at five column heights,
on a level floor at 21 deg C.

What one record holds (``include/measurement.py`` of that repository reads the same fields):

- ``joint_states``: the column's reading (``column_prismatic_joint``, m: the column's extension, its two
  segments mimic it in the URDF), then ``dsr_joint1`` .. ``dsr_joint6`` (rad);
- ``prism_position``: the prism's centre measured by the total station, in its frame (m);
- ``tilt_sensor_base_accel``, ``tilt_sensor_column_accel``: each accelerometer's reading (m/s^2) in its own
  frame, which the URDF puts parallel to the column base's and to the column tip's (``tilt_sensor_base``,
  ``tilt_sensor_column_tip``): at rest they read gravity's reaction, about (0, 0, 9.807), its x and y parts
  the sensor's tilt times g;
- ``time`` (unix s), ``upside_down`` (the tool turned over), ``doosan_cmd`` (the Cartesian target, m), ``id``.

Records are grouped by column height, then by the arm's solution space (0 and 7; 4: upside down, measured at the
end, after the column had been at every height: its column readings differ from the others' of that height by 0.4
to 7.5 mm), then into stationing and evaluation points.

What this script writes into OUT (one session per column height, rows in time order):

- ``c_<height>.csv`` (``c_1.98.csv`` ...): casadical measurement files (docs/formats.md section 2): ``q1_deg`` ..
  ``q6_deg`` (the arm's joints), ``x_mm, y_mm, z_mm`` (the prism, total station frame), ``time_s`` (s since the
  file's first record), ``session`` (``c_<height>``), and columns casadical keeps without reading them today: the
  session covariate ``height_m`` (the column height the dataset names the station by, constant in the session), the
  per-pose sensors ``acc_base_x``, ``acc_base_y``, ``acc_base_z``, ``acc_column_x``, ``acc_column_y``,
  ``acc_column_z`` (m/s^2, sensor frames), ``column_m`` (the column's own reading, m), ``solution_space``,
  ``upside_down`` (0 or 1), ``stationing`` (1 for a stationing point, 0 for an evaluation point), ``record``
  (the record's id);
- ``column_arm.toml``: the arm as a casadical robot (docs/formats.md section 1), read from the dataset's URDF by
  casadical's URDF reader with the base link ``column_tip_mount`` (the column's top plate: level, z up along the
  column, the arm bolted on its side) and the tip ``prism``: MDH rows, joint 1's axis horizontal (``alpha_deg`` 90
  on its row), each joint's mass and centre of mass merged from the URDF's inertials (the tool's 3 kg with joint
  6), gravity **right**, down the column (the URDF root's -z). The base frame sits on the column's axis at its top,
  where the column bends: the moment of the weights about it is the one that bends the column, and its z is
  vertical, as the mount compliance and the structure screen's base tilt (about the base's x and y) expect;
- ``column_arm_upright.toml``: the arm alone, read with its own base link ``dsr_base_0`` (its z is joint 1's axis),
  with gravity along that z, as a description of the arm alone (the arm maker's URDF) has it: the **wrong** gravity
  for this mounting, 90 deg off.

The robot files are written here, from the fetched URDF, and not committed: they are derived from the dataset's URDF
(its prism offset, its tool mass, the arm's inertials), which is under the dataset's licence, and the arm is not a
robot casadical ships (problems/ holds those). The script checks them against the URDF's own forward kinematics
(yourdfpy, joint by joint from the XML) at every record, read by the tests' independent forward model (tests/truth),
before it writes anything.

Usage::

    python benchmarks/studies/column_data.py PATH/flat.yaml OUT/ [--urdf PATH/trailblazer.urdf] [--force]

(the URDF defaults to ``data/trailblazer.urdf`` beside ``data/datasets/``, as in that repository).
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.append(str(ROOT))  # the tests' helpers as ``tests.helpers``, after any casadical on PYTHONPATH

from casadical.loading import load_robot  # noqa: E402
from casadical.robot import robot_to_dict  # noqa: E402
from tests.helpers.arms import to_toml  # noqa: E402

#: the URDF links: the column's top plate (the right robot file's base: level, z up, the column's axis), the arm's
#: own base (where it is bolted on the plate's side: its z is joint 1's axis, horizontal), the measured point
PLATE_LINK, ARM_LINK, TIP_LINK = "column_tip_mount", "dsr_base_0", "prism"
#: the dataset's joint order (``joint_names``)
COLUMN_JOINT = "column_prismatic_joint"
ARM_JOINTS = tuple(f"dsr_joint{i}" for i in range(1, 7))
#: the robot files written beside the measurement files
ROBOT_FILE, UPRIGHT_FILE = "column_arm.toml", "column_arm_upright.toml"
SENSORS = ("acc_base_x", "acc_base_y", "acc_base_z", "acc_column_x", "acc_column_y", "acc_column_z")
#: the URDF's forward kinematics and the robot file's must agree to this (m) at every record
FK_TOL_M = 1e-6


@dataclass
class Record:
    """One waypoint of the dataset."""

    height: float           # m, the station's column height (its key in the file)
    solution_space: int
    stationing: bool
    id: int
    time: float             # unix s
    upside_down: bool
    column: float           # m, the column's reading
    q: np.ndarray           # rad, dsr_joint1..6
    prism: np.ndarray       # m, total station frame
    acc_base: np.ndarray    # m/s^2
    acc_column: np.ndarray  # m/s^2


def session_name(height: float) -> str:
    """The session of a column height: ``c_1.98``."""
    return f"c_{height:.2f}"


def read_records(path: Path) -> list[Record]:
    """Every record of a stationing dataset file (``flat.yaml`` and the others of that repository)."""
    try:
        import yaml
    except ImportError as e:
        raise SystemExit("reading the dataset needs PyYAML: pip install pyyaml") from e
    with open(path) as f:
        doc = yaml.safe_load(f)
    names = doc.get("joint_names") if isinstance(doc, dict) else None
    if names != [COLUMN_JOINT, *ARM_JOINTS]:
        raise SystemExit(f"{path}: joint_names are {names!r}, expected {[COLUMN_JOINT, *ARM_JOINTS]}: not a "
                         "stationing dataset of Trailblazer")
    out = []
    for height, station in doc["column_heights"].items():
        for space, kinds in station["solution_spaces"].items():
            for kind in ("stationing_measurements", "evaluation_measurements"):
                for m in kinds.get(kind) or []:
                    js = np.asarray(m["joint_states"], float)
                    out.append(Record(float(height), int(space), kind.startswith("stationing"), int(m["id"]),
                                      float(m["time"]), bool(m["upside_down"]), float(js[0]), js[1:],
                                      np.asarray(m["prism_position"], float),
                                      np.asarray(m["tilt_sensor_base_accel"], float),
                                      np.asarray(m["tilt_sensor_column_accel"], float)))
    return out


#: each robot file's base link in the URDF
BASE_OF = {ROBOT_FILE: PLATE_LINK, UPRIGHT_FILE: ARM_LINK}


def robot_files(urdf: Path) -> dict[str, dict]:
    """The arm's robot documents read from the URDF: on the column's top plate, gravity right (the URDF root's
    down: -z of the plate, the arm's joint 1 axis horizontal); and the arm alone (its own base, gravity down its
    joint 1 axis)."""
    doc = robot_to_dict(load_robot(urdf, tip=TIP_LINK, base=PLATE_LINK))
    doc["name"] = "Doosan arm on Trailblazer's lifting column (from trailblazer.urdf)"
    alone = robot_to_dict(load_robot(urdf, tip=TIP_LINK, base=ARM_LINK))
    alone.update(name="Doosan arm of Trailblazer alone (from trailblazer.urdf), gravity down joint 1's axis",
                 gravity={"direction": [0.0, 0.0, -1.0]})
    return {ROBOT_FILE: doc, UPRIGHT_FILE: alone}


def urdf_prism(urdf: Path, records: list[Record], base: str) -> tuple[np.ndarray, np.ndarray]:
    """The prism in the frame of the link ``base`` at each record, and the URDF root's down there, by yourdfpy's
    forward kinematics of the URDF itself (not casadical's reading of it)."""
    import yourdfpy
    u = yourdfpy.URDF.load(str(urdf), build_scene_graph=True, load_meshes=False)
    points = []
    for r in records:
        u.update_cfg({COLUMN_JOINT: r.column, **dict(zip(ARM_JOINTS, r.q))})
        points.append(u.get_transform(TIP_LINK, base)[:3, 3])
    down = u.get_transform(base, u.base_link)[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    return np.array(points), down


def check_robot(text: str, urdf: Path, records: list[Record], base: str) -> float:
    """The angle (deg) between the robot file's gravity and the URDF root's down, in the frame of the link
    ``base``; first, its prism (by the tests' independent forward model, tests/truth, its base pose applied)
    must be the URDF's at every record."""
    from tests.truth import Arm, TrueRobot
    from tests.truth import transforms as tf
    arm = Arm.from_toml(text)
    truth = TrueRobot(arm)
    placed = tomllib.loads(text)["base"]
    B = tf.pose(placed["xyz_m"], np.radians(placed["rpy_deg"]))[0]
    got = truth.tool_point(truth.state(np.array([r.q for r in records]))) @ B[:3, :3].T + B[:3, 3]
    expected, down = urdf_prism(urdf, records, base)
    down = B[:3, :3].T @ down           # in the robot's frame 0
    worst = float(np.max(np.linalg.norm(got - expected, axis=1)))
    off = math.degrees(math.acos(min(1.0, float(arm.gravity @ down) / np.linalg.norm(arm.gravity))))
    if worst > FK_TOL_M:
        raise SystemExit(f"{urdf}: the robot file's prism misses the URDF's by up to {worst * 1000:.4f} mm: the "
                         "URDF reader and the URDF disagree")
    return off


def rows(records: list[Record], t0: float) -> tuple[list[str], list[list[str]]]:
    """The measurement file of one session: header and rows in time order."""
    head = [f"q{j}_deg" for j in range(1, 7)] + ["x_mm", "y_mm", "z_mm", "time_s", "session", "height_m",
                                                 *SENSORS, "column_m", "solution_space", "upside_down",
                                                 "stationing", "record"]
    out = []
    for r in sorted(records, key=lambda r: r.time):
        values = [*np.degrees(r.q), *(r.prism * 1000.0), r.time - t0]
        out.append([repr(float(v)) for v in values]
                   + [session_name(r.height), repr(r.height)]
                   + [repr(float(v)) for v in (*r.acc_base, *r.acc_column, r.column)]
                   + [str(r.solution_space), str(int(r.upside_down)), str(int(r.stationing)), str(r.id)])
    return head, out


def convert(yaml_path: Path, out: Path, urdf: Path | None = None, force: bool = False,
            solution_spaces: tuple[int, ...] | None = None) -> dict[str, Path]:
    """Write the sessions' measurement files and the two robot files into ``out``; returns them by name (session
    names, then the robot files' names). ``solution_spaces``: keep these only (default: every one)."""
    yaml_path = Path(yaml_path)
    urdf = Path(urdf) if urdf is not None else yaml_path.resolve().parents[1] / "trailblazer.urdf"
    if not urdf.is_file():
        raise SystemExit(f"{urdf}: no such URDF; give the dataset's trailblazer.urdf with --urdf")
    records = read_records(yaml_path)
    t0 = min(r.time for r in records)
    if solution_spaces is not None:
        records = [r for r in records if r.solution_space in solution_spaces]
    docs = {name: to_toml(doc) for name, doc in robot_files(urdf).items()}
    off = {name: check_robot(text, urdf, records, BASE_OF[name]) for name, text in docs.items()}
    if off[ROBOT_FILE] > 0.01 or off[UPRIGHT_FILE] < 89.9:
        raise SystemExit(f"{urdf}: gravity {off[ROBOT_FILE]:.3f} deg off the URDF's in {ROBOT_FILE}, "
                         f"{off[UPRIGHT_FILE]:.3f} deg in {UPRIGHT_FILE} (expected 0 and 90)")
    texts: dict[str, tuple[Path, str]] = {}
    for height in sorted({r.height for r in records}):
        head, body = rows([r for r in records if r.height == height], t0)
        name = session_name(height)
        texts[name] = (out / f"{name}.csv", "\n".join(",".join(x) for x in [head] + body) + "\n")
    for name, text in docs.items():
        texts[name] = (out / name, text)
    clash = [str(p) for p, _ in texts.values() if p.exists()]
    if clash and not force:
        raise SystemExit(f"{clash[0]} exists: give --force to replace the converted files")
    out.mkdir(parents=True, exist_ok=True)
    for path, text in texts.values():
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text)
        tmp.replace(path)
    return {name: path for name, (path, _) in texts.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", type=Path, help="the dataset's flat.yaml (or another of its YAML files)")
    ap.add_argument("out", type=Path, help="folder for the measurement and robot files")
    ap.add_argument("--urdf", type=Path, help="the dataset's trailblazer.urdf (default: beside data/datasets/)")
    ap.add_argument("--solution-spaces", type=int, nargs="+", help="keep these solution spaces only (0, 7, 4)")
    ap.add_argument("--force", action="store_true", help="replace converted files in OUT")
    args = ap.parse_args()
    if not args.data.is_file():
        raise SystemExit(f"{args.data}: no such file")
    spaces = tuple(args.solution_spaces) if args.solution_spaces else None
    files = convert(args.data, args.out, args.urdf, args.force, spaces)
    for name, path in files.items():
        print(f"{name}: {path}")


if __name__ == "__main__":
    main()
