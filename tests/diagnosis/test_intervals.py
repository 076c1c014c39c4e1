"""Stage calibrate_intervals: the named causes' 95 % interval of a measured point, its factor calibrated on the
calibration poses' random folds (issue 38: intervals that cover 90-98 % of held-out poses)."""

import warnings

import numpy as np
import pytest

from casadical.calibration import load_calibration
from casadical.data import Measurements
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.prediction import CHI3_95, fold_interval_k, prediction_interval
from tests.helpers import hidden


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fold_interval_k_is_the_quantile_of_the_scaled_held_out_errors_never_below_chi3(seed):
    rng = np.random.default_rng(seed)
    std, sigma = rng.uniform(1e-6, 5e-6, 500), np.full(500, 20e-6)
    scale = np.sqrt(std ** 2 / 3 + sigma ** 2)
    wide = np.linalg.norm(rng.normal(0.0, 1.0, (500, 3)), axis=1) * 1.3 * scale     # errors 1.3x what it assumes
    k = fold_interval_k(wide, std ** 2, sigma)
    assert k == pytest.approx(np.quantile(wide / scale, 0.95))
    assert 1.15 * CHI3_95 < k < 1.45 * CHI3_95
    assert fold_interval_k(wide / 2, std ** 2, sigma) == CHI3_95       # narrower than chi_3's: the floor


@pytest.mark.parametrize("effect", ["axis tilt", "quadratic reading error"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_intervals_widen_by_what_the_folds_show_the_named_causes_miss(tmp_path, effect, seed):
    """Hidden on a 7-axis DH arm (not built in): an effect no catalogue cause explains (a joint's axis wobbling
    with its angle; a joint's error quadratic in its reading), no GP compensator: the named causes leave
    structure, and chi_3's factor held 81.5-92.2 % of 400 held-out poses (3 of these 6 runs below 90 %).
    The factor calibrated on the folds is above chi_3's, and holds 90-98 %; the calibration file keeps it and
    predict's interval is the diagnosis's."""
    c = hidden.case("arm7-dh", effect, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c, n_val=400)
        rep = diagnose(rob, cal, val, DiagnosisSettings(seed=seed, blackbox=False))
    final = rep.final
    k = final.uncertainty.interval_k
    err = np.linalg.norm(final.predict(val) - val.xyz, axis=1)
    radius = prediction_interval(final, val)
    inside, inside_chi3 = np.mean(err <= radius), np.mean(err <= radius * CHI3_95 / k)
    print(effect, seed, "k", k, "coverage", inside, "chi3", inside_chi3)
    assert k > CHI3_95 and inside > inside_chi3
    assert 0.90 <= inside <= 0.98, (inside, inside_chi3)
    assert rep.interval_coverage == pytest.approx(inside)
    path = tmp_path / "final.json"
    final.save(path)
    again = load_calibration(path)
    assert again.uncertainty.interval_k == pytest.approx(k)
    assert np.allclose(prediction_interval(again, val), radius, rtol=1e-6)


def test_no_fold_factor_on_a_weak_design(tmp_path):
    """24 poses moving one joint at a time on a 7-axis DH arm with a compliant joint 2 (the truth): a weak design,
    whose folds leave a joint's parameters to a handful of poses. Their errors measure the design, not the model
    fitted on every pose (they asked a factor of 29.5, ten times chi_3's, where the model misses the held-out poses
    by 0.08 mm): the interval keeps chi_3's factor."""
    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARM7_DH
    from tests.helpers.hidden import BASE_RPY, BASE_XYZ
    from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

    rng = np.random.default_rng(0)
    true = TrueRobot.draw(Arm.from_dict(ARM7_DH), Effects(stiffness={2: 2e4}), rng)
    home, lim, q = np.radians([0, 30, 0, -60, 0, 45, 0]), true.arm.limits, []
    for j in range(7):
        for x in np.linspace(0.2, 0.8, 4 if j < 3 else 3):
            pose = home.copy()
            pose[j] = lim[j, 0] + x * (lim[j, 1] - lim[j, 0])
            q.append(pose)
    session = Session("A", base_xyz=BASE_XYZ, base_rpy=BASE_RPY)
    data = [Measurements.read_csv(measure(true, poses, rng, session=session).write_csv(tmp_path / f"{name}.csv"),
                                  n_joints=7)
            for name, poses in (("cal", np.array(q[:24])), ("val", sample(true, 300, rng, floor_z=None)))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = diagnose(robot_from_dict(ARM7_DH, "arm7"), *data, DiagnosisSettings(seed=0))
    assert any(n.startswith("the design of the calibration poses is weak") for n in rep.notes), rep.notes
    assert "joint_compliance[2]" in rep.final_model
    assert rep.final.uncertainty.interval_k is None
