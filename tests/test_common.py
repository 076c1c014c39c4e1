"""Common checks: every registered error term and every registered method through the same checks.

As scikit-learn's ``check_estimator`` runs every estimator through one set of checks, this file is
parametrised over the registries (:data:`casadical.terms.REGISTRY`, :func:`casadical.methods.method_names`):
a new term or method is checked without editing it. A term that needs more than its defaults to be built
(joints, harmonics, session names, a fitted process) says so in :data:`BUILD`; a check that cannot apply to a
term is skipped with its reason in :data:`SKIP` (shown by ``pytest -rs``), never silently.

Terms, on a model of the YS100 (the built-in six-axis arm) holding the term:
  * the model's outputs have their sizes (positions, Jacobians, torques, joint offsets, covariates) at 1 and
    4 poses;
  * the Jacobian of the tool point w.r.t. the term's parameters is the central finite difference of the
    positions, at a parameter point away from nominal, to a relative 1e-6;
  * every parameter has finite bounds or a reason in :data:`UNBOUNDED`, and starts inside them;
  * a calibration whose model holds the term reads back from its JSON to the same predictions (1e-12).
Methods, on 20 simulated poses (few generations and epochs):
  * each runs and returns a MethodResult whose statistics are those of its predictions, with a JSON entry;
  * the same seed gives the same result;
  * the calibration underneath reads back from its JSON to the same predictions (1e-12).
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from casadical import calibrate, load_calibration, load_robot
from casadical.compensators import RBFNetwork, ResidualGP
from casadical.data import Effects, another_session, combine, sample_poses, simulate
from casadical.methods import MethodResult, lookup, method_names, run_method
from casadical.model import Model
from casadical.terms import REGISTRY, make_term

ROBOT = load_robot("ys100")
#: the YS100 on a 4 m track (joint 1 a linear axis): the robot of the terms of a linear axis (:data:`ON_TRACK`)
TRACK = load_robot(str(Path(__file__).resolve().parents[1] / "problems" / "robots" / "track6.toml"))
#: terms of a linear axis only, checked on :data:`TRACK` and its data
ON_TRACK = ("straightness", "carriage_angle")


def robot_of(name: str):
    return TRACK if name in ON_TRACK else ROBOT


def term_names() -> list[str]:
    """Every registered term once (aliases name the same class)."""
    return sorted({cls.name for cls in REGISTRY.values()})


def _gp(robot, rng):
    """A Gaussian process of the residual, as a calibration fits one (hyperparameters drawn, not fitted)."""
    X = sample_poses(robot, 30, rng, floor_z=None)
    return ResidualGP(X, 1e-4 * rng.normal(size=(30, 3)), rng.uniform(0.3, 1.5, (3, robot.n)), np.ones(3),
                      np.full(3, 0.05), 1e-5 * rng.normal(size=3), np.full(3, 1e-4))


def _rbf(robot, rng):
    """An RBF network fitted to a smooth offset of the compensator's features (sin q, cos q, torques)."""
    X = rng.normal(size=(40, 3 * robot.n))
    return RBFNetwork(n_centers=8, width=2.0).fit(X, 1e-4 * np.tanh(X[:, :3]))


#: how a term is built for the model checks, where its defaults are not enough (any other: ``make_term(name)``,
#: every joint)
BUILD = {
    "joint_periodic": lambda robot, rng: make_term("joint_periodic", harmonics=[(2, 1), (3, 2)]),
    "joint_coupling": lambda robot, rng: make_term("joint_coupling", pairs=[(3, 2), (2, 1)]),
    "sessions": lambda robot, rng: make_term("sessions", names=["A", "B"], tools=["B"], references={
        "B": [0, -1, 0, 1, 0, 0, 0, 0, 1, 1.2, -0.8, 0.1]}),
    "gp_compensator": lambda robot, rng: make_term("gp_compensator", gp=_gp(robot, rng)),
    "rbf_compensator": lambda robot, rng: make_term("rbf_compensator", network=_rbf(robot, rng)),
    "tool_points": lambda robot, rng: make_term("tool_points", names=["smr1", "smr2"]),
}

#: the model specification a calibration with the term is asked for, where it is not ``kinematic+<term spec>``
CALIBRATE = {
    "sessions": "kinematic",            # data of two sessions: the calibration adds the term itself
    "joint_periodic": "kinematic+joint_periodic[2:1,3:2]",
    "tool_points": "kinematic",         # rows naming their tool point: the calibration adds the term itself
}

#: checks that cannot apply to a term, and why (checks: "sizes", "derivatives", "bounds", "json")
SKIP = {
    ("derivatives", "gp_compensator"): "no parameters: the process is fitted after the model, then frozen",
    ("derivatives", "rbf_compensator"): "no parameters: the network is fitted after the model, then frozen",
    ("bounds", "gp_compensator"): "no parameters: the process is fitted after the model, then frozen",
    ("bounds", "rbf_compensator"): "no parameters: the network is fitted after the model, then frozen",
}

