"""The superset: every model the diagnosis tries evaluated as a mask of one model per robot and sessions.

Its positions, orientation residuals and Jacobians (w.r.t. the parameters and the chain angles) must be the
model's own, on robots that are not built in (MDH and DH, beta or none, 3 to 7 joints), with every term the
superset expresses: periodic errors of any harmonic and joint couplings through the chain-angle offsets, the
mount's give, terms of one session
through per-pose parameters, thermal expansion and drifts against their own references.
"""

import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from casadical.data import Effects, sample_poses, simulate
from casadical.kinematics import base_pose_matrix
from casadical.model import Mapping, Model, batch, outputs, parse_spec, pose_to_base0, superset_for
from casadical.robot import robot_from_dict
from casadical.terms import REGISTRY, make_term, max_mount_moment
from tests.helpers.arms import ARM3, ARM4, ARM5, ARM5_COUPLED, ARM7, to_toml

#: every term the superset expresses, shared and of one session (two sessions, B with its own tool)
SPEC = ("kinematic+joint_compliance+nonlinear_stiffness[2]+encoder_scale[1,3]+backlash[2]+backlash_motion[1]"
        "+thermal_expansion+thermal_expansion[2]+joint_periodic[1:3,2:17,2:1]+joint_compliance[2]@B"
        "+encoder_scale[1]@A+backlash_motion[2]@B+joint_periodic[1:5]@B+drift@A+drift@B")


def two_session_model(robot, spec, orientation, seed):
    terms = parse_spec(spec + ("+tool_orientation" if orientation else ""))
    rng = np.random.default_rng(seed)
    for t in terms:
        if hasattr(t, "t_ref"):    # references as a calibration sets them: the means of its data
            t.t_ref = {"thermal_expansion": 24.5, "drift": 1000.0 + 300 * rng.random()}[t.name]
    frames = make_term("sessions", names=["A", "B"], tools=["B"])
    frames.set_reference("B", pose_to_base0(base_pose_matrix(rng.normal(size=3), 0.3 * rng.normal(size=3))))
    return Model(robot, terms + [frames])


def data(model, N, rng):
    """Poses, parameters off nominal by a few typical sizes, and covariates of both sessions."""
    q = sample_poses(model.robot, N, rng, floor_z=None)
    params = model.parameters
    values = params.values + 3 * rng.normal(size=len(params)) * params.scales
    sessions = rng.choice(["A", "B"], N)
    cov = np.zeros((N, len(model.covariate_names)))
    ref = model.term("sessions").references["B"]
    for k, name in enumerate(model.covariate_names):
        if name == "payload_kg":
            cov[:, k] = rng.uniform(0, 20, N)
        elif name == "temperature_c":
            cov[:, k] = rng.uniform(15, 35, N)
        elif name == "time_s":
            cov[:, k] = rng.uniform(0, 3600, N)
        elif name.startswith("move"):
            cov[:, k] = rng.choice([-1.0, 0.0, 1.0], N)
        elif name.startswith("session@"):
            cov[:, k] = sessions == name.split("@")[1]
        elif name.startswith("ref"):
            cov[:, k] = np.where(sessions == "B", ref[int(name[3:])], 0.0)
    R = np.array([base_pose_matrix((0, 0, 0), 0.5 * rng.normal(size=3))[:3, :3] for _ in range(N)])
    return q, values, cov, R


def assert_close(a, b, what):
    scale = max(float(np.abs(a).max()), 1e-300)
    assert np.abs(a - b).max() <= 1e-12 * scale, f"{what}: {np.abs(a - b).max():.3e} of {scale:.3e}"


