"""Study: the bar for calibration from touches, on the peer's real socket data (MUKCa), measured independently.

MUKCa (github platonics-delft/kinematics_calibration, MIT) calibrates a URDF
from a ball on the flange held in two sockets 50 mm apart, ~30 poses each,
at several placements of the block (one folder ``data/ROBOT/PLACEMENT`` per
placement). For every robot folder with socket data and every placement,
this prints for the nominal URDF (the one a user of the repository would
start from) and for the peer's calibrated URDF (trained on one placement):

- **consistency** (mm): the mean distance of the predicted ball points from
  their socket's mean point, over both sockets' rows (the peer's
  ``mean_absolute_error`` of ``calibrate_fk/utils.py:evaluate_model``);
- **distance error** (mm): ``| |mean0 - mean1| - 50 mm |``;

marking the placement the peer trained on (``*``: from its ``config.yaml``;
``?``: not recorded, taken as the placement where the calibrated URDF is
most consistent), and per robot the means over the placements it never saw.

The forward model is this file's own (``UrdfChain``: ElementTree and numpy
from the URDF's joint origins and axes), checked at every row against
yourdfpy the way the peer evaluates (``update_cfg`` with the readings padded
with zeros, ``get_transform(base_link, "ball_link")``) to 1e-9 m, and against
the ball points the peer stored in ``calibrated_urdf/panda_6|7/kpis.yaml``.

The third column is casadical's own calibration on the same training
placement (:func:`casadical_model`: the library as a user calls it, the
block as a fixture file), its model chosen on that placement alone: the
candidates of :data:`CANDIDATES` (the complete geometry; where the robot
file weighs its links, a joint or a bearing giving way under the weights:
the Pandas get their published masses, ``mukca.with_masses``) each fitted
to four fifths of the training rows and judged on the fifth left out, five
times (blocks of recording order, :func:`block_folds`); the least error
wins (``--model`` forces one). Per robot it prints the means over the
placements neither calibration saw and the ratios casadical / peer beside
issue 45's targets, and a Markdown table of them (``### Held-out means per
robot``, quoted in docs/touch.md).

The peer's calibrated URDFs exist only for panda_2, 3, 4, 6 and 7.
``--peer-runs DIR`` adds, for the robots without one, the URDFs the peer
makes when run on their first ``front*`` placement (``DIR/ROBOT/URDF`` as
``benchmarks/speed/bench_touch_peer.py --calibrate-all DIR`` writes them).

Usage::

    python benchmarks/studies/study_touch_peer.py --peer /work/peer/kinematics_calibration
    python benchmarks/studies/study_touch_peer.py            # the bundled panda_2 only
    python benchmarks/studies/study_touch_peer.py --peer P --peer-runs RUNS --json bar.json

The peer's path may also be given by ``MUKCA_PEER``. Without it, the bundled
copy of panda_2 (``problems/datasets/panda-mukca/raw``) is used.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks" / "datasets"))
from mukca import SOCKET_DISTANCE_MM, front_placement, model_of, read_placement  # noqa: E402

BUNDLED = ROOT / "problems" / "datasets" / "panda-mukca" / "raw"
TIP = "ball_link"
FK_TOLERANCE_M = 1e-9

#: a model: joint readings (rad, (N, n)) -> ball points (m, (N, 3))
Points = Callable[[np.ndarray], np.ndarray]


# --- the independent forward model ---------------------------------------------------------------------------

def _floats(text: str | None, default: str) -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


def rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    """URDF ``rpy``: fixed axes x, y, z in turn, R = Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


@dataclass
class Joint:
    name: str
    kind: str
    origin: np.ndarray                  # 4x4, parent link frame -> joint frame at q = 0
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))


