"""Cross-checks of the pose planner, with the plots of docs/planning.md.

1. ``fig6``: the GA paper's Fig. 6 experiment on the ``ga-ys100-pool``
   protocol: O1 of the D-optimal 20-pose set, of the GA's set, and the
   histogram of O1 over 1,000 random 20-sets of the 70-pose pool; once with
   casadical's scaling (kinematic+compliance, columns times parameter
   scales) and once in the paper's setting (kinematic model, SI columns).
2. ``simulation``: calibrating kinematic+compliance on D-optimal poses and
   on random poses of the same number, 100 repetitions (a new true robot and
   pool each time), judged on 500 independent validation poses.
3. ``ga``: D-optimal against the GA selector with certificates (D-efficiency
   against the relaxation bound) over several pools and M.

Usage::

    python benchmarks/studies/study_planning.py                    # all parts, ~10 min
    python benchmarks/studies/study_planning.py --parts fig6 ga --reps 20 --json study.json

Plots go to ``docs/img/planning_*.png`` (``--out-dir``); the numbers are
printed as markdown tables and optionally written as JSON.
"""

from __future__ import annotations

import argparse
import os
import sys


def _parse() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--parts", nargs="+", default=["fig6", "simulation", "ga"],
                    choices=["fig6", "simulation", "ga"])
    ap.add_argument("--reps", type=int, default=100, help="repetitions of the simulation study")
    ap.add_argument("--out-dir", default=os.path.join(os.path.dirname(__file__), "..", "..", "docs", "img"))
    ap.add_argument("--json", default=None, help="write every number here")
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads")
    return ap.parse_args()


ARGS = _parse() if __name__ == "__main__" else None
if ARGS is not None:
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.threads)

import json  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from casadical.data import load_protocol, sample_poses, simulate  # noqa: E402
from casadical.model import Model  # noqa: E402
from casadical.planning import (  # noqa: E402
    PlanSettings,
    d_efficiency,  # noqa: E402
    design_problem,
    o1_batch,  # noqa: E402
    random_o1,
    select_poses,
)

PAPER = {"ga_best": 0.0182, "random_max": 0.01613, "random_mean": 0.01357}
GA_SEEDS = range(5)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


# --- 1. the GA paper's Fig. 6 -----------------------------------------------------------