@pytest.mark.parametrize("arm", [ARM3, ARM4, ARM5, ARM7], ids=["arm3-dh", "arm4-mdh", "arm5-dh-beta", "arm7-mdh-beta"])
@pytest.mark.parametrize("seed", [0, 1])
def test_the_superset_gives_every_models_own_numbers(arm, seed):
    robot = robot_from_dict(arm)
    spec = SPEC.replace("[1,3]", "[1,3]" if robot.n >= 3 else "[1]")
    # a joint coupling through the chain offsets (the robot's and a session's), the mount's give where masses are
    spec += f"+joint_coupling[{robot.n}:{robot.n - 1},2:1]+joint_coupling[1:{robot.n}]@B"
    if max_mount_moment(robot) > 0:
        spec += "+mount_compliance+mount_compliance@A"
    model = two_session_model(robot, spec, orientation=True, seed=seed)
    own = Model(robot, list(model.terms), jit=False)     # the same terms, evaluated on its own graph
    assert model._mapping is not None and model._mapping.per_pose
    rng = np.random.default_rng(seed)
    q, values, cov, R = data(model, 150, rng)
    b0 = model.base0_nominal()
    xyz, J, JA = own.predict_angle_jacobian(q, values, cov, b0)
    y, Js, JAs = outputs(model, "jac", q, values, cov, b0, compile=False)   # full pose: 6 rows, positions first
    assert_close(xyz, y[:, :3], "positions")
    assert_close(J, Js[:, :3], "Jacobian")
    assert_close(JA, JAs[:, :3], "angle Jacobian")
    xyz, Jp, ro, Jo = own.pose_jacobian(q, R, values, cov, b0)
    y, Js, _ = outputs(model, "pose_jac", q, values, cov, b0, R.reshape(-1, 9), compile=False)
    assert_close(np.concatenate([xyz, ro], 1), y, "positions and orientation residuals")
    assert_close(np.concatenate([Jp, Jo], 1), Js, "full-pose Jacobian")
    assert_close(xyz, outputs(model, "fk", q, values, cov, b0, compile=False)[:, :3], "fk")
    probe = outputs(model, "probe", q, values, cov, b0, compile=False).reshape(-1, 3, 3).transpose(0, 2, 1)
    assert_close(own.probe_rotation(q, values, cov, b0), probe, "probe rotation")
    # each column is the model's: a parameter moved by a small step moves the superset's prediction by it
    k = model.parameters.index("gear1_s5@B")
    step = np.zeros_like(values)
    step[k] = 1e-6
    moved = outputs(model, "fk", q, values + step, cov, b0, compile=False)[:, :3]
    assert np.abs((moved - y[:, :3]) / 1e-6 - Js[:, :3, k]).max() < 1e-4 * np.abs(Js[:, :3, k]).max()


@pytest.mark.parametrize("arm", [ARM4, ARM7], ids=["arm4-mdh", "arm7-mdh-beta"])
@pytest.mark.parametrize("orientation", [False, True])
@pytest.mark.parametrize("block", [None, 50])
def test_session_compensators_map_onto_the_superset(arm, orientation, block, monkeypatch):
    """A GP compensator's Gaussian process (frozen: evaluated in numpy, an offset of the tool point before
    the base pose) gives the model's own graph's positions, orientation residuals and Jacobians, where its
    gate and its session say it applies and nowhere else; also where the poses are evaluated in blocks (``block``:
    the processes' predictions are made at every pose of their session once, then taken block by block)."""
    from casadical.compensators import ResidualGP
    from casadical.model import _superset as superset
    from casadical.terms import SessionLocal

    if block is not None:
        monkeypatch.setattr(superset, "BLOCK", block)
    robot = robot_from_dict(arm)
    rng = np.random.default_rng(5)
    model0 = two_session_model(robot, "kinematic+joint_compliance+joint_periodic[2:17]", orientation, 5)
    gps = []
    for s in "AB":
        X = sample_poses(robot, 30, rng, floor_z=None)
        gps.append(SessionLocal(make_term("gp_compensator", gp=ResidualGP(
            X, 1e-4 * rng.normal(size=(30, 3)), rng.uniform(0.3, 1.5, (3, robot.n)), np.ones(3),
            np.full(3, 0.05), 1e-5 * rng.normal(size=3), np.full(3, 1e-4))), s))
    model = Model(robot, list(model0.terms) + gps)
    own = Model(robot, list(model.terms), jit=False)
    assert model._mapping is not None and len(model._mapping.compensators) == 2
    q, values, cov, R = data(model, 120, rng)
    for k, name in enumerate(model.covariate_names):
        if name.startswith("gp_gate@"):
            cov[:, k] = rng.random(120) < 0.7
    b0 = model.base0_nominal()
    which = "pose_jac" if orientation else "jac"
    y, Js, _ = outputs(model, which, q, values, cov, b0, R.reshape(-1, 9) if orientation else None, compile=False)
    if orientation:
        xyz, J, ro, Jo = own.pose_jacobian(q, R, values, cov, b0)
        xyz, J = np.concatenate([xyz, ro], 1), np.concatenate([J, Jo], 1)
        probe = outputs(model, "probe", q, values, cov, b0, compile=False).reshape(-1, 3, 3).transpose(0, 2, 1)
        assert_close(own.probe_rotation(q, values, cov, b0), probe, "probe rotation (the offsets do not turn it)")
    else:
        xyz, J = own.predict_jacobian(q, values, cov, b0)
    assert_close(xyz, y, "positions")
    assert_close(J, Js, "Jacobian")
    off = own.predict(q, values, cov, b0) - model0.predict(q, values[:len(model0.parameters)], cov[:, :len(
        model0.covariate_names)], b0)
    assert np.abs(off).max() > 1e-6      # the processes do move the tool point (the test can fail)


