"""Pose planning: observability indices, certified D-optimal design, GA/random selectors, CLI."""

from __future__ import annotations

import csv
import itertools
import json
import math
import re

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from casadical import cli
from casadical.data import load_protocol, sample_poses
from casadical.errors import IdentifiabilityError, IdentifiabilityWarning, InputError
from casadical.loading import load_robot
from casadical.model import Model
from casadical.planning import (
    RelaxationSettings,
    d_optimal_design,
    design_problem,
    exchange,
    indices_from_singular_values,
    log_det_information,
    o1_batch,
    observability,
    pool_jacobian,
    random_o1,
    relax_cvxpy,
    relax_multiplicative,
    select_poses,
    upper_bound,
)
from casadical.planning._doptimal import _Pool, _swap_ratios
from casadical.planning._observability import _analyse_pool
from casadical.robot import PROBLEMS, robot_from_dict
from casadical.runtime import set_threads
from casadical.stats import analyse


def _random_pool(N: int, p: int, seed: int, r: int = 3) -> np.ndarray:
    """Synthetic Jacobian blocks with unequal column scales (as real ones have)."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=(N, r, p)) * np.logspace(-4, -1, p)


def _logdet(A, idx) -> float:
    return log_det_information(A, idx)


# --- observability indices ------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_indices_hand_computed(seed):
    # two poses whose stacked Jacobian has singular values 3, 2, 1, mixed by a random rotation
    # of the parameter space (which keeps the singular values)
    J = np.zeros((6, 3))
    J[0, 0], J[4, 1], J[5, 2] = 3.0, 2.0, 1.0
    V, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    A = (J @ V).reshape(2, 3, 3)
    o = observability(A)
    assert o.O1 == pytest.approx(6 ** (1 / 3) / math.sqrt(2), rel=1e-12)
    assert o.O2 == pytest.approx(1 / 3, rel=1e-12)
    assert o.O3 == pytest.approx(1.0, rel=1e-12)
    assert o.O4 == pytest.approx(1 / 3, rel=1e-12)
    assert o.O5 == pytest.approx(6 / 11, rel=1e-12)
    assert _logdet(A, [0, 1]) == pytest.approx(math.log(36.0), rel=1e-12)
    assert o1_batch(A, np.array([[0, 1]]))[0] == pytest.approx(o.O1, rel=1e-10)
    # a single pose sees only parameter 1 (singular values 3, 0, 0): nothing is identified
    assert observability(A, [0]).as_dict() == {f"O{k}": 0.0 for k in range(1, 6)}
    assert o1_batch(A, np.array([[0]]))[0] == 0.0


def test_indices_from_singular_values_checks():
    o = indices_from_singular_values([1.0, 4.0], n_poses=4)
    assert (o.O1, o.O2, o.O3, o.O4, o.O5) == pytest.approx((1.0, 0.25, 1.0, 0.25, 0.8))
    with pytest.raises(InputError):
        indices_from_singular_values([1.0, 2.0, 3.0], n_poses=1, n_parameters=2)


# --- relaxation and certificate -------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_relaxation_first_order_matches_cvxpy(seed):
    A = _random_pool(60, 7, seed)
    m = 10
    conic = relax_cvxpy(A, m)
    fo = relax_multiplicative(A, m, RelaxationSettings(tol=1e-5))
    p = A.shape[2]
    assert fo.status == "converged"
    assert abs(fo.log_det - conic.log_det) / p < 1e-3
    # each bound is valid for the other solver's optimum
    assert fo.upper_bound >= conic.log_det - 1e-7
    assert conic.upper_bound >= fo.log_det - 1e-7
    assert np.all((fo.weights >= 0) & (fo.weights <= 1 + 1e-12))
    assert fo.weights.sum() == pytest.approx(m, rel=1e-9)


@pytest.fixture(scope="module")
def ys100_pool():
    """The GA paper's 70-pose pool (ga-ys100-pool protocol) and its design problem."""
    proto = load_protocol("ga-ys100-pool")
    sets, _ = proto.generate()
    model = Model(proto.robot, "kinematic+compliance")
    return model, sets["pool"].q, design_problem(model, sets["pool"].q)


def test_relaxation_ys100_first_order_matches_cvxpy(ys100_pool):
    _, _, prob = ys100_pool
    p = prob.n_parameters
    assert p >= 25
    conic = relax_cvxpy(prob.A, 2 * p if 2 * p <= prob.n_candidates else 40)
    fo = relax_multiplicative(prob.A, 2 * p if 2 * p <= prob.n_candidates else 40)
    assert abs(fo.log_det - conic.log_det) / p < 1e-3
    assert fo.upper_bound >= conic.log_det - 1e-6


