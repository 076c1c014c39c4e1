"""Identification: recovery within reported uncertainty, real data, bounds, bad input."""

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from casadical import Measurements, calibrate, load_calibration, load_robot
from casadical.data import Effects, simulate
from casadical.errors import ConvergenceWarning, CorrelationWarning, IdentifiabilityError, IdentifiabilityWarning

UR10_B = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"
STIFF = {2: 1.7e6, 3: 1.2e6, 4: 0.3e6, 5: 0.57e6}


def _truth_without_unidentifiable(robot, effects, seed, n):
    """Simulate; parameters that no pose set can identify get no error in the truth."""
    data, truth = simulate(robot, n, effects, seed=seed)
    probe = calibrate(robot, data, "kinematic+compliance[2,3,4,5]", "lm", warn=False)
    structural = [p.name for p in probe.parameters if p.identifiable is False]
    for name in structural:
        i = truth.model.parameters.index(name)
        truth.values[i] = truth.model.parameters.nominal[i]
    data, _ = simulate(robot, data.q, truth=truth, seed=seed + 1000)
    return data, truth


def test_parameters_recovered_within_reported_uncertainty():
    """Normalised errors follow chi-square(p) and residual RMS matches the noise, over 20 seeds."""
    robot = load_robot("ys100")
    noise = 50e-6
    eff = Effects(stiffness=STIFF, noise=noise, base_xyz=(3.0, 1.0, -0.4), base_rpy=(0.02, -0.03, 2.0))
    d2s, rms_ratio, dims = [], [], []
    for seed in range(20):
        data, truth = _truth_without_unidentifiable(robot, eff, seed, 60)
        res = calibrate(robot, data, "kinematic+compliance[2,3,4,5]", "lm", warn=False)
        names = [n for n in res.uncertainty.names if not n.startswith("base_")]
        idx = [res.uncertainty.names.index(n) for n in names]
        err = np.array([res.parameters[n].value - truth.value(n) for n in names])
        cov = res.uncertainty.covariance[np.ix_(idx, idx)]
        d2s.append(err @ np.linalg.solve(cov, err))
        dims.append(len(names))
        m3 = 3 * len(data)
        p = len(res.uncertainty.names)
        r = res.residuals(data)
        rms = math.sqrt(float(np.sum(r * r)) / m3)
        rms_ratio.append(rms / (noise * math.sqrt((m3 - p) / m3)))
    ratio = np.mean(np.array(d2s) / np.array(dims))
    # mean of chi2(p)/p over 20 draws with p ~ 30: 1 +- 0.06
    assert 0.75 < ratio < 1.3, ratio
    assert abs(np.mean(rms_ratio) - 1) < 0.05, np.mean(rms_ratio)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_stiffness_found_and_kinematic_model_misses_it(seed):
    robot = load_robot("ys100")
    eff = Effects(stiffness=STIFF, noise=20e-6)
    cal, truth = simulate(robot, 40, eff, seed=seed)
    val, _ = simulate(robot, 60, truth=truth, seed=seed + 100)
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False)
    kc = calibrate(robot, cal, "kinematic+compliance", "ipopt", warn=False)
    for j, k in STIFF.items():
        kj, sk = kc.stiffness()[j]
        assert abs(kj - k) < 5 * sk + 0.02 * k, (j, kj, k, sk)
    assert kc.stats(val).mean_mm < 0.1 < kin.stats(val).mean_mm


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tilt_of_joint_1_against_gravity_identified_on_a_heavy_compliant_arm(seed):
    """At nominal values (no compliance) tilting joint 1 is tilting the base; a fitted compliance tells them apart
    (the tilt changes the gravity torques). On the heavy HH800 with compliant drives 2 and 3 these poses determine
    it: identified near the truth, and the held-out error reaches the truth's own. (Drive 2 alone carries
    tau2 - tau3 of the parallelogram: in one seed of three its torques leave the tilt with the base.)"""
    robot = load_robot("hh800")
    cal, truth = simulate(robot, 150, Effects(stiffness={2: 2e6, 3: 2e6}), seed=seed)
    val, _ = simulate(robot, 300, truth=truth, seed=seed + 10)
    res = calibrate(robot, cal, "kinematic+joint_compliance[2,3]", "lm", warn=False)
    for name in ("alpha1", "beta1"):
        p = res.parameters[name]
        assert not p.fixed and p.identifiable and abs(p.value - truth.value(name)) < 4 * p.std, (name, p)
    floor = np.linalg.norm(truth.predict(val) - val.xyz, axis=1).mean() * 1000
    assert res.stats(val).mean_mm < 1.1 * floor
    assert any("tell them apart" in n for n in res.notes)
    # their correlation with the base is said in that note, not warned about as a problem
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrate(robot, cal, "kinematic+joint_compliance[2,3]", "lm")
    assert not [w for w in caught if "alpha1" in str(w.message) or "beta1" in str(w.message)]
    # the same structure fitted without freeing it stops short
    fixed = calibrate(robot, cal, "kinematic+joint_compliance[2,3]", "lm", warn=False, fix=("alpha1", "beta1"))
    assert fixed.stats(val).mean_mm > res.stats(val).mean_mm


