"""Pose planning: observability indices, certified D-optimal design, GA/random selectors, CLI."""

from __future__ import annotations

import csv
import itertools
import json
import math
import re

import numpy as np
import pytest

from casadical import cli
from casadical.errors import IdentifiabilityError, InputError
from casadical.model import Model
from casadical.planning import (RelaxationSettings, d_optimal_design, design_problem, exchange,
                                indices_from_singular_values, log_det_information, o1_batch,
                                observability, random_o1, relax_cvxpy, relax_multiplicative,
                                select_poses, upper_bound)
from casadical.robot import PROBLEMS, load_robot
from casadical.simulate import load_protocol, sample_poses


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