class UrdfChain:
    """The chain from a URDF's root link to ``tip``: the tip's origin at joint readings (rad, in chain order)."""

    def __init__(self, path: str | Path, tip: str = TIP):
        self.path = Path(path)
        robot = ET.parse(self.path).getroot()
        by_child: dict[str, tuple[str, Joint]] = {}
        for j in robot.findall("joint"):
            o = j.find("origin")
            T = np.eye(4)
            if o is not None:
                T[:3, :3] = rpy_matrix(*_floats(o.get("rpy"), "0 0 0"))
                T[:3, 3] = _floats(o.get("xyz"), "0 0 0")
            a = j.find("axis")
            axis = _floats(a.get("xyz") if a is not None else None, "1 0 0")
            if j.get("type") != "fixed":        # a fixed joint's axis is not used (gen3lite's are zero)
                axis = axis / np.linalg.norm(axis)
            by_child[j.find("child").get("link")] = (j.find("parent").get("link"),
                                                     Joint(j.get("name"), j.get("type"), T, axis))
        chain, link = [], tip
        while link in by_child:
            parent, joint = by_child[link]
            chain.append(joint)
            link = parent
        if not chain:
            raise ValueError(f"{self.path}: no joint leads to link {tip!r}")
        self.root = link
        self.chain = chain[::-1]
        self.moving = [j for j in self.chain if j.kind in ("revolute", "continuous", "prismatic")]

    @property
    def n(self) -> int:
        return len(self.moving)

    def points(self, q: np.ndarray) -> np.ndarray:
        """The tip's origin (m, (N, 3)) in the root link's frame at readings ``q`` (rad or m, (N, n))."""
        q = np.atleast_2d(np.asarray(q, float))
        if q.shape[1] != self.n:
            raise ValueError(f"{self.path}: {q.shape[1]} readings for the {self.n} joints to {TIP}")
        N = len(q)
        T = np.tile(np.eye(4), (N, 1, 1))
        k = 0
        for j in self.chain:
            T = T @ j.origin
            if j.kind in ("revolute", "continuous"):
                T = T @ _rotations(j.axis, q[:, k])
                k += 1
            elif j.kind == "prismatic":
                M = np.tile(np.eye(4), (N, 1, 1))
                M[:, :3, 3] = np.outer(q[:, k], j.axis)
                T = T @ M
                k += 1
        return T[:, :3, 3]


