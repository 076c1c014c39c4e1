"""A screen's validation errors of its one-step fits (a judge of every candidate): the columns kept column by column
in memory and each candidate's made once give, in any order of asking, the validation residual plus the fit's step
along the model's and the candidate's columns, computed here from the model's Jacobian at the validation poses."""

import numpy as np
import pytest

from casadical import calibrate
from casadical.data import Effects, simulate
from casadical.diagnosis import Candidate, Screen, periodic_columns
from casadical.robot import robot_from_dict
from casadical.terms import phase
from tests.helpers.arms import ARM5


@pytest.mark.filterwarnings("ignore::casadical.errors.CorrelationWarning")
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_validation_errors_are_the_steps_along_the_columns(seed):
    robot = robot_from_dict(ARM5)
    data, _ = simulate(robot, 160, Effects(), seed=seed, floor_z=None)
    cal, val = data.subset(np.arange(100)), data.subset(np.arange(100, 160))
    current = calibrate(robot, cal, model="kinematic")
    cands = [Candidate("joint_compliance", 2), Candidate("joint_periodic", 3, harmonic=2),
             Candidate("joint_periodic", 1, harmonic=5), Candidate("encoder_scale", 4)]
    scr = Screen(current, [], cands, True, cal, val)
    big, p = scr.model, scr.model_params
    xyz, J, JA = big.predict_angle_jacobian(val.q, p.values, big.covariates(val), current.base0)
    r, J = xyz - val.xyz, J[:, :, scr.free] * p.scales[scr.free]
    n_model = J.shape[2]
    rng = np.random.default_rng(seed)
    for c in [cands[int(i)] for i in rng.integers(len(cands), size=8)] + [None]:
        fit = scr.fit(c)
        cols = [J[:, :, k] if k < n_model else scr._column(*scr.extra[k - n_model], val, J, JA) for k in fit.cols]
        want = np.linalg.norm(r + np.einsum("kni,k->ni", np.array(cols), fit.step), axis=1)
        assert np.allclose(scr.validation_errors(fit), want, rtol=1e-10, atol=1e-15)


@pytest.mark.filterwarnings("ignore::casadical.errors.CorrelationWarning")
def test_a_periodic_candidates_columns_are_its_sine_and_cosine():
    """Each column of a periodic candidate, made alone: the joint's angle direction times the sine (first) and the
    cosine (second) of the harmonic of its reading, at the calibration and the validation poses."""
    robot = robot_from_dict(ARM5)
    data, _ = simulate(robot, 90, Effects(), seed=4, floor_z=None)
    cal, val = data.subset(np.arange(60)), data.subset(np.arange(60, 90))
    current = calibrate(robot, cal, model="kinematic")
    cands = [Candidate("joint_periodic", j, harmonic=h) for j, h in ((1, 1), (3, 7), (5, 23))]
    scr = Screen(current, [], cands, True, cal, val)
    for d in (cal, val):
        big, p = scr.model, scr.model_params
        _, J, JA = big.predict_angle_jacobian(d.q, p.values, big.covariates(d), current.base0)
        for c in cands:
            both = periodic_columns(JA[:, :, c.joint - 1], phase(robot, c.joint, d.q[:, c.joint - 1]), c.harmonic)
            for k in (0, 1):
                scale = scr.params[c.parameter_names()[k]].scale
                assert np.array_equal(scr._column(c, k, d, J, JA), both[:, :, k] * scale)