def test_light_compliance_leaves_the_tilt_of_joint_1_to_the_base():
    """On the YS100 the same tilt would be determined to about 0.4 of its typical size only: it stays fixed."""
    robot = load_robot("ys100")
    cal, _ = simulate(robot, 150, Effects(stiffness={2: 1.7e6, 3: 1.2e6}), seed=0)
    res = calibrate(robot, cal, "kinematic+joint_compliance[2,3]", "lm", warn=False)
    assert res.parameters["alpha1"].fixed and res.parameters["beta1"].fixed
    assert not any("tell them apart" in n for n in res.notes)


def test_lm_and_ipopt_agree_without_active_bounds():
    robot = load_robot("ys100")
    data, _ = simulate(robot, 40, Effects(stiffness=STIFF), seed=8)
    a = calibrate(robot, data, "kinematic+compliance[2,3,4,5]", "lm", warn=False)
    b = calibrate(robot, data, "kinematic+compliance[2,3,4,5]", "ipopt", warn=False)
    assert a.solver.success and b.solver.success
    dv = (a.parameters.values - b.parameters.values) / a.parameters.scales
    assert np.abs(dv).max() < 1e-3
    assert b.solver.iterations > 0 and b.solver.solve_time_s > 0


def test_ipopt_keeps_stiffness_inside_bounds():
    robot = load_robot("ys100")
    data, _ = simulate(robot, 40, Effects(stiffness={2: 1e6}), seed=4)
    from casadical.model import Model
    from casadical.terms import make_term
    model = Model(robot, [make_term("kinematic"), make_term("joint_compliance", joints=[2], k_min=2e6)])
    # the note quotes the bound, not the value
    bound = r"c2 = \S+ rad/\(N\*m\) is at or beyond its upper bound 5e-07 rad/\(N\*m\)"
    with pytest.warns(CorrelationWarning, match=bound):
        res = calibrate(robot, data, model, "ipopt")
    c2 = res.parameters["c2"]
    assert c2.value <= 1 / 2e6 * (1 + 1e-6)
    lm = calibrate(robot, data, model, "lm", warn=False)
    assert lm.parameters["c2"].value > 1 / 2e6  # unbounded LM crosses it: the reason for IPOPT
    auto = calibrate(robot, data, model, "auto", warn=False)
    assert auto.solver_name == "levenberg-marquardt+ipopt"
    assert auto.parameters["c2"].value <= 1 / 2e6 * (1 + 1e-6)


def test_payload_column_is_used():
    robot = load_robot("ys100")
    rng = np.random.default_rng(0)
    payload = rng.uniform(0, 150, 50)
    data, truth = simulate(robot, 50, Effects(stiffness=STIFF), seed=5, payload_kg=payload)
    res = calibrate(robot, data, "kinematic+compliance", "lm", warn=False)
    assert res.calibration.rms_mm < 0.05
    # ignoring the rows' payload (robot default 110 kg for every row) fits much worse
    no_payload = Measurements({k: v for k, v in data.columns.items() if k != "payload_kg"})
    assert calibrate(robot, no_payload, "kinematic+compliance", "lm", warn=False).calibration.rms_mm > 0.1