@pytest.mark.parametrize("seed", [3, 4])
def test_bound_holds_against_enumeration(seed):
    # small enough to try every subset: the bound must cover the best one, and
    # rounding + exchange should find it (or come within its certificate)
    A = _random_pool(12, 4, seed, r=2)
    m = 4
    best = max(_logdet(A, s) for s in itertools.combinations(range(12), m))
    des = d_optimal_design(A, m, settings=RelaxationSettings(tol=1e-6))
    assert des.upper_bound >= best - 1e-9
    assert des.log_det <= best + 1e-9
    assert des.log_det >= best - 1e-6 * abs(best) - 0.05  # exchange reaches (nearly) the optimum
    assert des.d_efficiency == pytest.approx(math.exp((des.log_det - des.upper_bound) / 4))


@pytest.mark.parametrize("seed,m_factor", [(0, 2), (1, 2), (2, 3)])
def test_exact_design_certified_efficiency(seed, m_factor):
    robot = load_robot("ys100")
    model = Model(robot, "kinematic+compliance")
    q = sample_poses(robot, 400, np.random.default_rng(seed))
    prob = design_problem(model, q)
    p = prob.n_parameters
    m = m_factor * p
    des = d_optimal_design(prob.A, m)
    assert len(des.indices) == m == len(np.unique(des.indices))
    assert des.d_efficiency >= 0.95
    assert des.log_det == pytest.approx(_logdet(prob.A, des.indices), abs=1e-8)
    # the certificate is consistent: the relaxation is above the exact design, the bound above both
    assert des.relaxation.log_det >= des.log_det - 1e-9
    assert des.upper_bound >= des.relaxation.log_det - 1e-9


def test_bad_sizes():
    A = _random_pool(20, 6, 0)
    with pytest.raises(InputError):
        relax_multiplicative(A, 21)
    with pytest.raises(IdentifiabilityError):
        relax_multiplicative(A, 1)  # 3 equations for 6 parameters
    with pytest.raises(InputError):
        exchange(A, 3, [0, 0, 1])
    with pytest.raises(IdentifiabilityError):
        upper_bound(np.zeros((5, 3, 2)), 2, np.ones(5) * 0.4)


# --- selectors ------------------------------------------------------------------------


def test_doptimal_beats_random_and_ga(ys100_pool):
    model, _, prob = ys100_pool
    d = select_poses(model, None, 20, "d-optimal", problem=prob)
    rand = random_o1(prob.A, 20, 200, seed=7)
    assert d.O1 > rand.max()
    for seed in (0, 1):
        g = select_poses(model, None, 20, "ga", seed=seed, problem=prob)
        assert g.O1 > rand.mean()
        assert d.O1 >= g.O1 * (1 - 1e-9)
        # both are certified against the same bound; D-efficiency orders like O1
        assert g.upper_bound == pytest.approx(d.upper_bound, abs=1e-3 * prob.n_parameters)
        assert g.d_efficiency <= d.d_efficiency + 1e-3
    r = select_poses(model, None, 20, "random", seed=3, problem=prob)
    assert r.O1 < d.O1 and len(set(r.indices)) == 20


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_planted_poses_are_chosen(seed):
    # parameters 4 and 5 are each seen by one pose only (elsewhere 1e-4 of it): without those
    # two poses the design loses ~log(1e8) of log det, so it must take both; a random
    # 8-set of 150 holds both with probability 0.25 %
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(150, 3, 6))
    A[:, :, 4:] *= 1e-4
    planted = rng.choice(150, 2, replace=False)
    A[planted[0], :, 4] = rng.normal(size=3)
    A[planted[1], :, 5] = rng.normal(size=3)
    des = d_optimal_design(A, 8)
    assert set(planted) <= set(des.indices)
    assert des.d_efficiency > 0.9
    # removing a planted pose (best replacement) costs far more than the certificate allows
    for k in planted:
        rest = [i for i in range(150) if i not in des.indices]
        worse = max(_logdet(A, [i for i in des.indices if i != k] + [j]) for j in rest)
        assert worse < des.log_det - 5.0


