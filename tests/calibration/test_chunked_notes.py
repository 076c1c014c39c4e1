"""The sag note and the set-aside tests read the poses chunk by chunk (casadical.runtime._chunks.pose_chunks) and the
angle Jacobian of the set-aside poses alone: the same figures as all poses at once, on arms not built in."""

import numpy as np
import pytest

import casadical.runtime._chunks as chunks
from casadical import calibrate
from casadical.data import Effects, Measurements, simulate
from casadical.robot import robot_from_dict
from casadical.stats import first_order_sag, of_model, set_aside_structure
from tests.helpers.arms import ARM4, ARM5


@pytest.mark.parametrize("arm,seed", [(ARM4, 0), (ARM5, 1), (ARM5, 2)])
def test_chunked_sag_and_set_aside_are_those_of_all_poses(arm, seed, monkeypatch):
    robot = robot_from_dict(arm)
    data, _ = simulate(robot, 90, Effects(stiffness={2: 2e4, 3: 1e4}), seed=seed, floor_z=None)
    rng = np.random.default_rng(seed)
    bad = rng.choice(len(data), 6, replace=False)        # bad measurements: 1.5 mm off in any direction
    shot = rng.normal(size=(6, 3))
    xyz = data.xyz.copy()
    xyz[bad] += 1.5e-3 * shot / np.linalg.norm(shot, axis=1)[:, None]
    data = Measurements.from_arrays(data.q, xyz)
    res = calibrate(robot, data, "kinematic+compliance", "lm", warn=False)
    m, v, cov = res.model, res.parameters.values, res.model.covariates(data)
    flagged = np.zeros(len(data), bool)
    flagged[bad] = True

    monkeypatch.setattr(chunks, "CHUNK", 10 ** 9)          # one chunk: every pose at once
    sags, leaves = first_order_sag(res, data)
    monkeypatch.setattr(chunks, "CHUNK", 37)               # three chunks of uneven size
    sags_c, leaves_c = first_order_sag(res, data)
    assert sags and leaves > 0
    assert [(s.joint, s.sag_rad, s.leaves_m) for s in sags_c] == [(s.joint, s.sag_rad, s.leaves_m) for s in sags]
    assert leaves_c == leaves

    # the tests on every pose's residuals, directions and torques (as before the change) against of_model's
    xyz, _, directions = m.predict_angle_jacobian(data.q, v, cov, res.base0)
    whole = set_aside_structure(data, flagged, data.xyz - xyz, directions, m.torques(data.q, v, cov))
    chunked = of_model(m, v, res.base0, data, flagged, cov)
    assert chunked.to_dict() == whole.to_dict() and chunked.text() == whole.text()
    assert [t.to_dict() for t in chunked.tests] == [t.to_dict() for t in whole.tests]
    assert any(t.kind == "direction" for t in chunked.tests)