@pytest.mark.parametrize("spec", ["nominal", "kinematic", "kinematic+joint_compliance[2]+joint_periodic[2:8]"])
def test_a_model_of_one_session_broadcasts_its_parameters(spec):
    robot = robot_from_dict(ARM5)
    model = Model(robot, spec)
    own = Model(robot, spec, jit=False)
    rng = np.random.default_rng(3)
    q = sample_poses(robot, 40, rng, floor_z=None)
    values = model.parameters.values + rng.normal(size=len(model.parameters)) * model.parameters.scales
    cov = model.default_covariates(40)
    assert not model._mapping.per_pose
    xyz, J = own.predict_jacobian(q, values, cov)
    y, Js, _ = outputs(model, "jac", q, values, cov, model.base0_nominal(), compile=False)
    assert_close(xyz, y, "positions")
    assert_close(J, Js, "Jacobian")


@pytest.mark.parametrize("terms", [
    lambda: [make_term("backlash_motion", joints=[2], lag=False)],             # files older than the lag convention
    lambda: parse_spec("drift+drift@B"),                                        # two references of one covariate
    lambda: [make_term("thermal_expansion", t_ref=20.0), make_term("thermal_expansion", joints=[2], t_ref=25.0)],
    lambda: [make_term("rbf_compensator")],                                     # a network in the graph
])
def test_what_the_superset_cannot_express_runs_on_the_models_own_graph(terms):
    model = Model(robot_from_dict(ARM4), terms())
    assert Mapping.of(model) is None and model._mapping is None


@pytest.mark.parametrize("cls", sorted({c for c in REGISTRY.values() if getattr(c, "LEGACY", None)},
                                       key=lambda c: c.name), ids=lambda c: c.name)
def test_a_calibration_file_older_than_a_convention_is_not_predicted_by_the_new_one(cls):
    """A term as a file older than one of its settings reads it (its class' LEGACY) either maps onto the
    superset with the model's own positions and Jacobian, or runs on its own graph: on the coupled arm, where
    the conventions differ, the superset (which has the new ones) must never stand in for it."""
    robot = robot_from_dict(ARM5_COUPLED)
    joints = [2] if cls.name != "geometric" else None
    terms = [make_term("geometric", **(cls.LEGACY if cls.name == "geometric" else {})),
             make_term("joint_compliance", joints=[2]), make_term("encoder_scale", joints=[2])]
    if cls.name != "geometric":
        terms.append(make_term(cls.name, joints=joints, **cls.LEGACY))
    model = Model(robot, terms)
    if model._mapping is None:
        return
    own = Model(robot, terms, jit=False)
    rng = np.random.default_rng(4)
    q = sample_poses(robot, 30, rng, floor_z=None)
    values = model.parameters.values + 0.1 * rng.normal(size=len(model.parameters)) * model.parameters.scales
    cov = model.default_covariates(30)
    xyz, J = own.predict_jacobian(q, values, cov)
    y, Js, _ = outputs(model, "jac", q, values, cov, model.base0_nominal(), compile=False)
    assert_close(xyz, y, "positions")
    assert_close(J, Js, "Jacobian")


def test_a_model_without_jit_never_maps():
    assert Model(robot_from_dict(ARM4), "kinematic", jit=False)._mapping is None


def test_periodic_columns_are_exact_at_any_harmonic():
    """A harmonic is data, not a graph: the 40th harmonic's columns are the derivative of its own model's."""
    robot = robot_from_dict(ARM7)
    model = Model(robot, "kinematic+joint_periodic[4:40]")
    rng = np.random.default_rng(5)
    q = sample_poses(robot, 30, rng, floor_z=None)
    values = model.parameters.values.copy()
    values[model.parameters.index("gear4_c40")] = math.radians(0.01)
    cov = model.default_covariates(30)
    own = Model(robot, "kinematic+joint_periodic[4:40]", jit=False)
    xyz, J = own.predict_jacobian(q, values, cov)
    y, Js, _ = outputs(model, "jac", q, values, cov, model.base0_nominal(), compile=False)
    assert_close(xyz, y, "positions")
    assert_close(J, Js, "Jacobian")


# --- compiled once per machine -------------------------------------------------------------------

needs_compiler = pytest.mark.skipif(not (shutil.which("gcc") or shutil.which("cc")), reason="no C compiler")