def test_json_round_trip_and_predict(tmp_path):
    robot = load_robot("ys100")
    data, truth = simulate(robot, 30, Effects(stiffness=STIFF), seed=6)
    res = calibrate(robot, data, "kinematic+compliance", "lm", warn=False)
    path = tmp_path / "cal.json"
    res.save(path)
    back = load_calibration(path)
    np.testing.assert_allclose(back.predict(data), res.predict(data), atol=1e-12)
    assert back.model.spec == res.model.spec
    import json
    doc = json.loads(path.read_text())
    assert {"robot", "model", "parameters", "calibration", "solver"} <= set(doc)
    assert {"name", "value", "std", "identifiable", "unit"} <= set(doc["parameters"][0])
    assert {"n_poses", "mean_mm", "max_mm", "rms_mm"} <= set(doc["calibration"])
    assert {"name", "status", "iterations", "solve_time_s"} <= set(doc["solver"])


def test_real_ur10_series_b_held_out():
    """Kinematic calibration on 300 real poses leaves about 0.4 mm on the held-out ones."""
    robot = load_robot("ur10")
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    rng = np.random.default_rng(0)
    idx = rng.permutation(len(data))
    cal, val = data.subset(np.sort(idx[:300])), data.subset(np.sort(idx[300:]))
    nominal = calibrate(robot, cal, "nominal", "lm", warn=False).stats(val)
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False)
    held = kin.stats(val)
    assert 0.25 < held.mean_mm < 0.6, held
    assert held.mean_mm < 0.6 * nominal.mean_mm


#: IPOPT's tolerances before issue 21: on the summed objective (mm^2) whatever the number of poses, and
#: IPOPT's own tiny_step_tol (10 machine epsilons)
SUM_TOLERANCES = {"tol": 1e-8, "acceptable_tol": 1e-6, "compl_inf_tol": 1e-4, "acceptable_compl_inf_tol": 1e-2,
                  "barrier_tol_factor": 10, "tiny_step_tol": 10 * 2.0 ** -52}


def _record_ipopt(monkeypatch) -> list:
    """(status, iterations, objective evaluations) of every IPOPT solve from now on, the noise-scale loop's too."""
    from casadical.solvers import Ipopt

    solves = []
    solve = Ipopt.solve

    def recorded(self, problem, x0=None):
        res = solve(self, problem, x0)
        solves.append((res.status, res.iterations, int(self._last.stats()["n_call_nlp_f"])))
        return res

    monkeypatch.setattr(Ipopt, "solve", recorded)
    return solves


