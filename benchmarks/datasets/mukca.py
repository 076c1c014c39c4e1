"""The MUKCa socket data (github platonics-delft/kinematics_calibration, MIT): read the raw files, convert them.

The peer records, per placement of its two-socket block (a folder such as
``data/panda_2/front_center``), ``hole_0.csv`` and ``hole_1.csv``: one row per
pose at which the ball on the flange sat in socket 0 (socket 1), the joint
readings in radians, comma separated, written by ``numpy.savetxt`` (``%.18e``,
no header). ``hole_0_pose.csv`` and ``hole_1_pose.csv`` hold the controller's
Cartesian pose at each recorded pose (x, y, z in m, quaternion w, x, y, z) and
are not converted: the recorder's "delete the last point" button removes the
joint row but not its pose row, so in three of panda_2's eighteen files they
have more rows than the joint files and cannot be matched row by row.

The converted file is the measurement CSV of docs/formats.md with the touch
column ``point`` (sections 2 and "what the tool touches"): ``q1_deg ..
qN_deg`` (radians times 180/pi, written with Python's ``repr``: the shortest
text that reads back to the same double) and ``point`` (``socket0``,
``socket1``); the rows of ``hole_0.csv`` in file order, then those of
``hole_1.csv``. No x/y/z: nothing measured where the ball was. The peer's
files do not say in which order the two sockets' poses were recorded, so the
row order is time order within a socket only.

    python benchmarks/datasets/mukca.py problems/datasets/panda-mukca

rewrites the converted files of the bundled panda_2 data from its ``raw/``
folder, ``panda_2_held_out.csv`` (every placement but ``front_center``) and
``panda_masses.urdf``: the nominal URDF with the Panda's published link masses
(:data:`PANDA_INERTIALS`), which a compliance needs (``--check``: compare
instead; exit 1 if any differs).
``tests/importers/test_mukca.py`` checks that the bundled files equal a fresh
conversion. Plain Python and numpy: nothing of casadical.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

#: the nine placements of panda_2's block, as the raw folders name them
PANDA2_PLACEMENTS = ("back_left", "back_right", "front_center", "front_left", "front_right", "high", "mid-high",
                     "mid_left", "mid_right")
#: socket file -> the ``point`` name of its rows
SOCKETS = {"hole_0.csv": "socket0", "hole_1.csv": "socket1"}
#: the block's two sockets, mm in the block's frame (the peer's ``--offset-distance`` default, 0.05 m)
SOCKET_DISTANCE_MM = 50.0
#: the peer's model (its ``urdf/NAME.urdf``, ``config_optimizer/NAME.yaml``) a user takes for each robot folder of
#: its data (its README); the others are Pandas
MODELS = {"kuka_14": "iiwa14", "dinova_1": "gen3lite", "dinova_2": "gen3lite", "panda_1_with_sensor": "panda_plus_bota"}


def model_of(robot: str) -> str:
    """The peer's model name for a robot folder of its data."""
    return MODELS.get(robot, "panda")


def front_placement(names) -> str:
    """The placement a user trains on first: the first ``front*`` one (sorted), else the first."""
    names = sorted(names)
    return next((n for n in names if n.startswith("front")), names[0])

FIXTURE_TOML = f"""\
# The MUKCa block (github platonics-delft/kinematics_calibration, stl/MUKCa_tool.stl): two spherical sockets
# {SOCKET_DISTANCE_MM:g} mm apart, 3D printed (0.08 mm layers); its authors found the printed distance within 0.1 mm
# of 50 with a caliper. Its pose in each placement (session) is unknown and estimated.
[[fixture]]
name = "two_sockets"
sd_mm = 0.05                  # how well the 50 mm is known: the caliper check's 0.1 mm as two standard deviations
[fixture.points]              # mm, in the block's frame
socket0 = [0.0, 0.0, 0.0]
socket1 = [{SOCKET_DISTANCE_MM!r}, 0.0, 0.0]
"""