@pytest.mark.parametrize("seed", [5, 6])
def test_planted_loaded_poses_are_chosen(tmp_path, seed):
    # compliance only shows under load: a robot with nearly massless links, and a pool in which
    # only 10 of 150 candidate poses carry the 110 kg payload
    text = (PROBLEMS / "robots" / "ys100.toml").read_text()
    text = re.sub(r"mass_kg = [0-9.]+\ncom_m", "mass_kg = 0.01\ncom_m", text)
    path = tmp_path / "light.toml"
    path.write_text(text)
    robot = load_robot(str(path))
    model = Model(robot, "kinematic+compliance")
    rng = np.random.default_rng(seed)
    q = sample_poses(robot, 150, rng)
    payload = np.zeros(150)
    loaded = rng.choice(150, 10, replace=False)
    payload[loaded] = 110.0
    cov = np.column_stack([payload])
    assert model.covariate_names == ["payload_kg"]
    prob = design_problem(model, q, cov)
    assert {"c2", "c3", "c5"} <= set(prob.names)
    m = 2 * prob.n_parameters
    res = select_poses(model, None, m, "d-optimal", problem=prob)
    chosen = len(set(loaded) & set(res.indices))
    assert chosen >= 9  # random sets take 10 m / 150 ~ 3.7 on average
    assert res.d_efficiency >= 0.95
    # without compliance in the model the loaded poses are nothing special
    kin = Model(robot, "kinematic")
    res_kin = select_poses(kin, q, m, "d-optimal", cov=cov)
    assert len(set(loaded) & set(res_kin.indices)) <= 7


def test_select_poses_rejects_bad_input(ys100_pool):
    model, q, prob = ys100_pool
    with pytest.raises(InputError):
        select_poses(model, q, 20, "best")
    with pytest.raises(InputError):
        select_poses(model, None, 71, problem=prob)
    with pytest.raises(IdentifiabilityError):
        select_poses(model, None, 5, problem=prob)


# --- command line ---------------------------------------------------------------------


def _run(argv, capsys):
    rc = cli.main(argv)
    out = capsys.readouterr()
    return rc, out.out, out.err


@pytest.fixture
def candidates(tmp_path, capsys):
    path = tmp_path / "cands.csv"
    rc, out, _ = _run(["candidates", "ys100", "-n", "80", "--out", str(path), "--seed", "3",
                       "--box", "0.6,-1.2,0.0,2.4,1.2,2.2"], capsys)
    assert rc == 0
    # add columns a user may have: a label and a payload
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    rows[0] += ["label", "payload_kg"]
    for k, r in enumerate(rows[1:]):
        r += [f"pose-{k:03d}", "110.0"]
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return path, rows


def test_cli_candidates_respect_box(candidates):
    path, rows = candidates
    assert len(rows) == 81 and rows[0][:6] == [f"q{i}_deg" for i in range(1, 7)]
    robot = load_robot("ys100")
    q = np.radians(np.array([[float(x) for x in r[:6]] for r in rows[1:]]))
    xyz = Model(robot, "nominal").predict(q)
    assert np.all(xyz >= [0.6, -1.2, 0.0]) and np.all(xyz <= [2.4, 1.2, 2.2])
    assert np.all(q >= robot.limits[:, 0]) and np.all(q <= robot.limits[:, 1])


def test_cli_plan_poses_writes_selected_rows(candidates, tmp_path, capsys):
    path, rows = candidates
    out = tmp_path / "sel.csv"
    rc, text, err = _run(["plan-poses", "ys100", str(path), "-m", "24", "--out", str(out)], capsys)
    assert rc == 0, err
    assert "O1 =" in text and "O5 =" in text and "D-efficiency" in text and "time:" in text
    with open(out, newline="") as fh:
        sel = list(csv.reader(fh))
    assert sel[0] == rows[0] and len(sel) == 25
    labels = [r[6] for r in sel[1:]]
    assert labels == sorted(labels)  # candidate order
    body = {tuple(r) for r in rows[1:]}
    assert all(tuple(r) in body for r in sel[1:])  # rows copied verbatim
    # refuse to overwrite, then replace with --force (GA this time)
    rc, _, err = _run(["plan-poses", "ys100", str(path), "-m", "24", "--out", str(out)], capsys)
    assert rc == 2 and "exists already" in err and err.count("\n") == 1 and str(out) in err
    summary = tmp_path / "sel.json"
    rc, text, err = _run(["plan-poses", "ys100", str(path), "-m", "24", "--out", str(out),
                          "--method", "random", "--seed", "1", "--force", "--json", str(summary)], capsys)
    assert rc == 0, err
    doc = json.loads(summary.read_text())
    with open(out, newline="") as fh:
        sel = list(csv.reader(fh))
    assert [rows[k - 1] for k in doc["file_lines"]] == sel[1:]
    assert doc["method"] == "random" and 0 < doc["d_efficiency"] < 1 and set(doc["observability"]) == {
        "O1", "O2", "O3", "O4", "O5"}


