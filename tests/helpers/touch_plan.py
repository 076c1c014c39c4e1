"""Touch plans on the truth's sockets (tests/planning/test_touch_plan.py and
benchmarks/studies/study_touch_plan.py): candidate rows the independent truth puts in the two sockets of a block
at several placements, and the held-out consistency of calibrations on the rows the Ds criterion keeps against
random selections of as many."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from casadical import calibrate
from casadical.data import Measurements
from casadical.model import Model
from casadical.planning import random_rows, schur_log_det, select_touches, touch_problem
from casadical.robot import robot_from_dict
from casadical.rows import read_fixture_file
from tests.helpers import hidden
from tests.helpers.arms import to_toml
from tests.truth import Arm, Effects, Session, TrueRobot, touch


def sockets(robot: str, seed: int, per_socket: int, placements: int, folder: Path, fixture: bool = True,
            prefix: str = "P", true: TrueRobot | None = None, rng: np.random.Generator | None = None):
    """Rows of the truth's robot (geometry errors only, drawn from ``seed``) in the two sockets of a block at
    ``placements`` places (sessions ``P0``, ...), ``per_socket`` per socket, the ball 20 um off the socket (per
    axis), read back as a user's file ``folder/{prefix}-{seed}.csv`` (with ``folder/fixture.toml``, or as free
    points; ``folder/robot.toml`` written too). Returns (robot, data, true robot, rng)."""
    doc = hidden.robot_doc(robot)
    rng = rng if rng is not None else np.random.default_rng(seed)
    true = true or TrueRobot.draw(Arm.from_dict(doc), Effects(), rng)
    block = touch.two_sockets()
    rows = None
    for k in range(placements):
        more = touch.fixture_session(true, block, per_socket, rng, Session(f"{prefix}{k}"), contact_noise=20e-6)
        rows = more if rows is None else rows + more
    path = rows.write_csv(folder / f"{prefix}-{seed}.csv", session_column=True)
    (folder / "fixture.toml").write_text(touch.fixture_toml([block]))
    (folder / "robot.toml").write_text(to_toml(doc))
    data = Measurements.read_csv(path, n_joints=true.arm.n, require_positions=True)
    if fixture:
        data = data.with_fixtures(read_fixture_file(folder / "fixture.toml"))
    return robot_from_dict(doc, robot), data, true, rng


@dataclass
class Comparison:
    """The selected rows against random selections of as many: held-out consistency (mm) and the Ds value."""

    seed: int
    n_parameters: int
    efficiency: float
    gap: float
    selected: float
    randoms: list
    selected_ds: float
    random_ds: list


def compare(robot: str, seed: int, folder: Path, m: int = 18, per_socket: int = 30, placements: int = 2,
            n_random: int = 7) -> Comparison:
    """Calibrate (kinematic, Levenberg-Marquardt) on the ``m`` rows the Ds criterion keeps of ``placements`` x 2 x
    ``per_socket`` candidates, and on ``n_random`` random selections of ``m`` (each socket none or 4+ rows); judge
    each on three fresh placements of 10 rows per socket (their sockets fitted to their own rows)."""
    rob, cal, true, rng = sockets(robot, seed, per_socket, placements, folder)
    _, val, _, _ = sockets(robot, seed, 10, 3, folder, prefix="V", true=true, rng=rng)
    problem = touch_problem(Model(rob, "kinematic", jit=False), cal)
    chosen = select_touches(problem, m)

    def consistency(S) -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = calibrate(rob, cal.subset(np.sort(S)), "kinematic", "lm", warn=False)
        return res.stats(val).touch["consistency_mm"]

    pick = np.random.default_rng(seed)
    randoms = [random_rows(problem.sets, problem.least, m, pick) for _ in range(n_random)]
    p = problem.n_parameters
    return Comparison(seed, p, chosen.d_efficiency, chosen.relaxation_gap, consistency(chosen.indices),
                      [consistency(S) for S in randoms], chosen.log_det / p, [schur_log_det(problem, S) / p
                                                                              for S in randoms])