#: The Panda's link masses (kg) and centres of mass (m, in each link's frame), for the gravity torques of a
#: compliance: franka_ros ``franka_description/robots/common/inertial.yaml`` (github frankaemika/franka_ros, Apache
#: 2.0), which takes them from Gaz, Cognetti, Oliva, Robuffo Giordano, De Luca, "Dynamic Identification of the
#: Franka Emika Panda Robot With Retrieval of Feasible Parameters Using Penalty-Based Optimization", IEEE RA-L 4(4),
#: 2019 (not Franka's official values, as the file says); the hand and its fingers are Franka Hand's. The ball and
#: whatever holds it are not weighed (a few grams of printed plastic).
PANDA_INERTIALS = {
    "panda_link1": (4.970684, (0.003875, 0.002081, -0.04762)),
    "panda_link2": (0.646926, (-0.003141, -0.02872, 0.003495)),
    "panda_link3": (3.228604, (2.7518e-02, 3.9252e-02, -6.6502e-02)),
    "panda_link4": (3.587895, (-5.317e-02, 1.04419e-01, 2.7454e-02)),
    "panda_link5": (1.225946, (-1.1953e-02, 4.1065e-02, -3.8437e-02)),
    "panda_link6": (1.666555, (6.0149e-02, -1.4117e-02, -1.0517e-02)),
    "panda_link7": (7.35522e-01, (1.0517e-02, -4.252e-03, 6.1597e-02)),
    "panda_hand": (0.73, (-0.01, 0.0, 0.03)),
    "panda_leftfinger": (0.015, (0.0, 0.0, 0.0)),
    "panda_rightfinger": (0.015, (0.0, 0.0, 0.0)),
}
#: the Panda URDF with its masses, beside the bundled data (made from ``raw/urdf/panda.urdf``)
PANDA_MASSES_URDF = "panda_masses.urdf"
#: every placement of panda_2 but ``front_center`` (the one the peer trained on), with their ``session`` column
HELD_OUT = "panda_2_held_out.csv"


def with_masses(urdf_text: str, inertials: dict = PANDA_INERTIALS) -> str:
    """``urdf_text`` with an ``<inertial>`` (mass and centre of mass; inertia tensors zero: casadical uses none)
    at the top of each link ``inertials`` names, and a comment saying where they come from; every other byte
    kept. Raises ValueError for a link the URDF lacks or one that has an ``<inertial>`` already."""
    import re

    out = urdf_text
    for link, (mass, com) in inertials.items():
        m = re.search(rf'<link name="{re.escape(link)}"\s*(/?)>', out)
        if m is None:
            raise ValueError(f"the URDF has no link {link!r}")
        end = out.find("</link>", m.end()) if not m.group(1) else m.end()
        if "<inertial" in out[m.end():end]:
            raise ValueError(f"link {link!r} has an <inertial> already")
        xyz = " ".join(repr(float(v)) for v in com)
        inertial = (f'\n    <inertial>\n      <origin rpy="0 0 0" xyz="{xyz}"/>\n      <mass value="{mass!r}"/>\n'
                    '      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>\n    </inertial>')
        tag = f'<link name="{link}">' + inertial + ("\n  </link>" if m.group(1) else "")
        out = out[:m.start()] + tag + out[m.end():]
    note = ("<!-- casadical: link masses and centres of mass added from franka_ros "
            "franka_description/robots/common/inertial.yaml\n     (Gaz et al., IEEE RA-L 2019); made by "
            "benchmarks/datasets/mukca.py from the nominal URDF, every other line as it is -->\n")
    head, sep, tail = out.partition("<robot")
    return head + note + sep + tail


class RawFileError(ValueError):
    """A raw file that is not as the peer writes it: names the file, the row (1-based line) and the column."""

    def __init__(self, path: Path, row: int, column: int | None, what: str):
        where = f"{path}, row {row}" + (f", column {column}" if column is not None else "")
        super().__init__(f"{where}: {what}")
        self.file, self.row, self.column = str(path), row, column


