"""Study: calibration of a real UR10 (laser-tracker data), held-out accuracy.

Data: ``problems/datasets/ur10-ipa`` (Landgraf et al., IEEE CASE 2021; MIT
licence), robot ``ur10``. For each random split (seeds 0..4 by default):

- series B (1,495 poses): a held-out set of the poses not drawn for
  calibration (the same held-out poses for every model and calibration size
  of a split: the permutation's poses after the first 600); calibration sets
  of the first 100, 300 and 600 poses of the permutation;
- series A (11,911 poses): 600 calibration poses and 3,000 random held-out
  poses (a subset, to keep the time down).

Models: ``nominal`` (manufacturer's DH table, only the base pose estimated),
``kinematic`` (every identifiable geometric parameter) and
``kinematic+compliance`` (plus joint compliance c_j = 1/k_j, deflection
c_j * gravity torque), with Levenberg-Marquardt and IPOPT; compliance of
joints 2 and 3 only; and, to see what the compliance absorbs, both with the
three periodic gear errors that docs/diagnosis.md finds in both series. Reported: held-out
position error mean / max / std / rms (mm) as mean +- standard deviation over
the splits, the RMS on the calibration poses, calibration time, and the
identified joint stiffness with its standard error.

Usage::

    python benchmarks/studies/study_ur10.py                 # 5 splits, series B and A (~2-3 min)
    python benchmarks/studies/study_ur10.py --seeds 0 1 --series B
    python benchmarks/studies/study_ur10.py --json ur10.json

BLAS runs single-threaded (``OPENBLAS_NUM_THREADS=1`` unless set): on a
small, busy machine a multi-threaded OpenBLAS spends up to a hundred times
longer on the small least-squares products than one thread (measured here:
a 300-pose calibrate() call 1.4-2 s instead of 15 ms).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "speed"))   # bench_model
from bench_model import cpu_model  # noqa: E402

from casadical.calibration import calibrate  # noqa: E402
from casadical.data import Measurements  # noqa: E402
from casadical.loading import load_robot  # noqa: E402
from casadical.model import Model  # noqa: E402

DATA = ROOT / "problems" / "datasets" / "ur10-ipa"
KC = "kinematic+compliance"
KC23 = "kinematic+compliance[2,3]"  # only the joints with sizeable gravity torque
# the periodic gear errors that docs/diagnosis.md finds in both series (joint:harmonic)
PER = "periodic[2:3,2:17,3:17]"
KP, KCP = f"kinematic+{PER}", f"kinematic+compliance[2,3]+{PER}"
# (model, solver, calibration poses) per series
CONFIGS = {
    "B": [("nominal", "lm", 300), ("kinematic", "lm", 100), ("kinematic", "lm", 300), ("kinematic", "lm", 600),
          (KC, "lm", 100), (KC, "lm", 300), (KC, "ipopt", 300), (KC, "lm", 600), (KC23, "lm", 300),
          (KP, "lm", 300), (KCP, "lm", 300)],
    "A": [("nominal", "lm", 600), ("kinematic", "lm", 600), (KC, "lm", 600), (KC, "ipopt", 600),
          (KC23, "lm", 600), (KP, "lm", 600), (KCP, "lm", 600)],
}
# (with, without) compliance: the paired held-out comparison
PAIRS = [(KC, "kinematic"), (KC23, "kinematic"), (KCP, KP)]
B_HOLDOUT_FROM = 600      # series B: held-out = permutation[600:]
A_CAL, A_VAL = 600, 3000  # series A: calibration and held-out subset sizes
STATS = ("mean_mm", "max_mm", "std_mm", "rms_mm")


def split(series: str, n_total: int, n_cal: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    perm = np.random.default_rng(seed).permutation(n_total)
    if series == "B":
        return np.sort(perm[:n_cal]), np.sort(perm[B_HOLDOUT_FROM:])
    return np.sort(perm[:n_cal]), np.sort(perm[A_CAL:A_CAL + A_VAL])


def pm(values, fmt: str = "{:.3f}") -> str:
    """mean +- sample standard deviation."""
    v = [x for x in values if x == x]
    if not v:
        return "-"
    if len(v) == 1:
        return fmt.format(v[0])
    return fmt.format(statistics.mean(v)) + " ± " + fmt.format(statistics.stdev(v))


def run(robot, series: str, data: Measurements, seeds, models: dict) -> list[dict]:
    rows = []
    for spec, solver, n_cal in CONFIGS[series]:
        for seed in seeds:
            ical, ival = split(series, len(data), n_cal, seed)
            cal, val = data.subset(ical), data.subset(ival)
            model = models.setdefault(spec, Model(robot, spec))
            t0 = time.perf_counter()
            res = calibrate(robot, cal, model, solver, warn=False, position_only=True)   # figures of docs/ur10.md
            wall = time.perf_counter() - t0
            held = res.stats(val)
            comp = {}
            for p in res.parameters.select(term="joint_compliance"):
                if p.fixed:
                    continue
                comp[p.joint] = (p.value, p.std)
            row = {"series": series, "model": spec, "solver": solver, "n_cal": n_cal, "n_val": len(val),
                   "seed": seed, "status": res.solver.status, "iterations": res.solver.iterations,
                   "wall_s": wall, "solve_s": res.solver.solve_time_s, "cal_rms_mm": res.calibration.rms_mm,
                   **{k: getattr(held, k) for k in STATS}, "compliance": comp,
                   "fixed": [p.name for p in res.parameters if p.fixed and p.reason != "nominal model"],
                   "notes": res.notes}
            rows.append(row)
            print(f"  {series} {spec:<22} {solver:<6} cal {n_cal:>4} seed {seed}: held-out mean "
                  f"{held.mean_mm:.4f} max {held.max_mm:.4f} rms {held.rms_mm:.4f} mm; cal rms "
                  f"{res.calibration.rms_mm:.4f}; {res.solver.status}, {res.solver.iterations} it, "
                  f"{wall:.2f} s", flush=True)
    return rows


def table(rows: list[dict]) -> str:
    head = ["series", "model", "solver", "cal poses", "held-out poses", "mean (mm)", "max (mm)", "std (mm)",
            "rms (mm)", "cal rms (mm)", "calibrate() first / median", "solve (median)"]
    out = ["| " + " | ".join(head) + " |", "|---|---|---|" + "|".join("---:" for _ in head[3:]) + "|"]
    keys = []
    for r in rows:
        k = (r["series"], r["model"], r["solver"], r["n_cal"])
        if k not in keys:
            keys.append(k)
    for k in keys:
        g = [r for r in rows if (r["series"], r["model"], r["solver"], r["n_cal"]) == k]
        name = "nominal (base only)" if k[1] == "nominal" else k[1]
        out.append(f"| {k[0]} | {name} | {k[2]} | {k[3]} | {g[0]['n_val']} | "
                   + " | ".join(pm([r[s] for r in g]) for s in STATS)
                   + f" | {pm([r['cal_rms_mm'] for r in g])}"
                   + f" | {g[0]['wall_s']:.2f} s / {statistics.median(r['wall_s'] for r in g):.3f} s"
                   + f" | {statistics.median(r['solve_s'] for r in g) * 1e3:.1f} ms |")
    return "\n".join(out)


def stiffness_table(rows: list[dict]) -> str:
    out = ["| series | model | solver | cal poses | joint | c (urad/(N m)), mean ± sd over splits | "
           "its std error (median) | k = 1/mean c (N m/rad) | k range over splits |",
           "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    groups: dict = {}
    for r in rows:
        if r["model"].startswith(KC):
            groups.setdefault((r["series"], r["model"], r["solver"], r["n_cal"]), []).append(r)
    for (series, spec, solver, n_cal), g in groups.items():
        for j in sorted({j for r in g for j in r["compliance"]}):
            c = [r["compliance"][j][0] for r in g if j in r["compliance"]]
            s = [r["compliance"][j][1] for r in g if j in r["compliance"]]
            cm = statistics.mean(c)
            k = f"{1 / cm:.3g}" if cm > 0 else "inf (c <= 0)"
            ks = [1 / x if x > 0 else math.inf for x in c]
            out.append(f"| {series} | {spec} | {solver} | {n_cal} | {j} | {pm([x * 1e6 for x in c], '{:.2f}')} | "
                       f"{statistics.median(s) * 1e6:.2f} | {k} | {min(ks):.3g} - {max(ks):.3g} |")
    return "\n".join(out)


def paired(rows: list[dict]) -> str:
    """Held-out change from adding compliance, split by split (same calibration and held-out poses): a table."""
    out = ["| series, cal poses | comparison | mean (mm) | rms (mm) | max (mm) |", "|---|---|---|---|---|"]
    for series in ("B", "A"):
        for n_cal in sorted({r["n_cal"] for r in rows if r["series"] == series}):
            for spec, ref in PAIRS:
                base = {r["seed"]: r for r in rows
                        if (r["series"], r["model"], r["n_cal"]) == (series, ref, n_cal)}
                comp = {r["seed"]: r for r in rows
                        if (r["series"], r["model"], r["solver"], r["n_cal"]) == (series, spec, "lm", n_cal)}
                seeds = sorted(set(base) & set(comp))
                if not seeds:
                    continue
                parts = []
                for k in ("mean_mm", "rms_mm", "max_mm"):
                    d = [comp[s][k] - base[s][k] for s in seeds]
                    parts.append(f"{min(d):+.4f} .. {max(d):+.4f}")
                out.append(f"| {series}, {n_cal} | {spec} - {ref} | " + " | ".join(parts) + " |")
    return "\n".join(out)


def torques(robot, data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Largest and median |gravity torque| per joint over the data (nominal model, the robot file's masses)."""
    m = Model(robot, KC, jit=False)
    tau = np.abs(m.torques(data.q, m.parameters.values, m.covariates(data)))
    return tau.max(axis=0), np.median(tau, axis=0)