@pytest.mark.parametrize("m,expect", [("81", "more poses than the 80 candidate rows"),
                                      ("5", "use -m 11 or more"), ("0", "at least 1")])
def test_cli_plan_poses_bad_m(candidates, tmp_path, capsys, m, expect):
    path, _ = candidates
    out = tmp_path / "sel.csv"
    rc, _, err = _run(["plan-poses", "ys100", str(path), "-m", m, "--out", str(out)], capsys)
    assert rc == 2
    assert err.count("\n") == 1 and expect in err, err
    assert str(path) in err or "argument -m" in err
    assert not out.exists()


def test_cli_candidates_bad_box(tmp_path, capsys):
    rc, _, err = _run(["candidates", "ys100", "-n", "5", "--out", str(tmp_path / "c.csv"),
                       "--box", "1,2,3"], capsys)
    assert rc == 2 and "--box" in err and err.count("\n") == 1


# --- fast paths, thread limit, duplicated and degenerate pools ------------------------


def _arm(n: int, convention: str, beta_joint: int | None, seed: int):
    """A random n-joint arm that is not built in (Hayati beta on ``beta_joint``, if any)."""
    rng = np.random.default_rng(seed)
    joints = []
    for j in range(1, n + 1):
        jt = {"alpha_deg": float(rng.choice([-90, 0, 90])) if j > 1 else 90.0,
              "a_m": float(rng.uniform(0.05, 0.6)), "d_m": float(rng.uniform(0.0, 0.4)),
              "min_deg": -160.0, "max_deg": 160.0, "mass_kg": float(rng.uniform(2, 30)),
              "com_m": [float(x) for x in rng.uniform(-0.2, 0.2, 3)]}
        if j == beta_joint:
            jt.update(alpha_deg=0.0, beta_deg=0.0)
        joints.append(jt)
    return robot_from_dict({"name": f"arm{n}", "convention": convention, "joint": joints,
                            "tool": {"a_m": 0.05, "b_m": 0.02, "d_m": 0.1}, "payload": {"mass_kg": 10.0}})


ARMS = [(4, "mdh", 2), (5, "dh", None), (7, "dh", 3)]


@pytest.mark.parametrize("n,convention,beta", ARMS)
@pytest.mark.parametrize("seed", [0, 1])
def test_chunked_pool_jacobian_and_compressed_analysis(n, convention, beta, seed):
    robot = _arm(n, convention, beta, seed)
    model = Model(robot, "kinematic+compliance", jit=False)
    q = sample_poses(robot, 300, np.random.default_rng(seed), floor_z=None)
    J = model.predict_jacobian(q)[1]
    np.testing.assert_allclose(pool_jacobian(model, q, chunk=64), J, rtol=1e-13, atol=1e-15)  # last chunk padded
    full, small = analyse(J, model.parameters), _analyse_pool(J, model.parameters)
    assert small.identifiable == full.identifiable and len(full.identifiable) >= 3 * n
    assert [(u.name, u.reason) for u in small.unidentifiable] == [(u.name, u.reason) for u in full.unidentifiable]
    assert small.n_equations == full.n_equations == 900
    np.testing.assert_allclose(small.singular_values, full.singular_values, rtol=1e-9)


@pytest.mark.parametrize("r", [2, 3, 4])
@pytest.mark.parametrize("seed", [0, 1])
def test_swap_ratios_are_determinant_ratios(r, seed):
    A = _random_pool(40, 9, seed, r=r)
    pool = _Pool(A, 6)
    rng = np.random.default_rng(seed)
    X = rng.choice(40, 6, replace=False)
    cand = np.setdiff1d(np.arange(40), X)
    L = np.linalg.cholesky(pool.info(X, np.ones(6)))
    ratio = _swap_ratios(pool, np.linalg.inv(L), cand, X, np.eye(r))
    base = _logdet(A, X)
    brute = np.array([[math.exp(_logdet(A, np.where(X == o, c, X)) - base) for o in X] for c in cand])
    np.testing.assert_allclose(ratio, brute, rtol=1e-8)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exchange_ends_where_no_swap_improves(seed):
    A = _random_pool(120, 10, seed)
    m = 8
    start = np.random.default_rng(seed).choice(120, m, replace=False)
    ex = exchange(A, m, start, n_candidates=120 - m)  # every unselected pose is a candidate
    assert ex.swaps > 0 and ex.log_det > _logdet(A, start)
    best_swap = max(_logdet(A, np.where(ex.indices == o, c, ex.indices))
                    for o in ex.indices for c in np.setdiff1d(np.arange(120), ex.indices))
    assert best_swap <= ex.log_det + 1e-9