def read_socket_file(path: str | Path, joints: int | None = None) -> np.ndarray:
    """The joint readings (rad, (rows, joints)) of one ``hole_K.csv``; ``joints``: the number of columns expected
    (default: the first row's). Raises :class:`RawFileError` at the first row that is not a row of numbers."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise RawFileError(path, 1, None, f"cannot read: {e}") from e
    rows = []
    for i, line in enumerate(lines, 1):
        fields = line.split(",")
        if joints is None:
            joints = len(fields)
        if len(fields) != joints:
            raise RawFileError(path, i, min(len(fields), joints) + 1,
                               f"{len(fields)} fields where the file has {joints} joints")
        row = []
        for j, text in enumerate(fields, 1):
            try:
                value = float(text)
            except ValueError as e:
                raise RawFileError(path, i, j, f"not a number: {text!r}") from e
            if not math.isfinite(value):
                raise RawFileError(path, i, j, f"not a finite number: {text!r}")
            row.append(value)
        rows.append(row)
    if not rows:
        raise RawFileError(path, 1, None, "no rows")
    return np.array(rows)


def read_placement(folder: str | Path) -> dict[str, np.ndarray]:
    """``{"socket0": q, "socket1": q}`` (rad) of one placement folder (its ``hole_0.csv``, ``hole_1.csv``)."""
    folder = Path(folder)
    out: dict[str, np.ndarray] = {}
    for name, point in SOCKETS.items():
        out[point] = read_socket_file(folder / name, None if not out else next(iter(out.values())).shape[1])
    return out


def degrees(rad: float) -> float:
    """Radians to degrees in two correctly rounded operations (the same bits on every machine)."""
    return rad * 180.0 / math.pi


def placement_table(folder: str | Path, session: str | None = None) -> tuple[list[str], list[list[str]]]:
    """The header and rows (text) of one placement's measurement CSV; ``session``: add a ``session`` column."""
    sockets = read_placement(folder)
    n = next(iter(sockets.values())).shape[1]
    header = [f"q{j + 1}_deg" for j in range(n)] + ["point"] + (["session"] if session is not None else [])
    rows = []
    for point, q in sockets.items():
        for reading in q.tolist():
            rows.append([repr(degrees(v)) for v in reading] + [point] + ([session] if session is not None else []))
    return header, rows


def csv_text(header: list[str], rows: list[list[str]]) -> str:
    return "\n".join(",".join(r) for r in [header] + rows) + "\n"


def converted_files(raw_robot: str | Path, placements=PANDA2_PLACEMENTS, combined: str = "panda_2.csv"
                    ) -> dict[str, str]:
    """Relative path -> text of every converted file of one robot's raw folder (``raw/data/panda_2``):
    ``placements/NAME.csv`` per placement (one session per file, named after it), ``combined`` (every
    placement, its name in a ``session`` column) and the fixture ``two_sockets.toml``."""
    raw_robot = Path(raw_robot)
    out: dict[str, str] = {}
    header, every = None, []
    for name in placements:
        h, rows = placement_table(raw_robot / name)
        out[f"placements/{name}.csv"] = csv_text(h, rows)
        header = h + ["session"]
        every += [r + [name] for r in rows]
    out[combined] = csv_text(header, every)
    out["two_sockets.toml"] = FIXTURE_TOML
    return out


def convert_dataset(dataset: str | Path, check: bool = False) -> list[str]:
    """Write (or with ``check`` compare) the converted files of the bundled panda_2 data in ``dataset`` (the folder
    holding ``raw/``); returns the files written, or those that differ from a fresh conversion."""
    dataset = Path(dataset)
    files = converted_files(dataset / "raw" / "data" / "panda_2")
    files[PANDA_MASSES_URDF] = with_masses((dataset / "raw" / "urdf" / "panda.urdf").read_text())
    # the eight placements the peer's calibrated URDF never saw, in one file: the README job's --validate
    lines = files["panda_2.csv"].splitlines(keepends=True)
    files[HELD_OUT] = "".join([lines[0]] + [x for x in lines[1:] if not x.rstrip("\n").endswith(",front_center")])
    changed = []
    for rel, text in files.items():
        path = dataset / rel
        if check:
            if not path.exists() or path.read_text() != text:
                changed.append(rel)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(text)
        tmp.replace(path)
        changed.append(rel)
    return changed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path, help="the dataset folder, e.g. problems/datasets/panda-mukca")
    ap.add_argument("--check", action="store_true", help="compare with a fresh conversion instead of writing")
    args = ap.parse_args(argv)
    try:
        changed = convert_dataset(args.dataset, check=args.check)
    except RawFileError as e:
        print(f"mukca.py: error: {e}", file=sys.stderr)
        return 2
    if args.check:
        print("\n".join(f"differs: {c}" for c in changed) or "every converted file equals a fresh conversion")
        return 1 if changed else 0
    print("\n".join(f"wrote {args.dataset / c}" for c in changed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