def test_ipopt_stops_where_rounding_stalls_it(monkeypatch):
    """On the README's split (300 real poses), with a tolerance on the summed objective (as before issue 21),
    the robust loss's second IPOPT solve reaches the optimum in a few iterations; then the objective's rounding
    hides every decrease, and with IPOPT's own acceptable_iter (15) it backtracks ~30 times per iteration for
    10 more. casadical ends such a stall at the acceptable level: the same optimum as LM, in far fewer
    iterations."""
    solves = _record_ipopt(monkeypatch)
    robot = load_robot("ur10")
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    cal = data.subset(np.sort(np.random.default_rng(0).permutation(len(data))[:300]))
    # on the positions (the full pose, which this data also allows, does not stall here)
    lm = calibrate(robot, cal, "kinematic", "lm", warn=False, position_only=True)
    runs = {}
    for name, options in (("ours", SUM_TOLERANCES), ("ipopt's", {**SUM_TOLERANCES, "acceptable_iter": 15})):
        solves.clear()
        result = calibrate(robot, cal, "kinematic", "ipopt", warn=False, solver_options={"options": options},
                           position_only=True)
        runs[name] = (result, list(solves))
    ours, ours_solves = runs["ours"]
    stalled, stalled_solves = runs["ipopt's"]
    for other in (ours, stalled):
        dv = np.abs(other.parameters.values - lm.parameters.values) / lm.parameters.scales
        assert dv.max() < 1e-5    # 10 nm of a 1 mm scale (CasADi 3.8: 1.1e-6)
        assert other.solver.cost <= lm.solver.cost * (1 + 1e-8)   # no worse than LM's optimum
    # the premise: this data stalls IPOPT. Whether the objective's rounding hides the decrease depends on the
    # machine's arithmetic (BLAS kernels): on a 2-core Xeon of 2026-11 (OpenBLAS Haswell kernels) the second
    # solve ends in 7 iterations with IPOPT's own rule, and there is no stall to end. The two runs differ in
    # acceptable_iter alone: the same iterates, the same solves, until casadical's rule ends one
    k = next((i for i, (a, b) in enumerate(zip(ours_solves, stalled_solves)) if a != b), None)
    if k is None:
        pytest.skip("IPOPT does not stall on this machine's arithmetic: casadical's rule ends no solve earlier "
                    f"(iterations of the solves: {[it for _, it, _ in stalled_solves]})")
    # the solve that stalls ends at the acceptable level, earlier (IPOPT 3.14 with CasADi 3.6: 16 against 32
    # iterations in all; with CasADi 3.8: 16 against 22)
    assert ours_solves[k][0] == "Solved_To_Acceptable_Level" and ours.solver.success
    assert ours_solves[k][1] < stalled_solves[k][1]


@pytest.mark.parametrize("position_only", [True, False], ids=["positions", "full-pose"])
def test_ipopt_line_search_trials_evaluate_the_loss_alone(monkeypatch, position_only):
    """Where IPOPT backtracks (the README's split with IPOPT's tolerances on the summed objective: most of its
    objective evaluations are trials its line search rejects), a trial after a rejected one is evaluated for
    its loss alone (``CalibrationProblem.cost``, no Jacobian): at most one linearisation per gradient IPOPT asks
    for and one per iteration (a first trial it rejects), and the iterates are to the bit those of a
    linearisation at every point, the loss taken from it. (The robust loop's second solve: 361 objective
    evaluations in 15 iterations; 27 linearisations and 301 losses alone, where a linearisation at every
    point made 317 against the bound of 32; full pose 328 evaluations, 27 linearisations against 284.) That
    IPOPT backtracks is the machine's arithmetic (issue 47): where it does not, the rest is asserted and the test
    skipped with its figures."""
    from casadical.problem import CalibrationProblem
    from casadical.solvers import Ipopt

    robot = load_robot("ur10")
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    cal = data.subset(np.sort(np.random.default_rng(0).permutation(len(data))[:300]))
    options = {"options": {**SUM_TOLERANCES, "acceptable_iter": 15}}
    counts = {"linearize": 0, "cost": 0}
    for name in counts:
        def counted(self, values, _call=getattr(CalibrationProblem, name), _name=name):
            counts[_name] += 1
            return _call(self, values)
        monkeypatch.setattr(CalibrationProblem, name, counted)
    solves = []
    solve = Ipopt.solve

    def recorded(self, problem, x0=None):
        before = dict(counts)
        res = solve(self, problem, x0)
        stats = self._last.stats()
        solves.append({"iterations": res.iterations, "f": stats["n_call_nlp_f"], "grad": stats["n_call_nlp_grad_f"],
                       **{k: counts[k] - before[k] for k in counts}})
        return res

    monkeypatch.setattr(Ipopt, "solve", recorded)
    ours = calibrate(robot, cal, "kinematic", "ipopt", warn=False, solver_options=options, position_only=position_only)
    # the premise: IPOPT backtracks here. Whether the objective's rounding rejects trials is the machine's arithmetic
    # (numpy's OpenBLAS with its Sandybridge kernels: not on the positions); what follows holds either way
    backtracks = any(s["f"] >= 2 * s["iterations"] + 10 for s in solves)
    for s in solves:
        assert s["linearize"] <= s["grad"] + s["iterations"], s
    # the reference: the loss from a linearisation at every point IPOPT evaluates
    with monkeypatch.context() as m:
        m.setattr(CalibrationProblem, "cost", lambda self, values: self.linearize(values).cost)
        ours_solves, solves[:] = list(solves), []
        reference = calibrate(robot, cal, "kinematic", "ipopt", warn=False, solver_options=options,
                              position_only=position_only)
    assert [(s["iterations"], s["f"]) for s in solves] == [(s["iterations"], s["f"]) for s in ours_solves]
    assert np.array_equal(ours.parameters.values, reference.parameters.values)
    assert ours.solver.cost == reference.solver.cost
    if not backtracks:
        pytest.skip("IPOPT does not backtrack on this machine's arithmetic: no trial after a rejected one to evaluate "
                    f"(objective evaluations against iterations: {[(s['f'], s['iterations']) for s in solves]})")