def fig6(out_dir: str) -> dict:
    proto = load_protocol("ga-ys100-pool")
    sets, _ = proto.generate()
    pool = sets["pool"]
    results = {}
    for label, spec, scaling in [("casadical", "kinematic+compliance", "scales"),
                                 ("paper setting", "kinematic", "si")]:
        model = Model(proto.robot, spec)
        prob = design_problem(model, pool.q, model.covariates(pool), scaling=scaling)
        d = select_poses(model, None, 20, "d-optimal", problem=prob)
        gas = [select_poses(model, None, 20, "ga", seed=s, problem=prob) for s in GA_SEEDS]
        rand = random_o1(prob.A, 20, 1000, seed=2020)
        ga_best = max(gas, key=lambda g: g.O1)
        results[label] = {
            "model": spec, "scaling": scaling, "p": prob.n_parameters,
            "doptimal_O1": d.O1, "doptimal_d_eff": d.d_efficiency, "doptimal_time_s": d.time_s,
            "ga_O1": [g.O1 for g in gas], "ga_d_eff": [g.d_efficiency for g in gas],
            "ga_time_s": [g.time_s for g in gas],
            "random_max": float(rand.max()), "random_mean": float(rand.mean()),
            "random_min": float(rand.min()), "random_hist": rand.tolist(),
            "upper_bound_O1": float(np.exp(d.upper_bound / (2 * prob.n_parameters)) / np.sqrt(20)),
            "ga_best_O1": ga_best.O1,
        }
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, (label, r) in zip(axes, results.items()):
        ax.hist(r["random_hist"], bins=40, color="0.75", edgecolor="0.5",
                label=f"1,000 random 20-sets (max {r['random_max']:.4g}, mean {r['random_mean']:.4g})")
        ax.axvline(r["doptimal_O1"], color="C3", lw=2, label=f"D-optimal {r['doptimal_O1']:.4g}")
        for k, v in enumerate(r["ga_O1"]):
            ax.axvline(v, color="C0", lw=1, ls="--", label=f"GA, {len(r['ga_O1'])} seeds "
                       f"({min(r['ga_O1']):.4g}..{max(r['ga_O1']):.4g})" if k == 0 else None)
        ax.axvline(r["upper_bound_O1"], color="k", lw=1, ls=":", label=f"relaxation bound {r['upper_bound_O1']:.4g}")
        unit = "m" if r["scaling"] == "scales" else "SI"
        ax.set_xlabel(f"O1 ({unit})")
        ax.set_ylabel("random sets")
        ax.set_title(f"{label}: {r['model']}, {r['p']} parameters, "
                     f"{'scaled' if r['scaling'] == 'scales' else 'SI'} columns", fontsize=9)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("GA paper Fig. 6 on the ga-ys100-pool protocol: 20 poses out of 70", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "planning_fig6.png"), dpi=120)
    plt.close(fig)
    print("\n### Fig. 6: O1 of 20-pose sets from the 70-pose pool\n")
    print("| setting | p | D-optimal | GA best (5 seeds) | GA worst | random max | random mean | "
          "D-opt / random max | D-opt / random mean | bound (O1) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, r in results.items():
        print(f"| {label} ({r['model']}, {r['scaling']}) | {r['p']} | {r['doptimal_O1']:.5g} "
              f"| {max(r['ga_O1']):.5g} | {min(r['ga_O1']):.5g} | {r['random_max']:.5g} | {r['random_mean']:.5g} "
              f"| {r['doptimal_O1'] / r['random_max']:.3f} | {r['doptimal_O1'] / r['random_mean']:.3f} "
              f"| {r['upper_bound_O1']:.5g} |")
    print(f"| GA paper (Fig. 6) | ? | - | {PAPER['ga_best']} | - | {PAPER['random_max']} "
          f"| {PAPER['random_mean']} | {PAPER['ga_best'] / PAPER['random_max']:.3f} (GA) "
          f"| {PAPER['ga_best'] / PAPER['random_mean']:.3f} (GA) | - |")
    for r in results.values():
        r.pop("random_hist")
    return results


# --- 2. simulation study ----------------------------------------------------------------


def _calibrate_errors(robot, data, val, truth) -> dict:
    """Validation errors (mm) of a calibration: against the noisy measurements and the true positions."""
    from casadical.calibration import calibrate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(robot, data, "kinematic+compliance", solver="lm", warn=False)
    pred = cal.predict(val)
    e_meas = np.linalg.norm(pred - val.xyz, axis=1) * 1000.0
    e_true = np.linalg.norm(pred - truth.predict(val), axis=1) * 1000.0
    return {"meas_mean": float(e_meas.mean()), "meas_max": float(e_meas.max()),
            "true_mean": float(e_true.mean()), "true_max": float(e_true.max())}


def simulation(out_dir: str, reps: int) -> dict:
    proto = load_protocol("ga-ys100-pool")
    robot = proto.robot
    model = Model(robot, "kinematic+compliance")
    configs = {"70-pose pool, M = 20 (the paper's protocol)": (70, 20),
               "1,000-pose pool, M = 64 (= 2p)": (1000, 64)}
    keys = ("meas_mean", "meas_max", "true_mean", "true_max")
    out: dict = {}
    for name, (n_pool, m) in configs.items():
        res = {"doptimal": {k: [] for k in keys}, "random": {k: [] for k in keys}}
        errors: list[str] = []
        d_eff = []
        t0 = time.perf_counter()
        for rep in range(reps):
            rng = np.random.default_rng(10_000 + rep)
            _, truth = proto.generate(seed=10_000 + rep)  # a new true robot each repetition
            q_pool = sample_poses(robot, n_pool, rng, **proto.workspace)
            val, _ = simulate(robot, 500, truth=truth, seed=int(rng.integers(2**31)), **proto.workspace)
            prob = design_problem(model, q_pool)
            d = select_poses(model, None, m, "d-optimal", problem=prob,
                             settings=PlanSettings(certify=False))
            d_eff.append(d.d_efficiency)
            r_idx = np.sort(rng.choice(n_pool, m, replace=False))
            for label, idx in (("doptimal", d.indices), ("random", r_idx)):
                data, _ = simulate(robot, q_pool[idx], truth=truth, seed=int(rng.integers(2**31)))
                try:
                    e = _calibrate_errors(robot, data, val, truth)
                except Exception as exc:  # a failed calibration counts, it is not hidden
                    e = {k: float("nan") for k in keys}
                    errors.append(f"rep {rep} {label}: {type(exc).__name__}: {exc}")
                for k in keys:
                    res[label][k].append(e[k])
        arr = {lab: {k: np.array(v) for k, v in d.items()} for lab, d in res.items()}
        ok = np.isfinite(arr["doptimal"]["true_mean"]) & np.isfinite(arr["random"]["true_mean"])
        entry = {"n_pool": n_pool, "m": m, "reps": reps, "failed": int((~ok).sum()), "errors": errors,
                 "time_s": time.perf_counter() - t0}
        for k in keys:
            dd, rr = arr["doptimal"][k][ok], arr["random"][k][ok]
            entry[k] = {"doptimal": _stats(dd), "random": _stats(rr), "doptimal_wins": float(np.mean(dd < rr)),
                        "ratio_median": float(np.median(dd / rr)),
                        "reduction_of_average_pct": float(100 * (1 - dd.mean() / rr.mean()))}
        entry["per_rep"] = {lab: {k: arr[lab][k].tolist() for k in keys} for lab in arr}
        entry["d_efficiency"] = _stats(np.array(d_eff, dtype=float))
        out[name] = entry
    plt = _plt()
    fig, axes = plt.subplots(2, len(out), figsize=(11, 7))
    for col, (name, r) in enumerate(out.items()):
        for row, (k, what) in enumerate((("true_mean", "error against the true positions"),
                                         ("meas_mean", "error against the noisy measurements"))):
            ax = axes[row, col]
            d = np.array(r["per_rep"]["doptimal"][k])
            rr = np.array(r["per_rep"]["random"][k])
            ok = np.isfinite(d) & np.isfinite(rr)
            both = np.concatenate([d[ok], rr[ok]])
            bins = np.linspace(both.min(), np.percentile(both, 99.5), 40)
            st = r[k]
            ax.hist(rr[ok], bins=bins, alpha=0.6, color="0.5",
                    label=f"random: mean {st['random']['mean'] * 1000:.1f} um, "
                          f"median {st['random']['median'] * 1000:.1f} um")
            ax.hist(d[ok], bins=bins, alpha=0.7, color="C3",
                    label=f"D-optimal: mean {st['doptimal']['mean'] * 1000:.1f} um, "
                          f"median {st['doptimal']['median'] * 1000:.1f} um")
            ax.set_xlabel(f"validation mean {what} (mm), 500 poses", fontsize=8)
            ax.set_ylabel("repetitions")
            ax.set_title(f"{name}: D-optimal better in {100 * st['doptimal_wins']:.0f} % of "
                         f"{int(ok.sum())}, average -{st['reduction_of_average_pct']:.0f} %", fontsize=8)
            ax.legend(fontsize=7)
    fig.suptitle("Calibrating kinematic+compliance (YS100, noise 0.02 mm per axis): D-optimal vs random "
                 "poses, 100 repetitions", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "planning_simulation.png"), dpi=120)
    plt.close(fig)
    print("\n### Simulation: validation mean error (mm) over repetitions\n")
    print("| configuration | error against | D-optimal mean / median / p90 | random mean / median / p90 "
          "| D-opt better in | median ratio D/R | average error reduction |")
    print("|---|---|---|---|---|---|---|")
    for name, r in out.items():
        for k, what in (("true_mean", "true positions"), ("meas_mean", "measurements"),
                        ("true_max", "true positions (max)")):
            a, b = r[k]["doptimal"], r[k]["random"]
            print(f"| {name} ({r['reps'] - r['failed']} reps) | {what} | {a['mean']:.4f} / {a['median']:.4f} / "
                  f"{a['p90']:.4f} | {b['mean']:.4f} / {b['median']:.4f} / {b['p90']:.4f} "
                  f"| {100 * r[k]['doptimal_wins']:.0f} % | {r[k]['ratio_median']:.3f} "
                  f"| {r[k]['reduction_of_average_pct']:.1f} % |")
    print("\n### Simulation: certified D-efficiency of the D-optimal sets over the repetitions\n")
    print("| configuration | lowest | median | highest |")
    print("|---|---|---|---|")
    for name, r in out.items():
        e = r["d_efficiency"]
        print(f"| {name} | {e['min']:.4f} | {e['median']:.4f} | {e['max']:.4f} |")
    for r in out.values():
        r.pop("per_rep")
    return out


