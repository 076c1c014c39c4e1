"""Studies of touch protocols: how many placements of a block, how many rows per socket (docs/formats.md section 8).

A study with a ``[touch]`` table simulates, in each repetition, a block of sockets (its points at known
coordinates in its frame) placed at random where the drawn true robot reaches, and the robot's ball put in each
socket by many configurations (:mod:`casadical.data._simulate_touches`: the inverse kinematics of the true robot,
from random starts). Its plans say how many placements and rows per socket a calibration gets:

- ``random``: the first ``rows_per_point`` rows of each socket at each of the first ``placements`` placements
  (configurations as a user's hand guiding gives them);
- ``d-optimal``: as many rows chosen out of ``pool`` candidates per socket and placement by the Ds criterion
  (:mod:`casadical.planning._touches`).

Plans of one repetition share the simulated rows: a plan of 2 placements takes the first two of the placements a
plan of 4 takes, a plan of 10 rows per socket the first 10 of the 20 another takes, so that plans are compared on
the same placements and configurations. Each calibration is judged on ``validation_placements`` fresh
placements (their sockets fitted to their own rows: ``val_consistency_mm``, ``val_distance_error_mm``), and
against the true robot at ``validation_poses`` random poses over the workspace, after the best rigid motion (what
touches cannot see: the base pose; ``val_true_mean_mm``, ``val_true_max_mm``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..data._measurements import MIN_TOUCH_ROWS, Measurements
from ..errors import InputError
from ..rows._fixture import Fixture

#: keys of a study's ``[touch]`` table
TOUCH_KEYS = {"points_mm", "contact_noise_mm", "known_geometry", "sd_mm", "validation_placements",
              "validation_rows_per_point", "tilt_deg", "min_height_m"}
#: most placements a plan or the validation may ask for
MAX_PLACEMENTS = 100
#: most rows per socket and placement (a candidate pool's too)
MAX_ROWS = 10_000


@dataclass
class TouchSpec:
    """A study's ``[touch]`` table: the block and how its rows are simulated and judged.

    Attributes
    ----------
    points : dict of str to tuple
        The block's sockets, m in its own frame.
    contact_noise : float
        How far the ball sits off a socket's centre (m, Gaussian per axis).
    known_geometry : bool
        The calibrations know the block (a fixture file of these points, ``sd``); else the sockets are free points
        (and the scale of every length is not seen).
    sd : float
        The fixture's tolerance (m).
    validation_placements, validation_rows : int
        Fresh placements each calibration is judged on, rows per socket at each.
    tilt : float
        A placement's tilt from level, at most (rad).
    min_height : float
        A placement's centre at least this high above the robot's base (m).
    """

    points: dict
    contact_noise: float = 20e-6
    known_geometry: bool = True
    sd: float = 1e-5
    validation_placements: int = 2
    validation_rows: int = 10
    tilt: float = math.radians(5.0)
    min_height: float = 0.1

    def fixture(self) -> Fixture:
        return Fixture("block", {k: np.asarray(v, float) for k, v in self.points.items()}, self.sd)

    def fixtures(self) -> tuple:
        """What the calibrations are given: the block, or nothing (free points)."""
        return (self.fixture(),) if self.known_geometry else ()


def touch_from_table(t: dict, v) -> TouchSpec:
    """The :class:`TouchSpec` of a study's ``[touch]`` table (``v``: the file's TomlValidator)."""
    v.keys(t, TOUCH_KEYS, "touch")
    pts = t.get("points_mm")
    if not isinstance(pts, dict) or len(pts) < 2:
        raise InputError("must be a table of two or more named points, [x, y, z] in mm in the block's frame",
                         file=v.file, column="touch.points_mm")
    points = {}
    for name, xyz in pts.items():
        vec = v.vector(pts, name, "touch.points_mm", 3)
        points[name] = tuple(float(x) / 1000.0 for x in vec)
    arr = np.array(list(points.values()))
    if np.linalg.matrix_rank(arr - arr[0], tol=1e-9) < 1:
        raise InputError("the points all stand at one place", file=v.file, column="touch.points_mm")
    known = t.get("known_geometry", True)
    if not isinstance(known, bool):
        raise InputError(f"must be true or false, got {known!r}", file=v.file, column="touch.known_geometry")
    sd = v.nonnegative(t, "sd_mm", "touch", 0.01)
    if not sd > 0:
        raise InputError(f"must be positive, got {sd}", file=v.file, column="touch.sd_mm")
    return TouchSpec(points, v.nonnegative(t, "contact_noise_mm", "touch", 0.02) / 1000.0, known, sd / 1000.0,
                     v.integer(t, "validation_placements", "touch", default=2, minimum=1, maximum=MAX_PLACEMENTS),
                     v.integer(t, "validation_rows_per_point", "touch", default=10, minimum=MIN_TOUCH_ROWS,
                               maximum=MAX_ROWS),
                     math.radians(v.nonnegative(t, "tilt_deg", "touch", 5.0)),
                     v.number(t, "min_height_m", "touch", default=0.1))


def touch_plan(t: dict, where: str, selector: str, touch: TouchSpec, v) -> tuple[int, tuple[int, ...], int | None]:
    """A touch plan's ``placements``, ``rows_per_point`` (sizes) and ``pool`` (candidates per socket and placement
    of ``d-optimal``), checked."""
    if "poses" in t:
        raise InputError("a plan of a [touch] study gives placements and rows_per_point, not poses", file=v.file,
                         column=f"{where}.poses")
    if selector not in ("random", "d-optimal"):
        raise InputError(f"a [touch] study's plans are random or d-optimal (the Ds criterion), not {selector!r}",
                         file=v.file, column=f"{where}.method")
    placements = v.integer(t, "placements", where, required=True, minimum=1, maximum=MAX_PLACEMENTS)
    raw = t.get("rows_per_point")
    sizes = raw if isinstance(raw, list) else [raw]
    if raw is None or not sizes or any(isinstance(r, bool) or not isinstance(r, int) or not
                                       MIN_TOUCH_ROWS <= r <= MAX_ROWS for r in sizes):
        raise InputError(f"must be a whole number from {MIN_TOUCH_ROWS} (the fewest rows that fix a socket) to "
                         f"{MAX_ROWS:,}, or a list of them, got {raw!r}", file=v.file, column=f"{where}.rows_per_point")
    if len(set(sizes)) != len(sizes):
        raise InputError(f"lists a number of rows twice: {sizes}", file=v.file, column=f"{where}.rows_per_point")
    pool = v.integer(t, "pool", where, default=None, minimum=1, maximum=MAX_ROWS)
    if selector == "d-optimal" and pool is None:
        raise InputError("d-optimal chooses out of candidates: give pool = N, the candidate rows per socket and "
                         "placement", file=v.file, column=f"{where}.pool")
    if pool is not None and pool < max(sizes):
        raise InputError(f"the pool ({pool} rows per socket and placement) must hold the {max(sizes)} to choose",
                         file=v.file, column=f"{where}.pool")
    return placements, tuple(sizes), pool


@dataclass
class TouchWorld:
    """The simulated rows of one repetition of a touch study.

    Attributes
    ----------
    rows : Measurements
        Every calibration candidate: placements ``P0``, ``P1``, ... in order, each ``per_placement`` rows, the
        sockets in turn (row ``j`` of a placement touches socket ``j mod n_points``); with the study's fixtures.
    per_placement : int
    workspace_q : ndarray
        Random readings over the workspace, and the true robot's points there (``workspace_true``, m).
    """

    rows: Measurements
    per_placement: int
    workspace_q: np.ndarray
    workspace_true: np.ndarray


def draw_touch_world(study, repetition: int, truth, stream) -> tuple[TouchWorld, Measurements]:
    """The repetition's calibration candidates, its validation rows (fresh placements ``V0``, ...) and its
    workspace poses (``stream(*names)``: a seed of the repetition's named stream)."""
    from ..data._simulate import sample_poses
    from ..data._simulate_touches import touch_rows

    touch = study.touch
    npts = len(touch.points)
    placements = max(p.placements for p in study.plans)
    rows = max(max(max(p.rows_per_point), p.pool or 0) for p in study.plans)
    common = {"contact_noise": touch.contact_noise, "tilt": touch.tilt, "floor_z": touch.min_height}
    cal, _ = touch_rows(truth, touch.points, placements, rows, np.random.default_rng(stream("touch")), **common)
    val, _ = touch_rows(truth, touch.points, touch.validation_placements, touch.validation_rows,
                        np.random.default_rng(stream("validation")), session_prefix="V", **common)
    q = sample_poses(study.robot, study.validation_poses, np.random.default_rng(stream("workspace")),
                     **study.workspace)
    fx = touch.fixtures()
    world = TouchWorld(cal.with_fixtures(fx) if fx else cal, rows * npts, q,
                       truth.model.predict(q, truth.values, truth.model.default_covariates(len(q)), truth.base0))
    return world, val.with_fixtures(fx) if fx else val


def plan_rows(plan, world: TouchWorld, m: int, n_points: int, pool: bool = False) -> np.ndarray:
    """The rows of ``plan``'s ``m`` (its placements' first ``m / (placements n_points)`` rows per socket; with
    ``pool``, its placements' first ``plan.pool`` per socket: what d-optimal chooses from)."""
    per = (plan.pool if pool else m // (plan.placements * n_points)) * n_points
    return np.concatenate([k * world.per_placement + np.arange(per) for k in range(plan.placements)])


def select_touch_rows(study, world: TouchWorld, plan, m: int, designs: dict, seed: int):
    """``plan``'s ``m`` calibration rows of the repetition: a :class:`~casadical.study._selection.Selection`."""
    from ..model._symbolic import Model
    from ..planning._selectors import PlanSettings
    from ..planning._touches import select_touches, touch_problem
    from ._selection import Selection

    npts = len(study.touch.points)
    if plan.selector == "random":
        return Selection(plan_rows(plan, world, m, npts))
    pool = plan_rows(plan, world, m, npts, pool=True)
    key = (plan.model, plan.placements, plan.pool)
    if key not in designs:
        model = Model(study.robot, plan.model, jit=False)
        designs[key] = touch_problem(model, world.rows.subset(pool))
    t0 = time.perf_counter()
    res = select_touches(designs[key], m, "d-optimal", seed=seed, settings=PlanSettings(certify=False))
    return Selection(pool[res.indices], res.O1, res.log_det, time.perf_counter() - t0)


def touch_figures(res, world: TouchWorld) -> dict:
    """The result columns of rows that touch: consistency and distance error (calibration rows, fresh
    placements), and the true error at the workspace poses after the best rigid motion."""
    from ..stats._alignment import align

    out = {"cal_consistency_mm": res.calibration.touch.get("consistency_mm", math.nan),
           "val_consistency_mm": res.validation.touch.get("consistency_mm", math.nan),
           "val_distance_error_mm": res.validation.touch.get("distance_error_mm", math.nan)}
    pred = res.predict(Measurements.from_arrays(world.workspace_q, prismatic=res.result.model.robot.prismatic))
    T = align(pred, world.workspace_true)
    e = np.linalg.norm(pred @ T[:3, :3].T + T[:3, 3] - world.workspace_true, axis=1) * 1000.0
    out["val_true_mean_mm"], out["val_true_max_mm"] = float(e.mean()), float(e.max())
    return out