@needs_compiler
def test_the_compiled_superset_gives_the_vms_bits(tmp_path, monkeypatch):
    """CasADi's VM and the compiled library give the same bits: a failed compile falls back to the VM, and
    which of them evaluates never changes a result."""
    monkeypatch.setenv("CASADICAL_CACHE", str(tmp_path / "cache"))
    robot = robot_from_dict(ARM3)
    model = two_session_model(robot, "kinematic+joint_compliance+backlash[2]+joint_periodic[1:4]+drift@B",
                              orientation=True, seed=2)
    q, values, cov, R = data(model, 120, np.random.default_rng(2))
    m = model._mapping
    P, C = m.inputs(q, values, cov)
    sup = superset_for(lambda terms: Model(robot, terms, jit=False), robot, model.term("sessions"))
    for which in ("fk", "jac", "pose_fk", "pose_jac"):
        compiled, used = sup.resolve(which, compile=True)
        assert used == which and compiled.class_name() == "External"
        ins = [q, P, C, model.base0_nominal()] + ([R.reshape(-1, 9)] if which.startswith("pose_") else [])
        vm, cc = (batch(lambda n, f=f: f.map(f"m{n}", "serial", n, [3], []), len(q), [3], True)(*ins)
                  for f in (sup.function(which), compiled))
        for a, b in zip(vm, cc):
            assert np.array_equal(a, b), which


@needs_compiler
def test_a_first_run_says_it_compiles_and_a_second_compiles_nothing(tmp_path):
    """The command line says once, before the compiler starts, that it compiles the robot's model; the cache
    then holds the superset's functions (none of one model), and the next run compiles nothing and gives the
    same numbers."""
    robot_file = tmp_path / "arm.toml"
    robot_file.write_text(to_toml(ARM3))
    data_, _ = simulate(robot_from_dict(ARM3), 120, Effects(stiffness={2: 4e5}), seed=1, floor_z=None)
    data_.write_csv(tmp_path / "d.csv")
    env = {**os.environ, "CASADICAL_JIT": "1", "CASADICAL_CACHE": str(tmp_path / "cache")}
    runs = []
    for k in range(2):
        out = tmp_path / f"cal{k}.json"
        r = subprocess.run([sys.executable, "-m", "casadical", "calibrate", str(robot_file), str(tmp_path / "d.csv"),
                            "--model", "kinematic+compliance[2]", "--out", str(out)], capture_output=True, text=True,
                           env=env)
        assert r.returncode == 0, r.stderr
        said = [line for line in r.stderr.splitlines() if line.startswith("compiling the model of")]
        runs.append((said, sorted(p.name.split("-")[0] for p in (tmp_path / "cache").iterdir()),
                     json.loads(out.read_text())["parameters"]))
    (said0, cache0, p0), (said1, cache1, p1) = runs
    # about 1 s with the quick compile (a core free), 2 s at -O1 at once (a loaded machine: jitcache.spare_core)
    assert said0 in [[f"compiling the model of three-axis test arm for these data (about {t} s, more if the run "
                      "needs further parts; once: later runs load it from the cache)"] for t in (1, 2)], said0
    assert said1 == [] and cache1 == cache0 == ["superset_fk", "superset_jac"]
    assert p0 == p1


@needs_compiler
def test_a_run_that_compiles_several_parts_says_so_once(tmp_path):
    """A diagnosis compiles several parts of the model (with and without the gravity torques) into an empty
    cache: its notice comes once, not once per part (issue 47: four times in one run of the README job); the
    next run, from the cache, says nothing."""
    (tmp_path / "arm.toml").write_text(to_toml(ARM5))
    robot = robot_from_dict(ARM5)
    cal, truth = simulate(robot, 150, Effects(stiffness={2: 4e5}), seed=1, floor_z=None)
    val, _ = simulate(robot, 120, Effects(stiffness={2: 4e5}), truth=truth, seed=2, floor_z=None)
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    env = {**os.environ, "CASADICAL_JIT": "1", "CASADICAL_CACHE": str(tmp_path / "cache")}
    said, parts = [], []
    for k in range(2):
        r = subprocess.run([sys.executable, "-m", "casadical", "diagnose", str(tmp_path / "arm.toml"),
                            str(tmp_path / "cal.csv"), "--validate", str(tmp_path / "val.csv"), "--no-blackbox",
                            "--out", str(tmp_path / f"final{k}.json")], capture_output=True, text=True, env=env)
        assert r.returncode == 0, r.stderr
        said.append([line for line in r.stderr.splitlines() if line.startswith("compiling the model of")])
        parts.append(sorted(p.name for p in (tmp_path / "cache").iterdir()))
    assert len(said[0]) == 1 and said[1] == [], said
    assert len(parts[0]) >= 4 and parts[1] == parts[0]      # more than one part was compiled, said once