def test_ipopt_tolerances_are_per_pose(monkeypatch):
    """Each of the README's 300 poses measured 20 times over: the same loss per pose, twenty times the sum.
    IPOPT's tests are per pose (issue 21): every tolerance it is given on the summed objective is N times its
    per-pose value, so the 6,000 poses are the 300's problem scaled by 20 and IPOPT ends both at the same
    optimum, converged. (Not asserted: iteration and evaluation counts, which are the CPU's arithmetic near the
    optimum, where the objective's rounding decides a line search; issue 47.)"""
    from casadical.solvers import Ipopt

    given = []
    options = Ipopt._options
    monkeypatch.setattr(Ipopt, "_options", lambda self, N: given.append((N, options(self, N))) or given[-1][1])
    robot = load_robot("ur10")
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    idx = np.sort(np.random.default_rng(0).permutation(len(data))[:300])
    runs = {k: calibrate(robot, data.subset(np.repeat(idx, k)), "kinematic", "ipopt", warn=False,
                         position_only=True) for k in (1, 20)}
    one, many = runs[1], runs[20]
    assert one.solver.success and many.solver.success
    # the tests on the gradient of the summed objective scale with the poses; complementarity stays on the sum
    by_n = {N: o["ipopt"] for N, o in given}
    assert set(by_n) == {300, 6000}
    for key in ("tol", "acceptable_tol", "barrier_tol_factor"):
        assert by_n[6000][key] == pytest.approx(20 * by_n[300][key], rel=1e-12)
    for key in ("compl_inf_tol", "acceptable_compl_inf_tol", "obj_scaling_factor"):
        assert by_n[6000][key] == by_n[300][key]
    # the same optimum: every parameter within a thousandth of its standard error (of the 300 poses: the larger),
    # the loss 20 times the 300 poses'
    free = one.parameters.free
    dv = np.abs(many.parameters.values - one.parameters.values)[free] / one.parameters.stds[free]
    assert dv.max() < 1e-3
    assert many.solver.cost == pytest.approx(20 * one.solver.cost, rel=1e-8)


def test_ipopt_ending_on_tiny_steps_is_converged():
    """IPOPT ends with "Search_Direction_Becomes_Too_Small" after two Newton steps in a row below tiny_step_tol
    with the barrier parameter at its floor: the best the rounding allows, a converged solve (forced here from
    LM's optimum: a barrier parameter that cannot fall, every step tiny)."""
    from casadical.problem import CalibrationProblem
    from casadical.solvers import make_solver

    robot = load_robot("ys100")
    data, _ = simulate(robot, 300, Effects(), seed=1)
    lm = calibrate(robot, data, "kinematic", "lm", warn=False)
    prob = CalibrationProblem(lm.model, lm.parameters.copy(), data.q, data.xyz, lm.model.covariates(data), lm.base0,
                              lm.loss)
    forced = {"tiny_step_tol": 1e10, "tol": 1e-30, "mu_init": 1e-9, "mu_target": 1e-9}
    x = prob.x_from_values(lm.parameters.values)
    res = make_solver("ipopt", options=forced).solve(prob, x)
    assert res.status == "Search_Direction_Becomes_Too_Small" and res.success
    assert np.abs(res.x - x).max() < 1e-6     # stayed at the optimum (scaled units)


