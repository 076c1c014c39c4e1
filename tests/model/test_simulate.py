"""The simulator: hidden effects enter as specified, reproducibly, within the workspace."""

import math

import numpy as np
import pytest

from casadical import Model, load_robot
from casadical.data import Effects, load_protocol, sample_poses, simulate
from tests.helpers.cli import cli, one_error


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compliance_displacement_matches_torque(seed):
    robot = load_robot("ys100")
    eff = Effects(stiffness={2: 1e6}, noise=0.0, length_sigma=0, angle_sigma=0)
    data, truth = simulate(robot, 30, eff, seed=seed)
    rigid = Model(robot, "nominal").predict(data.q)
    model = Model(robot, "kinematic+compliance[2]")
    tau = model.torques(data.q)
    # the deflected robot is the rigid one with joint 2 turned by tau2 / k2
    kin = Model(robot, "kinematic")
    expected = []
    for qi, t in zip(data.q, tau[:, 1]):
        p = kin.parameters.values
        p[kin.parameters.index("theta2")] += t / 1e6
        expected.append(kin.predict(qi[None], p)[0])
    np.testing.assert_allclose(data.xyz, np.array(expected), atol=1e-12)
    assert np.abs(data.xyz - rigid).max() > 1e-4  # the effect is really there


def test_reproducible_and_seed_dependent():
    robot = load_robot("ys100")
    a, _ = simulate(robot, 10, seed=4)
    b, _ = simulate(robot, 10, seed=4)
    c, _ = simulate(robot, 10, seed=5)
    np.testing.assert_array_equal(a.xyz, b.xyz)
    assert not np.allclose(a.xyz, c.xyz)


def test_workspace_filter_and_limits():
    robot = load_robot("ys100")
    rng = np.random.default_rng(0)
    q = sample_poses(robot, 200, rng, floor_z=0.5)
    xyz = Model(robot, "nominal").predict(q)
    assert (xyz[:, 2] > 0.5).all()
    assert (q >= robot.limits[:, 0]).all() and (q <= robot.limits[:, 1]).all()
    box = ((0.5, -1.0, 0.0), (2.0, 1.0, 2.0))
    xyz = Model(robot, "nominal").predict(sample_poses(robot, 50, rng, box=box))
    assert (xyz >= box[0]).all() and (xyz <= box[1]).all()


def test_hidden_effects_each_change_positions():
    robot = load_robot("ys100")
    base = Effects(noise=0.0)
    ref, truth0 = simulate(robot, 20, base, seed=1)
    for eff in [Effects(noise=0.0, periodic=[(2, 3, math.radians(0.02), 0.4)]),
                Effects(noise=0.0, encoder_scale={3: 2e-4}),
                Effects(noise=0.0, backlash={2: math.radians(0.01)}),
                Effects(noise=0.0, thermal_alpha=12e-6)]:
        d, t = simulate(robot, ref.q, eff, seed=1)
        diff = np.linalg.norm(d.xyz - truth0.predict(ref), axis=1)
        assert diff.max() > 2e-5, eff
    d, _ = simulate(robot, 20, Effects(thermal_alpha=12e-6), seed=1)
    assert d.get("temperature_c") is not None


def test_measurement_frame_and_noise():
    robot = load_robot("ys100")
    eff = Effects(noise=50e-6, base_xyz=(3.0, -1.0, 0.5), base_rpy=(0.0, 0.0, 2.0))
    d, truth = simulate(robot, 300, eff, seed=3)
    resid = d.xyz - truth.predict(d)
    assert abs(resid.std() - 50e-6) < 5e-6
    assert np.linalg.norm(d.xyz.mean(0) - np.array([3.0, -1.0, 0.5])) < 3.0


@pytest.mark.parametrize("name", ["ca-ys100", "ga-ys100-pool", "tlbo-hh800"])
def test_protocols_generate(name):
    proto = load_protocol(name)
    sets, truth = proto.generate()
    assert sum(len(s) for s in sets.values()) == sum(proto.sets.values())
    for s in sets.values():
        assert s.has_positions


def test_protocol_file_with_a_byte_order_mark_and_a_huge_number(tmp_path):
    """Protocols are read like robot files (UTF-8 BOM skipped); an integer beyond float range is one clear error."""
    import pytest

    from casadical.errors import InputError
    from casadical.robot import PROBLEMS

    text = (PROBLEMS / "protocols" / "ca-ys100.toml").read_text(encoding="utf-8")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert load_protocol(str(bom)).name == load_protocol("ca-ys100").name
    huge = tmp_path / "huge.toml"
    huge.write_text(text.replace("[truth]", "[truth]\nperiodic_deg = [[2, 1, 1" + "0" * 400 + ", 0]]", 1),
                    encoding="utf-8")
    with pytest.raises(InputError, match=r"periodic_deg\[1\]"):
        load_protocol(str(huge))


# --- a malformed protocol is one line (issue 10) ----------------------------------------------


@pytest.mark.parametrize("text", [
    'robot = "ys100"\nsets = 3\n',
    'robot = "ys100"\n[sets]\na = "x"\n',
    'robot = "ys100"\n[sets]\na = 5\n[truth]\nperiodic_deg = [[1, 2]]\n',
    'robot = "ys100"\n[sets]\na = 5\n[workspace]\nbox_min_m = [0, 0]\nbox_max_m = [1, 1, 1]\n',
    'robot = "nosuch.toml"\n[sets]\na = 5\n',
])
def test_malformed_protocol(tmp_path, capsys, text):
    (tmp_path / "p.toml").write_text(text)
    code, _, err = cli(capsys, "simulate", tmp_path / "p.toml", "--out-dir", tmp_path / "out")
    assert code == 2
    one_error(err)