@pytest.mark.parametrize("seed", [0, 1])
def test_relaxation_chunked_sweeps_same_certificate(seed):
    A = _random_pool(1500, 12, seed)
    a = relax_multiplicative(A, 30, RelaxationSettings(tol=1e-5))
    b = relax_multiplicative(A, 30, RelaxationSettings(tol=1e-5, chunk=32))  # pool and active set in chunks
    assert a.status == b.status == "converged"
    assert abs(a.log_det - b.log_det) / 12 < 1e-5
    assert a.upper_bound >= b.log_det - 1e-9 and b.upper_bound >= a.log_det - 1e-9


def test_same_design_with_and_without_the_thread_limit(ys100_pool):
    _, _, prob = ys100_pool
    limited = d_optimal_design(prob.A, 40)
    set_threads(0)
    try:
        with threadpool_limits(limits=2):
            free = d_optimal_design(prob.A, 40)
    finally:
        set_threads(None)
    np.testing.assert_array_equal(limited.indices, free.indices)
    assert limited.log_det == pytest.approx(free.log_det, abs=1e-9)
    assert limited.d_efficiency == pytest.approx(free.d_efficiency, abs=1e-9)


@pytest.mark.parametrize("n,convention,beta", ARMS)
def test_one_repeated_pose_gets_no_certificate(n, convention, beta):
    robot = _arm(n, convention, beta, 2)
    model = Model(robot, "kinematic+compliance", jit=False)
    pool = np.repeat(sample_poses(robot, 1, np.random.default_rng(2), floor_z=None), 50, axis=0)
    with pytest.raises(InputError, match="only 1 distinct pose"):
        select_poses(model, pool, 10)
    # the one pose identifies 3 parameters and is trivially the best 1-set for them: no certificate
    with pytest.warns(IdentifiabilityWarning, match="identify only 3 parameters"):
        res = select_poses(model, pool, 1)
    assert res.upper_bound is None and res.d_efficiency is None and res.duplicates == 49
    assert len(res.missing_parameters) >= 3 * n - 3
    assert "no certificate" in res.summary() and "D-efficiency" not in res.summary()


@pytest.mark.parametrize("n,convention,beta", ARMS)
def test_pool_where_a_joint_never_moves_is_not_certified(n, convention, beta):
    robot = _arm(n, convention, beta, 3)
    model = Model(robot, "kinematic+compliance", jit=False)
    q = sample_poses(robot, 150, np.random.default_rng(3), floor_z=None)
    good = select_poses(model, q, 15)
    assert not good.missing_parameters and good.d_efficiency > 0.5  # M near p / 3: a loose bound
    q[:, -1] = 0.3  # the hidden defect: the last joint stands still in every candidate
    with pytest.warns(IdentifiabilityWarning):
        bad = select_poses(model, q, 15)
    assert bad.upper_bound is None and bad.d_efficiency is None
    assert bad.missing_parameters and not set(bad.missing_parameters) & set(bad.parameters)
    assert len(bad.parameters) + len(bad.missing_parameters) == len(good.parameters)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_duplicated_rows_are_offered_once(seed):
    robot = _arm(6, "mdh", 2, seed)
    model = Model(robot, "kinematic+compliance", jit=False)
    rng = np.random.default_rng(seed)
    q = sample_poses(robot, 100, rng, floor_z=None)
    pool = np.concatenate([q, q[rng.choice(100, 60, replace=False)]])[rng.permutation(160)]
    m = 30
    res = select_poses(model, pool, m)
    assert res.duplicates == 60
    assert len(np.unique(pool[res.indices], axis=0)) == m  # M distinct poses, not copies
    ref = select_poses(model, q, m)
    p = len(ref.parameters)
    assert res.parameters == ref.parameters
    assert res.upper_bound == pytest.approx(ref.upper_bound, abs=2e-4 * p)  # the same relaxation, within its gap
    assert res.d_efficiency > 0.9


def test_cli_identical_candidates_one_line(tmp_path, capsys):
    path = tmp_path / "same.csv"
    path.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n" + "10,40,20,5,30,0\n" * 40)
    out = tmp_path / "sel.csv"
    rc, _, err = _run(["plan-poses", "ys100", str(path), "-m", "12", "--out", str(out)], capsys)
    assert rc == 2 and err.count("\n") == 1 and str(path) in err and "only 1 distinct pose" in err
    assert not out.exists()