def test_auto_hands_max_iter_to_ipopt():
    """``auto`` runs LM, then IPOPT where LM leaves the bounds (this robot's compliances go negative): a
    ``max_iter`` setting holds for both."""
    robot = load_robot("ur10")
    data = Measurements.read_csv(UR10_B, n_joints=6, require_positions=True)
    cal = data.subset(np.sort(np.random.default_rng(0).permutation(len(data))[:200]))
    free = calibrate(robot, cal, "kinematic+compliance", "auto", warn=False)
    capped = calibrate(robot, cal, "kinematic+compliance", "auto", warn=False, solver_options={"max_iter": 3})
    assert free.solver_name == "levenberg-marquardt+ipopt"
    if free.solver.iterations <= 3:     # the premise, the machine's arithmetic: IPOPT needs more than 3 iterations
        pytest.skip(f"IPOPT converges in {free.solver.iterations} iterations here: a cap of 3 is not reached")
    assert capped.solver.iterations == 3 and not capped.solver.success


def test_too_few_poses_says_how_many():
    robot = load_robot("ys100")
    data, _ = simulate(robot, 8, Effects(), seed=1)
    with pytest.raises(IdentifiabilityError, match=r"at least \d+ poses are needed"):
        calibrate(robot, data, "kinematic+compliance")


def test_degenerate_poses_warn_and_fix():
    robot = load_robot("ys100")
    rng = np.random.default_rng(2)
    q = np.tile(np.radians([0, 60, 10, 20, 30, 40]), (40, 1))
    q[:, 0] = rng.uniform(-2, 2, 40)   # only joint 1 moves
    data, _ = simulate(robot, q, Effects(), seed=2)
    with pytest.warns(IdentifiabilityWarning, match="cannot identify"):
        res = calibrate(robot, data, "kinematic", "lm")
    assert any(p.identifiable is False and p.term == "geometric" and p.joint and p.joint > 1
               for p in res.parameters)
    line = np.zeros((10, 6))
    line[:, 0] = np.linspace(0, 1, 10)
    flat = Measurements.from_arrays(line, np.column_stack([np.linspace(0, 1, 10), np.zeros(10), np.zeros(10)]))
    with pytest.raises(IdentifiabilityError, match="line"):
        calibrate(robot, flat, "kinematic")


def test_non_convergence_is_reported():
    robot = load_robot("ys100")
    data, _ = simulate(robot, 40, Effects(stiffness=STIFF), seed=3)
    with pytest.warns(ConvergenceWarning, match="did not converge"):
        res = calibrate(robot, data, "kinematic+compliance", "ipopt", solver_options={"max_iter": 1})
    assert not res.solver.success and "did not converge" in " ".join(res.notes)


def test_compiled_model_with_every_solver(tmp_path):
    """With a C compiler, large batches are compiled: every solver must work on them (IPOPT differentiates
    its objective, which a compiled library cannot be), and give the answer of the uncompiled model."""
    import json
    import os
    import shutil
    import subprocess
    import sys
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        pytest.skip("no C compiler on this machine")
    robot = load_robot("ys100")
    data, _ = simulate(robot, 320, Effects(stiffness={2: 1.5e6}), seed=3)     # above JIT_MIN_POSES
    data.write_csv(tmp_path / "d.csv")
    out = {}
    for jit in ("1", "0"):
        env = {**os.environ, "CASADICAL_JIT": jit}
        for solver in ("ipopt", "lm"):
            path = tmp_path / f"{solver}{jit}.json"
            r = subprocess.run([sys.executable, "-m", "casadical", "calibrate", "ys100", str(tmp_path / "d.csv"),
                                "--model", "kinematic+compliance[2]", "--solver", solver, "--out", str(path)],
                               capture_output=True, text=True, env=env)
            assert r.returncode == 0, r.stderr
            doc = json.loads(path.read_text())
            out[solver, jit] = {p["name"]: p["value"] for p in doc["parameters"] if not p.get("derived")}
    for solver in ("ipopt", "lm"):
        a, b = out[solver, "1"], out[solver, "0"]
        assert max(abs(a[k] - b[k]) for k in a) < 1e-6