@needs_compiler
@pytest.mark.parametrize("spare", [True, False])
def test_the_quick_compile_only_where_a_core_is_free(tmp_path, monkeypatch, spare):
    """A core free (jitcache.spare_core): the superset's Jacobian is compiled quickly, used at once, and
    optimised in the background, which a later evaluation takes when ready and the cache keeps; a loaded
    machine compiles it optimised at once. Either way the VM's bits."""
    from casadical.model import _jitcache as jitcache

    monkeypatch.setenv("CASADICAL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(jitcache, "QUICK_MIN_INSTRUCTIONS", 0)          # the test arm's Functions are small
    monkeypatch.setattr(jitcache, "spare_core", lambda: spare)
    robot = robot_from_dict(ARM3)
    model = two_session_model(robot, "kinematic+joint_compliance+drift@B", orientation=False, seed=5)
    q, values, cov, _ = data(model, 120, np.random.default_rng(5))
    P, C = model._mapping.inputs(q, values, cov)
    sup = superset_for(lambda terms: Model(robot, terms, jit=False), robot, model.term("sessions"))
    ins = [q, P, C, model.base0_nominal()]
    ref = batch(lambda n: sup.function("jac").map(f"m{n}", "serial", n, [3], []), len(q), [3], True)(*ins)
    first, _ = sup.resolve("jac", compile=True)
    assert first.class_name() == "External" and jitcache.pending(sup.function("jac")) == spare
    def kept():
        folder = tmp_path / "cache"
        return sorted(p.name.split("-")[0] for p in folder.iterdir()) if folder.exists() else []

    assert kept() == ([] if spare else ["superset_fk", "superset_jac"])
    if spare:       # gcc -O1 done: the next evaluation takes its code (and the cache keeps it)
        for which in ("fk", "jac"):
            jitcache._PENDING[id(sup.function(which))].process.wait()
    later, _ = sup.resolve("jac", compile=True)
    sup.resolve("fk", compile=True)
    assert later.class_name() == "External" and not jitcache.pending(sup.function("jac"))
    assert (later is not first) == spare
    assert kept() == ["superset_fk", "superset_jac"]
    for fun in (first, later):
        got = batch(lambda n, f=fun: f.map(f"m{n}", "serial", n, [3], []), len(q), [3], True)(*ins)
        assert all(np.array_equal(a, b) for a, b in zip(got, ref))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_periodic_columns_factors_are_each_columns_own(seed):
    """The factors of the periodic columns, made side by side (:meth:`Mapping.features`): each a coupling's source
    reading, or the sine or cosine of a harmonic times its joint's reading (per metre on a linear axis: 2 pi per
    metre), times its session's indicator for a column of one session; as one column alone makes it."""
    from tests.helpers.arms import ARM4_TRACK

    robot = robot_from_dict(ARM4_TRACK)
    model = two_session_model(robot, "kinematic+joint_periodic[1:3,2:17,4:1]+joint_coupling[3:2]+joint_periodic[1:5]@B"
                              "+joint_coupling[4:2]@A", False, seed)
    m = model._mapping
    rng = np.random.default_rng(seed)
    sets = [data(model, 70, rng) for _ in range(3)]
    sets.append((sets[0][0], None, 1.0 - sets[0][2], None))     # the same poses, the sessions swapped
    for q, _, cov, _ in [sets[int(rng.integers(len(sets)))] for _ in range(12)]:     # asked again (kept factors)
        F = m.features(q.copy(), cov.copy())
        assert F.shape == (70, len(m.periodic)) and len(m.periodic) == 2 * 4 + 2
        check_factors(m, robot, q, cov, F)


def check_factors(m, robot, q, cov, F):
    for k, i in enumerate(m.periodic):
        c = m.columns[i]
        if c.kind == "q":
            f = q[:, c.source - 1]
        else:
            j = c.index - m.n_params
            x = c.harmonic * q[:, j] * (2 * np.pi if robot.prismatic[j] else 1.0)
            f = np.sin(x) if c.kind == "s" else np.cos(x)
        f = f if m.at[i] < 0 else f * cov[:, m.at[i]]
        assert np.allclose(F[:, k], f, rtol=1e-15, atol=0), (c, np.abs(F[:, k] - f).max())
