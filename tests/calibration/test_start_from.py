"""``calibrate(start_from=fit)``: a fit started at another fit's solution (its base pose, probe mounting and
values) gives the fit started in closed form, in fewer iterations: the diagnosis fits every model from its
parent so."""

import warnings

import numpy as np
import pytest

from casadical import calibrate
from casadical.calibration import CalibrationRun, Options
from casadical.calibration import _pipeline as pipeline
from casadical.data import Effects, simulate
from casadical.errors import InputError
from casadical.robot import robot_from_dict
from tests.calibration.test_sessions import two_sessions
from tests.helpers.arms import ARM5, ARM7_DH

SEEDS = [0, 1, 2]


def _data(arm, seed, full_pose):
    robot = robot_from_dict(arm)
    effects = Effects(stiffness={2: 3e4}, orientation_noise=2e-4 if full_pose else None)
    data, _ = simulate(robot, 60, effects, seed=seed, floor_z=None)
    # three bad shots, 5-8 mm off: the robust fit sets them aside, the closed-form alignment of the start does not
    rng = np.random.default_rng(seed)
    data.xyz[:3] += rng.choice([-1, 1], size=(3, 3)) * rng.uniform(5e-3, 8e-3, size=(3, 3))
    return robot, data


def _compare(robot, data, parent, spec):
    """The model ``spec`` fitted from ``parent``'s values, cold (closed forms) and warm (start_from)."""
    start = {p.name: p.value for p in parent.parameters if not p.name.startswith("base_")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return [calibrate(robot, data, spec, "lm", start=start, start_from=frames, warn=False)
                for frames in (None, parent)]


def _same(cold, warm):
    for p in cold.parameters:
        if p.fixed:
            continue
        q = warm.parameters[p.name]
        assert abs(q.value - p.value) <= 1e-3 * max(p.std, 1e-12), (p.name, p.value, q.value, p.std)
    for s in cold.sessions or [None]:
        np.testing.assert_allclose(warm.base_matrix(s), cold.base_matrix(s), atol=1e-9)
    assert warm.calibration.mean_mm == pytest.approx(cold.calibration.mean_mm, rel=1e-6)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("arm, full_pose", [(ARM7_DH, False), (ARM5, True)], ids=["7-axis DH", "5-axis full pose"])
def test_warm_fit_is_the_cold_fit_in_fewer_iterations(arm, full_pose, seed):
    robot, data = _data(arm, seed, full_pose)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parent = calibrate(robot, data, "kinematic", "lm", warn=False)
    cold, warm = _compare(robot, data, parent, "kinematic+compliance")
    _same(cold, warm)
    if full_pose:
        np.testing.assert_allclose(warm.tool_rotation(), cold.tool_rotation(), atol=1e-9)


@pytest.mark.parametrize("seed", SEEDS[:2])
def test_warm_fit_of_two_sessions(seed):
    robot, cal, _, _ = two_sessions(ARM5, 6e4, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parent = calibrate(robot, cal, "kinematic", "lm", warn=False)
    cold, warm = _compare(robot, cal, parent, "kinematic+compliance")
    _same(cold, warm)


def _start(robot, data, spec, parent):
    """The run of ``calibrate(start_from=parent)`` as the solve starts (the stages before solve_parameters)."""
    start = {p.name: p.value for p in parent.parameters if not p.name.startswith("base_")}
    run = CalibrationRun(robot, data, spec, Options(solver="lm", start=start, start_from=parent, warn=False))
    for stage in pipeline.STAGES[:pipeline.STAGES.index(pipeline.solve_parameters)]:
        stage(run)
    return run


@pytest.mark.parametrize("seed", SEEDS[:2])
@pytest.mark.parametrize("case", ["7-axis DH", "5-axis full pose", "two sessions"])
def test_the_solve_starts_at_the_parent(case, seed):
    """The start is the parent's solution, its base pose (each session's) and probe mounting expressed in the
    closed-form references of the run: the same predicted points (and probe rotations)."""
    if case == "two sessions":
        robot, data, _, _ = two_sessions(ARM5, 6e4, seed)
    else:
        robot, data = _data(*{"7-axis DH": (ARM7_DH, False), "5-axis full pose": (ARM5, True)}[case], seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parent = calibrate(robot, data, "kinematic", "lm", warn=False)
        run = _start(robot, data, "kinematic", parent)
    assert not np.allclose(run.base0, parent.base0)        # the references are the run's own
    xyz = run.model.predict(data.q, run.params.values, run.cov, run.base0)
    np.testing.assert_allclose(xyz, parent.predict(data), atol=1e-9)
    if parent.has_orientation:
        R = run.model.probe_rotation(data.q, run.params.values, run.cov, run.base0) @ run.tool0
        np.testing.assert_allclose(R, parent.predict_rotations(data), atol=1e-9)


def test_a_fit_of_other_sessions_is_refused():
    robot, cal, _, _ = two_sessions(ARM5, 6e4, 0)
    one = cal.subset(cal.sessions == "A")
    one.sessions = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parent = calibrate(robot, one, "kinematic", "lm", warn=False)
        with pytest.raises(InputError, match="start_from: a fit of sessions"):
            calibrate(robot, cal, "kinematic", "lm", start_from=parent, warn=False)