#: parameters without finite bounds, by (term, name prefix), and why
UNBOUNDED = {
    ("geometric", "base_"): "the base pose is where the tracker stands: any pose",
    ("sessions", "base_"): "each session's base pose is where its tracker stood: any pose",
    ("tool_orientation", "tool_"): "the probe may be mounted at any rotation",
    ("tool_points", "tool_"): "a tool point the robot file does not declare ([tool.NAME]) may sit anywhere on the "
                              "tool (a declared one is bounded: its nominal +- the geometry's box)",
    ("nonlinear_stiffness", "cubic"): "a progressive spring may stiffen or soften (either sign, any size); "
                                      "the physics rules judge its value (casadical/stats/_physics.py)",
}


def terms_for(check: str) -> list:
    """Every registered term, as parameters of ``check``: those it cannot apply to skipped with the reason."""
    return [pytest.param(n, marks=pytest.mark.skip(reason=f"{n}: {SKIP[check, n]}")) if (check, n) in SKIP else n
            for n in term_names()]


def build(name: str, robot=None):
    robot = robot_of(name) if robot is None else robot
    return BUILD.get(name, lambda robot, rng: make_term(name))(robot, np.random.default_rng(0))


@pytest.fixture(scope="module")
def campaign():
    """Two sessions of the YS100 (the tracker moved, the probe re-mounted), with the covariates a term may read:
    times, temperatures, payloads. ``one``: session A alone; ``full``: A with measured orientations."""
    effects = Effects(stiffness={2: 1.5e6, 3: 9e5})
    a, truth = simulate(ROBOT, 40, effects, seed=1)
    tb = another_session(truth, (1.2, -0.8, 0.1), (0.0, 0.0, 1.6), tool_shift=(0.003, -0.002, 0.004))
    b, _ = simulate(ROBOT, 40, truth=tb, seed=2)
    full, _ = simulate(ROBOT, 40, Effects(stiffness={2: 1.5e6}, orientation_noise=math.radians(0.01)), seed=3)
    rng = np.random.default_rng(4)
    for d in (a, b, full):
        d.columns["time_s"] = np.sort(rng.uniform(0, 3600, len(d)))
        d.columns["temperature_c"] = rng.uniform(18, 28, len(d))
        d.columns["payload_kg"] = rng.uniform(0, 5, len(d))
    a.path, b.path = "A.csv", "B.csv"
    track, _ = simulate(TRACK, 40, Effects(stiffness={3: 1.5e6}), seed=5)
    # a tool of two points, each pose's rows alternating between them (a tool column)
    tools = replace(a, columns={**a.columns, "tool": np.array(["smr1", "smr2"] * (len(a) // 2), dtype=object)})
    return {"one": a, "two": combine([a, b]), "full": full, "track": track, "tools": tools}


def data_of(name: str, model: Model, campaign: dict):
    """The campaign's data a check of the term ``name`` runs on."""
    if name in ON_TRACK:
        return campaign["track"]
    if name == "tool_points":
        return campaign["tools"]
    return campaign["two"] if name == "sessions" else campaign["full"] if model.orientation else campaign["one"]


def model_of(name: str) -> tuple[Model, list[str]]:
    """The YS100's model holding the term (and the geometry), and the names of the term's parameters."""
    term, robot = build(name), robot_of(name)
    model = Model(robot, [term] if name == "geometric" else [make_term("geometric"), term])
    return model, [p.name for p in term.parameters(robot)]


def away_from_nominal(model: Model, rng) -> np.ndarray:
    """Parameter values within bounds, each some of its scale away from nominal (not a special point)."""
    v = np.array([p.nominal + rng.uniform(0.3, 1.0) * rng.choice([-1, 1]) * p.scale for p in model.parameters])
    lo = np.array([p.lower for p in model.parameters])
    hi = np.array([p.upper for p in model.parameters])
    inside = np.where(v < lo, lo + (lo - v), v)          # mirrored into the box (compliance: c >= 0)
    return np.where(inside > hi, hi - (inside - hi), inside)


# --- terms ---------------------------------------------------------------------------------------------------


def test_every_registered_term_is_checked():
    """The checks run over the registry, so a new term is checked; what it needs beyond its defaults is named
    here by the name it is registered under."""
    names = term_names()
    assert {"geometric", "joint_compliance", "gp_compensator", "rbf_compensator", "sessions"} <= set(names)
    assert set(BUILD) <= set(names) and {n for _, n in SKIP} <= set(names)
    assert {c for c, _ in SKIP} <= {"sizes", "derivatives", "bounds", "json"}
    assert {t for t, _ in UNBOUNDED} <= set(names)


@pytest.mark.parametrize("name", terms_for("sizes"))
def test_term_output_sizes(name, campaign):
    model, own = model_of(name)
    data = data_of(name, model, campaign)
    n, P, C = model.robot.n, len(model.parameters), len(model.covariate_names)
    assert set(own) <= set(model.parameters.names)
    cov_all = model.covariates(data)
    assert cov_all.shape == (len(data), C) and np.all(np.isfinite(cov_all))
    for N in (1, 4):
        q, cov = data.q[:N], cov_all[:N]
        assert model.default_covariates(N).shape == (N, C)
        xyz = model.predict(q, None, cov)
        assert xyz.shape == (N, 3) and np.all(np.isfinite(xyz))
        xyz2, J = model.predict_jacobian(q, None, cov)
        assert J.shape == (N, 3, P) and np.array_equal(xyz, xyz2)
        cols = [model.parameters.names.index(p) for p in own]
        assert model.predict_jacobian(q, None, cov, columns=cols)[1].shape == (N, 3, len(cols))
        assert model.torques(q, None, cov).shape == (N, n)
        assert model.joint_offsets(q, None, cov).shape == (N, n)
        if model.orientation:
            assert model.probe_rotation(q, None, cov).shape == (N, 3, 3)


def outputs(model: Model, q, values, cov, R=None, jacobian=False):
    """The tool points (N, 3), and on a full-pose model the orientation residuals against ``R`` too (N, 6); with
    ``jacobian``, also their Jacobian w.r.t. the parameters (N, 3 or 6, P)."""
    if not model.orientation:
        return model.predict_jacobian(q, values, cov) if jacobian else model.predict(q, values, cov)
    if jacobian:
        xyz, J, ro, Jo = model.pose_jacobian(q, R, values, cov)
        return np.concatenate([xyz, ro], 1), np.concatenate([J, Jo], 1)
    return np.concatenate(model.pose_residuals(q, R, values, cov), 1)


@pytest.mark.parametrize("name", terms_for("derivatives"))
def test_term_derivatives_are_finite_differences(name, campaign):
    """The Jacobian of the tool point (and of the probe's orientation, on a full-pose model) w.r.t. each of the
    term's parameters against central differences, each step moving the point by about 1 um."""
    model, own = model_of(name)
    assert own, f"{name} has no parameters: name the reason in SKIP"
    data = data_of(name, model, campaign)
    rng = np.random.default_rng(7)
    q, cov = data.q[::8], model.covariates(data)[::8]
    R = data.rotations[::8] if model.orientation else None
    if name == "sessions":                          # poses of both sessions
        assert len(set(data.sessions[::8])) == 2
    values = away_from_nominal(model, rng)
    _, J = outputs(model, q, values, cov, R, jacobian=True)
    moved = False
    for name_k in own:
        k = model.parameters.names.index(name_k)
        size = np.abs(J[:, :, k]).max()
        h = 1e-6 / size if size > 0 else model.parameters[name_k].scale
        step = np.zeros_like(values)
        step[k] = h
        fd = (outputs(model, q, values + step, cov, R) - outputs(model, q, values - step, cov, R)) / (2 * h)
        moved |= size > 0
        err = np.abs(fd - J[:, :, k]).max()
        assert err <= 1e-6 * size + 1e-12, f"{name_k}: |finite difference - Jacobian| {err:.3g}, size {size:.3g}"
    assert moved, f"no parameter of {name} moves the tool point or the probe"


@pytest.mark.parametrize("name", terms_for("bounds"))
def test_term_parameters_are_bounded_and_start_inside(name):
    term = build(name)
    term.bind(robot_of(name))
    params = term.parameters(robot_of(name))
    assert params, f"{name} has no parameters: name the reason in SKIP"
    for p in params:
        why = next((r for (t, prefix), r in UNBOUNDED.items() if t == name and p.name.startswith(prefix)), None)
        if why is None:
            assert math.isfinite(p.lower) and math.isfinite(p.upper) and p.lower < p.upper, \
                f"{p.name}: bounds [{p.lower}, {p.upper}]; give finite ones or a reason in UNBOUNDED"
        assert p.lower <= p.value <= p.upper, f"{p.name} starts at {p.value} outside [{p.lower}, {p.upper}]"
        assert p.scale > 0 and math.isfinite(p.scale)
    model, _ = model_of(name)
    for p in model.parameters:
        assert p.lower <= p.value <= p.upper, p.name


@pytest.mark.parametrize("name", terms_for("json"))
def test_term_calibration_json_round_trip(name, campaign, tmp_path):
    """A calibration of a model holding the term (fitted compensators included) saved and loaded predicts the
    same positions, to 1e-12 m, at poses it was not fitted on."""
    term = build(name)
    spec = CALIBRATE.get(name, "kinematic" if name == "geometric" else f"kinematic+{term.spec()}")
    data = data_of(name, model_of(name)[0], campaign)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate(robot_of(name), data, spec, "lm", warn=False, solver_options={"max_iter": 15})
    assert res.model.term(name) is not None, f"{spec}: the calibrated model lacks {name}"
    res.save(tmp_path / "cal.json")
    back = load_calibration(tmp_path / "cal.json")
    assert back.model.spec == res.model.spec
    assert back.parameters.names == res.parameters.names
    np.testing.assert_allclose(back.parameters.values, res.parameters.values, rtol=1e-14, atol=1e-18)
    other = data.subset(np.arange(len(data)) % 3 == 0)
    assert np.abs(back.predict(other) - res.predict(other)).max() <= 1e-12
    assert np.abs(back.predict(data) - res.predict(data)).max() <= 1e-12


# --- methods -------------------------------------------------------------------------------------------------

#: settings that keep every method quick here (applied where the method has them)
CHEAP = {"generations": 15, "pop_size": 10, "max_rounds": 2, "n_starts": 2, "epochs": 20, "folds": 3}


def cheap(name: str) -> dict:
    cls = lookup(name)
    return {k: v for k, v in CHEAP.items() if hasattr(cls, k)}


@pytest.fixture(scope="module")
def sets():
    """20 calibration, 15 validation and 20 extra poses of a compliant YS100 in front of the tracker."""
    effects = Effects(stiffness={2: 1.73e6, 3: 1.2e6, 4: 3e5, 5: 5.7e5}, base_xyz=(2.5, -1.0, 0.2),
                      base_rpy=(0.0, 0.0, math.radians(150.0)))
    cal, truth = simulate(ROBOT, 20, effects, seed=7)
    val, _ = simulate(ROBOT, 15, truth=truth, seed=107)
    extra, _ = simulate(ROBOT, 20, truth=truth, seed=207)
    return cal, val, extra


@pytest.fixture(scope="module")
def runs(sets):
    """Each method's run with seed 1 (made on first use, once per module)."""
    cache = {}

    def get(name, seed=1):
        key = (name, seed)
        if key not in cache:
            cal, val, extra = sets
            cache[key] = run_method(name, ROBOT, cal, val, extra=extra, seed=seed, **cheap(name))
        return cache[key]
    return get


def test_every_registered_method_is_checked():
    assert {"Nominal", "KM", "SKCM", "GA-RBF", "NN-SKCM"} <= set(method_names())


@pytest.mark.parametrize("name", method_names())
def test_method_result_interface(name, sets, runs):
    cal, val, extra = sets
    r = runs(name)
    assert isinstance(r, MethodResult) and r.name == name
    assert (r.calibration.n_poses, r.validation.n_poses, r.extra.n_poses) == (20, 15, 20)
    assert r.time_s > 0
    pred = r.predict(val)
    assert pred.shape == (15, 3) and np.all(np.isfinite(pred))
    np.testing.assert_allclose(r.errors(val), np.linalg.norm(pred - val.xyz, axis=1))
    assert r.stats(val).mean_mm == pytest.approx(r.validation.mean_mm, rel=1e-12)
    assert r.stats(cal).mean_mm == pytest.approx(r.calibration.mean_mm, rel=1e-12)
    assert all(k > 0 for k in r.stiffness().values())
    d = r.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["name"] == name and d["n_poses"] == {"calibration": 20, "validation": 15, "extra": 20}


@pytest.mark.parametrize("name", method_names())
def test_method_is_deterministic_under_a_seed(name, sets, runs):
    cal, val, extra = sets
    a = runs(name)
    b = run_method(name, ROBOT, cal, val, extra=extra, seed=1, **cheap(name))
    np.testing.assert_array_equal(a.predict(val), b.predict(val))
    np.testing.assert_array_equal(a.result.parameters.values, b.result.parameters.values)
    assert a.stiffness() == b.stiffness()
    assert untimed(a.to_dict()) == untimed(b.to_dict())


def untimed(d):
    """A JSON entry without its wall times (``time_s``, ``optimizer_time_s``, ``time_split_s``, ...)."""
    if isinstance(d, dict):
        return {k: untimed(v) for k, v in d.items() if "time" not in k}
    return [untimed(v) for v in d] if isinstance(d, list) else d


@pytest.mark.parametrize("name", method_names())
def test_method_calibration_json_round_trip(name, sets, runs, tmp_path):
    cal, val, _ = sets
    r = runs(name)
    r.result.save(tmp_path / "cal.json")
    back = load_calibration(tmp_path / "cal.json")
    assert back.model.spec == r.result.model.spec
    assert np.abs(back.predict(val) - r.result.predict(val)).max() <= 1e-12