def _rotations(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: (N, 4, 4) rotations by ``angle`` about the unit ``axis``."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    out = np.tile(np.eye(4), (len(angle), 1, 1))
    out[:, :3, :3] = np.eye(3) + s * K + (1 - c) * (K @ K)
    return out


def yourdfpy_points(path: Path, q: np.ndarray) -> np.ndarray:
    """The ball points as the peer computes them (``evaluate_model``): yourdfpy, readings padded with zeros."""
    import yourdfpy
    model = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    out = []
    for reading in np.atleast_2d(q):
        cfg = np.zeros(model.num_actuated_joints)
        cfg[:len(reading)] = reading
        model.update_cfg(cfg)
        out.append(model.get_transform(frame_from=model.base_link, frame_to=TIP)[:3, 3])
    return np.array(out)


# --- the peer's measures -------------------------------------------------------------------------------------

def measures(points: Points, sockets: dict[str, np.ndarray]) -> tuple[float, float]:
    """(consistency mm, distance error mm) of a model (``points``: readings (rad) -> ball points (m)) on one
    placement's two sockets."""
    centres, distances = [], []
    for q in sockets.values():
        p = points(q)
        centre = p.mean(axis=0)
        centres.append(centre)
        distances.append(np.linalg.norm(p - centre, axis=1))
    consistency = float(np.concatenate(distances).mean()) * 1000
    distance_error = abs(float(np.linalg.norm(centres[0] - centres[1])) * 1000 - SOCKET_DISTANCE_MM)
    return consistency, distance_error


# --- casadical, the third column -------------------------------------------------------------------------------

#: the models casadical tries on the training placement: the complete geometry and, where the robot file weighs its
#: links, each joint giving way under the weights it carries (about its axis, or its bearing tilting across it)
CANDIDATES = ("kinematic", "kinematic+joint_compliance", "kinematic+bearing_compliance")
#: blocks of each socket's rows (in recording order) that the model choice leaves out in turn
FOLDS = 5


@dataclass
class Ours:
    """casadical's calibration of one robot: its prediction, the model chosen and each candidate's fold error."""

    points: Points
    model: str
    robot_file: str                     # the URDF calibrated (the nominal, or the nominal with its masses)
    folds_mm: dict[str, float] = field(default_factory=dict)


def robot_file(robot: str, nominal_urdf: Path, folder: Path) -> Path:
    """The URDF a user calibrates: the nominal one, or where it weighs nothing and the robot is a Panda, the same
    file with the Panda's published link masses (``mukca.with_masses``, as ``panda_masses.urdf`` is bundled)."""
    from mukca import with_masses

    text = nominal_urdf.read_text()
    if "<inertial" in text or not model_of(robot).startswith("panda"):
        return nominal_urdf
    out = folder / f"{nominal_urdf.stem}_masses.urdf"
    out.write_text(with_masses(text))
    return out


def block_folds(points: np.ndarray, k: int = FOLDS) -> np.ndarray:
    """Each row's fold: each socket's rows, in recording order, cut into ``k`` blocks (a user records a few poses of
    one arm posture after another, so a block leaves postures out, not single rows)."""
    fold = np.zeros(len(points), int)
    for name in dict.fromkeys(points.tolist()):
        rows = np.flatnonzero(points == name)
        fold[rows] = np.arange(len(rows)) * k // len(rows)
    return fold


def fold_error_mm(arm, data, model: str) -> float:
    """The mean distance of each left-out row's ball point from its socket, as the model fitted to the other rows
    places both (:func:`block_folds`)."""
    import warnings

    from casadical import calibrate

    names = np.asarray(data.columns["point"]).astype(str)
    fold = block_folds(names)
    errors = []
    for k in range(FOLDS):
        train, test = np.flatnonzero(fold != k), np.flatnonzero(fold == k)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = calibrate(arm, data.subset(train).with_fixtures(data.fixtures), model,
                               allow_outside_limits=True)
        P = result.predict(data)
        for name in np.unique(names[test]):
            socket = P[train][names[train] == name].mean(axis=0)
            errors.append(np.linalg.norm(P[test][names[test] == name] - socket, axis=1))
    return float(np.concatenate(errors).mean()) * 1000


def casadical_model(robot: str, nominal_urdf: Path, train: str, train_sockets: dict[str, np.ndarray],
                    model: str | None = None) -> Ours | None:
    """casadical's calibration of ``robot`` from its ``train`` placement, as a user makes it with the library: the
    placement converted to a measurement CSV (``benchmarks/datasets/mukca.py``), the block as a fixture file,
    ``calibrate(load_robot(URDF, tip="ball_link"), data, model)``. The model is ``model``, or the one of
    :data:`CANDIDATES` (the robot file weighing its links; else ``kinematic``) whose fits to the training rows
    leave out fewest millimetres in :data:`FOLDS` blocks of them (:func:`fold_error_mm`): chosen on the training
    placement alone, never on the placements it is judged on. Readings beyond the URDF's limits are let through
    (``--allow-outside-limits``: the Kinova's are)."""
    import tempfile
    import warnings

    from mukca import FIXTURE_TOML, SOCKETS, csv_text, degrees

    from casadical import Measurements, calibrate, load_robot
    from casadical.rows import read_fixture_file

    with tempfile.TemporaryDirectory(prefix="touch-peer-") as tmp:
        urdf = robot_file(robot, nominal_urdf, Path(tmp))
        arm = load_robot(urdf, tip=TIP)
        header = [f"q{j + 1}_deg" for j in range(arm.n)] + ["point"]
        rows = [[repr(degrees(v)) for v in reading] + [point] for point in SOCKETS.values()
                for reading in train_sockets[point].tolist()]
        csv, toml = Path(tmp) / f"{train}.csv", Path(tmp) / "two_sockets.toml"
        csv.write_text(csv_text(header, rows))
        toml.write_text(FIXTURE_TOML)
        data = Measurements.read_csv(csv, robot=arm).with_fixtures(read_fixture_file(toml))
        weighed = sum(j.mass for j in arm.joints) > 0
        folds = {}
        if model is None:
            folds = {m: fold_error_mm(arm, data, m) for m in (CANDIDATES if weighed else CANDIDATES[:1])}
            model = min(folds, key=folds.get)
        with warnings.catch_warnings():          # what the calibration says is in its result; the table is ours
            warnings.simplefilter("ignore")
            result = calibrate(arm, data, model, allow_outside_limits=True)
    name = "nominal URDF" if urdf == nominal_urdf else f"nominal URDF with the Panda's masses ({urdf.name})"
    return Ours(lambda q: result.predict(Measurements.from_arrays(np.atleast_2d(q))), model, name, folds)


# --- the robots ----------------------------------------------------------------------------------------------

@dataclass
class Robot:
    name: str
    placements: dict[str, dict[str, np.ndarray]]
    nominal: Path
    calibrated: Path | None = None
    source: str = ""                # where the calibrated URDF comes from
    kind: str = ""                  # "stored" (in the peer's repository) or "run" (our run of the peer)
    train: str | None = None
    train_how: str = ""             # "*": the peer's config.yaml, "?": inferred, "run": our run of the peer
    ours: Ours | None = None        # casadical's calibration


def find_robots(peer: Path | None, peer_runs: Path | None) -> list[Robot]:
    if peer is None:
        data = BUNDLED / "data"
        urdf_dir, calibrated_dir = BUNDLED / "urdf", BUNDLED / "calibrated_urdf"
    else:
        data, urdf_dir, calibrated_dir = peer / "data", peer / "urdf", peer / "calibrated_urdf"
    robots = []
    for folder in sorted(p for p in data.iterdir() if p.is_dir()):
        placements = {p.name: read_placement(p) for p in sorted(folder.iterdir())
                      if (p / "hole_0.csv").exists() and (p / "hole_1.csv").exists()}
        if not placements:
            continue
        nominal = urdf_dir / f"{model_of(folder.name)}.urdf"
        robot = Robot(folder.name, placements, nominal)
        stored = calibrated_dir / folder.name / nominal.name
        ran = peer_runs / folder.name / nominal.name if peer_runs else None
        if stored.exists():
            robot.calibrated, robot.source, robot.kind = stored, "stored in the peer's repository", "stored"
            config = stored.parent / "config.yaml"
            if config.exists():
                robot.train, robot.train_how = _trained_on(config), "*"
        elif ran is not None and ran.exists():
            robot.calibrated, robot.source, robot.kind = ran, f"our run of the peer ({ran.parent})", "run"
            robot.train, robot.train_how = _trained_on(ran.parent / "config.yaml"), "run"
        robots.append(robot)
    return robots


def _trained_on(config: Path) -> str:
    """The placement named by a peer's config.yaml (``data_path``: one path, or a list of one)."""
    text = config.read_text()
    for line in text.splitlines():
        line = line.strip().removeprefix("- ")
        if line.startswith("data_path:"):
            line = line.split(":", 1)[1].strip()
        if "/data/" in line:
            return line.rstrip("/").rsplit("/", 1)[-1]
    raise ValueError(f"{config}: no data_path")


# --- the checks of the forward model -------------------------------------------------------------------------

def check_against_yourdfpy(robots: list[Robot]) -> float:
    """The largest distance (m) between this file's ball points and yourdfpy's, at every row of every placement,
    for every URDF used."""
    worst = 0.0
    for r in robots:
        for urdf in filter(None, (r.nominal, r.calibrated)):
            chain = UrdfChain(urdf)
            q = np.vstack([q for s in r.placements.values() for q in s.values()])
            worst = max(worst, float(np.abs(chain.points(q) - yourdfpy_points(urdf, q)).max()))
    return worst


def check_against_stored_kpis(peer: Path) -> list[tuple[str, int, float]]:
    """(robot, rows, largest distance m) between this file's points of the stored calibrated URDF and the ball
    points the peer stored in its kpis.yaml (fks_1, fks_2 of the training placement)."""
    import yaml
    out = []
    for kpis in sorted((peer / "calibrated_urdf").glob("*/kpis.yaml")):
        robot = kpis.parent.name
        doc = yaml.safe_load(kpis.read_text())
        train = _trained_on(kpis.parent / "config.yaml")
        sockets = read_placement(peer / "data" / robot / train)
        chain = UrdfChain(kpis.parent / "panda.urdf")
        worst, rows = 0.0, 0
        for key, q in zip(("fks_1", "fks_2"), sockets.values()):
            stored = np.array(doc[key], float).reshape(-1, 3)
            if len(stored) != len(q):
                out.append((f"{robot} ({key}: {len(stored)} stored, {len(q)} rows now)", 0, float("nan")))
                break
            worst = max(worst, float(np.abs(chain.points(q) - stored).max()))
            rows += len(q)
        else:
            out.append((robot, rows, worst))
    return out


# --- the table -----------------------------------------------------------------------------------------------

def run(robots: list[Robot], model: str | None = None) -> list[dict]:
    rows = []
    for r in robots:
        nominal = UrdfChain(r.nominal).points
        calibrated = UrdfChain(r.calibrated).points if r.calibrated else None
        if calibrated is not None and r.train is None:       # not recorded: where the URDF is most consistent
            r.train = min(r.placements, key=lambda p: measures(calibrated, r.placements[p])[0])
            r.train_how = "?"
        train = r.train or front_placement(r.placements)
        ours = r.ours = casadical_model(r.name, r.nominal, train, r.placements[train], model)
        for place, sockets in r.placements.items():
            row = {"robot": r.name, "placement": place, "rows": sum(len(q) for q in sockets.values()),
                   "peer_kind": r.kind,
                   "trained": place == r.train, "train_how": r.train_how if place == r.train else "",
                   "nominal": measures(nominal, sockets)}
            row["peer"] = measures(calibrated, sockets) if calibrated else None
            row["casadical"] = measures(ours.points, sockets) if ours else None
            row["casadical_trained"] = place == train and ours is not None
            rows.append(row)
    return rows


def _pair(m) -> str:
    return f"{m[0]:7.2f} {m[1]:7.2f}" if m else f"{'-':>7} {'-':>7}"


def print_table(robots: list[Robot], rows: list[dict]) -> None:
    head = (f"{'robot':<20} {'placement':<13} {'rows':>4}  {'nominal cons':>12} {'dist':>7}  "
            f"{'peer cons':>9} {'dist':>7}  {'casadical':>9} {'dist':>7}")
    print("consistency and distance error (mm); * trained on (peer's config.yaml), ? trained on (inferred: not "
          "recorded), r trained on (our run of the peer)")
    print(head)
    print("-" * len(head))
    for r in robots:
        mine = [x for x in rows if x["robot"] == r.name]
        for x in mine:
            mark = {"*": "*", "?": "?", "run": "r"}.get(x["train_how"], " ")
            print(f"{x['robot']:<20} {x['placement']:<12}{mark} {x['rows']:>4}  {_pair(x['nominal']):>20}  "
                  f"{_pair(x['peer']):>17}  {_pair(x['casadical']):>17}")
        held = [x for x in mine if not x["trained"]]
        means = {k: _means([x[k] for x in held if x[k]]) for k in ("nominal", "peer", "casadical")}
        label = "held-out mean" if len(held) < len(mine) else "mean"
        print(f"{'':<20} {label:<13} {len(held):>4}  {_pair(means['nominal']):>20}  "
              f"{_pair(means['peer']):>17}  {_pair(means['casadical']):>17}")
        if means["peer"] and means["casadical"]:
            c, d = (means["casadical"][i] / means["peer"][i] for i in (0, 1))
            print(f"{'':<20} casadical / peer, held out: consistency {c:.2f} (issue 45: at most 0.8), distance "
                  f"error {d:.2f} (at most 1)")
        print(f"{'':<20} calibrated URDF: {r.source or 'none in the peer repository'}")
        if r.ours:
            folds = ", ".join(f"{m} {e:.3f} mm" for m, e in r.ours.folds_mm.items())
            how = ("given" if not folds else f"chosen on the training placement's own folds: {folds}"
                   if len(r.ours.folds_mm) > 1 else f"the URDF weighs no link: the geometry alone; folds {folds}")
            print(f"{'':<20} casadical: {r.ours.model} on the {r.ours.robot_file} ({how})")


def markdown_summary(robots: list[Robot], rows: list[dict]) -> list[str]:
    """Per robot, the means over the placements the calibrations never saw (a Markdown table, for the docs)."""
    out = ["| robot | trained on | held out | nominal: consistency / distance error (mm) | peer's URDF | "
           "casadical | casadical's model | casadical / peer: consistency (at most 0.8) | distance error "
           "(at most 1) |", "|---|---|---|---|---|---|---|---|---|"]
    for r in robots:
        held = [x for x in rows if x["robot"] == r.name and not x["trained"] and not x["casadical_trained"]]
        if not held or not r.ours:
            continue
        means = {k: _means([x[k] for x in held if x[k]]) for k in ("nominal", "peer", "casadical")}
        cell = (lambda m: f"{m[0]:.3f} / {m[1]:.3f}" if m else "-")  # noqa: E731
        ratios = ("-", "-")
        if means["peer"]:
            ratios = tuple(f"{means['casadical'][i] / means['peer'][i]:.2f}" for i in (0, 1))
        train = next(x["placement"] for x in rows if x["robot"] == r.name and x["casadical_trained"])
        out.append(f"| {r.name} | {train} | {len(held)} | {cell(means['nominal'])} | {cell(means['peer'])} | "
                   f"{cell(means['casadical'])} | {r.ours.model.replace('kinematic+', '+')} | {ratios[0]} | "
                   f"{ratios[1]} |")
    return out


def _means(pairs):
    return tuple(float(np.mean(v)) for v in zip(*pairs)) if pairs else None


def summary(rows: list[dict], kind: str) -> dict:
    """The issue's ranges for the robots whose calibrated URDF is of ``kind`` ("stored": in the peer's
    repository, "run": our runs of the peer): the nominal consistency and distance error over every placement,
    the peer's on the placements it never saw, per placement and per robot mean."""
    rows = [x for x in rows if x["peer_kind"] == kind]
    held = [x for x in rows if x["peer"] and not x["trained"]]
    per_robot = {}
    for x in held:
        per_robot.setdefault(x["robot"], []).append(x["peer"])
    means = {k: _means(v) for k, v in per_robot.items()}
    span = lambda v: (min(v), max(v)) if v else None   # noqa: E731
    return {"robots": sorted({x["robot"] for x in rows}),
            "nominal_consistency_mm": span([x["nominal"][0] for x in rows]),
            "nominal_distance_error_mm": span([x["nominal"][1] for x in rows]),
            "peer_held_out_consistency_mm": span([x["peer"][0] for x in held]),
            "peer_held_out_distance_error_mm": span([x["peer"][1] for x in held]),
            "peer_robot_mean_consistency_mm": span([m[0] for m in means.values()]),
            "peer_robot_mean_distance_error_mm": span([m[1] for m in means.values()]),
            "peer_robot_means_mm": means}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--peer", type=Path, default=os.environ.get("MUKCA_PEER"),
                    help="a checkout of platonics-delft/kinematics_calibration (default: $MUKCA_PEER; without: "
                         "the bundled panda_2)")
    ap.add_argument("--peer-runs", type=Path, help="URDFs of our runs of the peer (DIR/ROBOT/URDF, config.yaml)")
    ap.add_argument("--robots", nargs="+", help="only these robot folders")
    ap.add_argument("--no-check", action="store_true", help="skip the check against yourdfpy (slow: ~1 min)")
    ap.add_argument("--model", help="casadical's model for every robot (default: chosen per robot on its training "
                                     "placement's folds among " + ", ".join(CANDIDATES) + ")")
    ap.add_argument("--json", type=Path, help="write the rows and the summary here")
    args = ap.parse_args(argv)
    peer = Path(args.peer) if args.peer else None
    if peer is not None and not (peer / "data").is_dir():
        print(f"study_touch_peer.py: error: {peer}: no data/ folder (not a checkout of the peer)", file=sys.stderr)
        return 2
    robots = find_robots(peer, args.peer_runs)
    if args.robots:
        robots = [r for r in robots if r.name in args.robots]
    print(f"data: {peer / 'data' if peer else BUNDLED / 'data'} ({len(robots)} robots)")
    if not args.no_check:
        worst = check_against_yourdfpy(robots)
        print(f"forward model vs yourdfpy (the peer's evaluation), every row and URDF: max {worst:.2e} m")
        if worst > FK_TOLERANCE_M:
            print(f"study_touch_peer.py: error: the forward model differs from yourdfpy by {worst:.2e} m",
                  file=sys.stderr)
            return 1
        if peer is not None:
            for robot, n, worst in check_against_stored_kpis(peer):
                print(f"forward model vs the peer's stored kpis.yaml points, {robot}: {n} rows, max {worst:.2e} m")
    rows = run(robots, args.model)
    print_table(robots, rows)
    print("\n### Held-out means per robot\n")
    print("\n".join(markdown_summary(robots, rows)))
    sums = {kind: summary(rows, kind) for kind in ("stored", "run")}
    for kind, s in sums.items():
        if not s["robots"]:
            continue
        print(f"\nranges, peer's URDFs {'in its repository' if kind == 'stored' else 'of our runs'} "
              f"({', '.join(s['robots'])}):")
        for k, v in s.items():
            if k.endswith("_mm") and isinstance(v, tuple):
                print(f"  {k:<36} {v[0]:.3f} - {v[1]:.3f}")
    if args.json:
        ours = {r.name: {"model": r.ours.model, "robot_file": r.ours.robot_file, "folds_mm": r.ours.folds_mm}
                for r in robots if r.ours}
        args.json.write_text(json.dumps({"rows": rows, "summary": sums, "casadical": ours}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