def _stats(x: np.ndarray) -> dict:
    return {"mean": float(np.mean(x)), "median": float(np.median(x)), "p90": float(np.percentile(x, 90)),
            "min": float(np.min(x)), "max": float(np.max(x))}


# --- 3. D-optimal vs GA with certificates -------------------------------------------------


def ga_vs_doptimal(out_dir: str) -> dict:
    proto = load_protocol("ga-ys100-pool")
    robot = proto.robot
    model = Model(robot, "kinematic+compliance")
    sets, _ = proto.generate()
    q70 = sets["pool"].q
    q1000 = sample_poses(robot, 1000, np.random.default_rng(7), **proto.workspace)
    cases = [("70", q70, m) for m in (12, 20, 32, 48)] + [("1000", q1000, m) for m in (20, 64)]
    rows = []
    for pool_name, q, m in cases:
        prob = design_problem(model, q)
        p = prob.n_parameters
        d = select_poses(model, None, m, "d-optimal", problem=prob)
        gas = [select_poses(model, None, m, "ga", seed=s, problem=prob,
                            settings=PlanSettings(certify=False)) for s in GA_SEEDS]
        ga_eff = [d_efficiency(g.log_det, d.upper_bound, p) for g in gas]
        rs = np.sort(np.argsort(np.random.default_rng(1).random((1000, len(q))), axis=1)[:, :m], axis=1)
        o1 = o1_batch(prob.A, rs)
        best_rand_ld = 2 * p * np.log(o1.max() * np.sqrt(m)) if o1.max() > 0 else -np.inf
        rows.append({"pool": pool_name, "m": m, "p": p, "bound": d.upper_bound,
                     "gap_per_param": d.relaxation_gap,
                     "doptimal_eff": d.d_efficiency, "doptimal_O1": d.O1, "doptimal_time_s": d.time_s,
                     "ga_eff": ga_eff, "ga_O1": [g.O1 for g in gas], "ga_time_s": [g.time_s for g in gas],
                     "random_best_eff": d_efficiency(best_rand_ld, d.upper_bound, p),
                     "ga_beats_doptimal": int(sum(g.log_det > d.log_det + 1e-9 for g in gas))})
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 4))
    x = np.arange(len(rows))
    ax.bar(x - 0.27, [r["doptimal_eff"] for r in rows], 0.27, color="C3", label="D-optimal")
    ge = np.array([r["ga_eff"] for r in rows])
    ax.bar(x, ge.mean(axis=1), 0.27, color="C0", label=f"GA ({len(GA_SEEDS)} seeds: mean, min-max)",
           yerr=[ge.mean(axis=1) - ge.min(axis=1), ge.max(axis=1) - ge.mean(axis=1)], capsize=3)
    ax.bar(x + 0.27, [r["random_best_eff"] for r in rows], 0.27, color="0.6", label="best of 1,000 random sets")
    ax.set_xticks(x, [f"pool {r['pool']}\nM = {r['m']}" for r in rows], fontsize=8)
    lo = min(min(r["random_best_eff"] for r in rows), ge.min()) - 0.05
    ax.set_ylim(max(0.0, lo), 1.0)
    ax.set_ylabel("certified D-efficiency (lower bound)")
    ax.set_title("D-efficiency against the relaxation's upper bound (1 = provably optimal), "
                 f"kinematic+compliance, p = {rows[0]['p']}", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "planning_ga_vs_doptimal.png"), dpi=120)
    plt.close(fig)
    print("\n### D-optimal vs GA: certified D-efficiency (lower bounds)\n")
    print("| pool | M | D-optimal | GA mean (min..max), 5 seeds | best of 1,000 random | GA sets better than "
          "D-optimal | D-opt time (s) | GA time (s, mean) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        g = np.array(r["ga_eff"])
        print(f"| {r['pool']} | {r['m']} | {r['doptimal_eff']:.4f} | {g.mean():.4f} ({g.min():.4f}..{g.max():.4f}) "
              f"| {r['random_best_eff']:.4f} | {r['ga_beats_doptimal']} of {len(g)} | {r['doptimal_time_s']:.3f} "
              f"| {np.mean(r['ga_time_s']):.2f} |")
    return {"rows": rows}


def main() -> int:
    args = ARGS
    os.makedirs(args.out_dir, exist_ok=True)
    results = {}
    if "fig6" in args.parts:
        results["fig6"] = fig6(args.out_dir)
    if "ga" in args.parts:
        results["ga"] = ga_vs_doptimal(args.out_dir)
    if "simulation" in args.parts:
        results["simulation"] = simulation(args.out_dir, args.reps)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
