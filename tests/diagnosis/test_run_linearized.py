"""``DiagnosisRun.linearized`` and ``held_out``: a fit's linearisation on the calibration poses and its held-out
errors are made once per fit and shared by the stages that ask them (the search's judge, the stand-in check, the
never-worse check, the structure screen, the intervals); what they answer is what a fresh computation gives, to the
bit, for each fit asked in any order, and again after the folds or the prior change."""

import numpy as np
import pytest

from casadical.data import Effects, simulate
from casadical.diagnosis import DiagnosisRun, DiagnosisSettings, Linearized, check_data, fit_geometry, fit_nominal
from casadical.model import parse_spec
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM5


def _run(seed):
    robot = robot_from_dict(ARM5)
    data, _ = simulate(robot, 120, Effects(stiffness={2: 3e4}), seed=seed, floor_z=None)
    cal, val = data.subset(np.arange(80)), data.subset(np.arange(80, 120))
    run = DiagnosisRun(robot, cal, val, DiagnosisSettings(seed=seed), lambda _: None, None, {})
    for stage in (check_data, fit_nominal, fit_geometry):     # as the pipeline runs them
        made = stage(run)
        if made is not None:
            run.install(made)
    return run


def _same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])


@pytest.mark.parametrize("seed", [0, 1])
def test_kept_per_fit_and_the_same_as_made_afresh(seed):
    run = _run(seed)
    fits = [run.kinematic, run.nominal, run.fit(parse_spec("kinematic+compliance"), start=run.kinematic)]
    for res in fits + fits[::-1]:
        lin = run.linearized(res)
        assert run.linearized(res) is lin
        fresh = Linearized.of(res, run.cal)
        np.testing.assert_array_equal(lin.J, fresh.J)
        np.testing.assert_array_equal(lin.r, fresh.r)
        _same(run.held_out(res).errors, fresh.cv(run.schemes, run.prior).errors)
    # other folds (a design of one joint at a time gets its own): the held-out errors are made again for them
    res = fits[0]
    before = run.held_out(res)
    run.schemes = run.schemes[:2]
    after = run.held_out(res)
    assert after is not before and set(after.errors) == {s.name for s in run.schemes}
    _same(after.errors, Linearized.of(res, run.cal).cv(run.schemes, run.prior).errors)