def torque_table(contexts: dict) -> str:
    series = list(contexts)
    out = ["| joint | " + " | ".join(f"series {s}: largest (N m) | median (N m)" for s in series) + " |",
           "|---:|" + "---:|---:|" * len(series)]
    for j in range(len(next(iter(contexts.values()))[0])):
        out.append(f"| {j + 1} | " + " | ".join(f"{contexts[s][0][j]:.1f} | {contexts[s][1][j]:.1f}"
                                                for s in series) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--series", nargs="+", default=["B", "A"], choices=["A", "B"])
    ap.add_argument("--json", metavar="PATH", help="also write every run as JSON")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    robot = load_robot("ur10")
    print(f"machine: {cpu_model()}, {os.cpu_count()} cores; Python {platform.python_version()}, "
          f"numpy {np.__version__}, CasADi {ca.__version__}; load average {os.getloadavg()[0]:.2f} at start")
    rows: list[dict] = []
    contexts = {}
    for series in args.series:
        data = Measurements.read_csv(DATA / f"series_{series.lower()}.csv", n_joints=6)
        print(f"\nseries {series}: {len(data)} poses")
        contexts[series] = torques(robot, data)
        models: dict = {}  # one model per specification, reused over splits (JIT compiled once)
        rows += run(robot, series, data, args.seeds, models)

    print(f"\nHeld-out position error, mean ± standard deviation over {len(args.seeds)} random splits "
          f"(seeds {', '.join(map(str, args.seeds))}); series B held-out = the {B_HOLDOUT_FROM}+ part of each "
          f"permutation (same poses for every model and size), series A: {A_CAL} calibration and {A_VAL} "
          "held-out poses; calibrate() wall time of the first split (includes the JIT compile of a new model at \n"
          "300+ poses) and the median over splits; solve = the solver's own time:\n")
    print(table(rows))
    print(f"\nEffect of compliance on the held-out errors, split by split: the change from the model without to "
          f"the model with compliance, smallest .. largest over the {len(args.seeds)} splits (same calibration "
          "and held-out poses; negative = better):\n")
    print(paired(rows))
    print("\nIdentified joint compliance (kinematic+compliance), joints the identifiability analysis kept "
          "free:\n")
    print(stiffness_table(rows))
    print("\nGravity torques over the data, |tau| per joint (nominal model, the robot file's masses, no payload):\n")
    print(torque_table(contexts))
    fixed = sorted({n for r in rows if r["model"] == KC for n in r["fixed"]})  # union over splits
    print(f"\nfixed in kinematic+compliance runs (not identifiable from these poses): {', '.join(fixed)}")
    statuses = sorted({(r["solver"], r["status"]) for r in rows})
    print("solver statuses seen: " + ", ".join(f"{s}: {t}" for s, t in statuses))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float))
        print(f"results written to {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
