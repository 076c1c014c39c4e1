"""Calibration time against the number of poses: 2,000, 20,000 and 200,000 (issue 21, item 4).

Data: the YS100 of the CA paper's protocol (``problems/protocols/ca-ys100.toml``:
geometric errors, joint stiffness k2..k5, 110 kg payload, 20 um tracker
noise), simulated once at the largest size; each size takes the first N
of those poses. Two models: ``kinematic+compliance`` (exact: the model the
data were simulated with) and ``kinematic`` (a misfit: the compliance is
not modelled and leaves about 3.6 mm RMS).

Each figure is one fresh process per run that loads the poses and times
one call (its peak resident memory, ``ru_maxrss``, is the process's), in
turn, interleaved run by run:

- casadical IPOPT: ``calibrate(robot, data, model)``, the default solver and
  loss (pseudo-Huber, noise scale re-estimated), everything the call does
  (identifiability analysis, alignment, the robust loop, uncertainty);
- casadical IPOPT, tolerances on the sum: the same call with IPOPT's
  tolerances as before issue 21 (``tol`` 1e-8 and ``acceptable_tol`` 1e-6 on
  the loss summed over the poses, IPOPT's own ``compl_inf_tol``,
  ``barrier_tol_factor`` and ``tiny_step_tol``): the baseline of the change;
- casadical LM: the same call with ``solver="lm"``;
- scipy reference: ``scipy.optimize.least_squares(method="lm")`` (MINPACK)
  on the numpy model of ``numpy_model.py`` with its batched forward-difference
  Jacobian (``bench_calibration.NumpyProblem``), the same robust loss written
  as least squares (each pose's residual times ``sqrt(2 rho(u2) / u2)``) and
  the same noise-scale loop, from nominal, given casadical LM's free set and
  base pose: its time has no identifiability analysis and no uncertainty.

Columns: wall and CPU time of the call, time per 1,000 poses and its ratio
to the smallest size's (the target: at most 2 from 2,000 to 200,000),
iterations (casadical: per solve of the noise-scale loop, IPOPT's with its
objective evaluations; scipy: function evaluations), peak memory and its
excess over a process that only loads the poses (``VmHWM``), RMS of the calibration
residuals, and the largest parameter difference to casadical IPOPT's result
in units of the parameter's typical size (the same optimum: below 1e-4).

Usage::

    python benchmarks/speed/bench_scale.py                        # 2k, 20k, 200k: ~15-30 min on 2 cores
    python benchmarks/speed/bench_scale.py --sizes 2000 20000 --repeats 3
    python benchmarks/speed/bench_scale.py --no-before --no-scipy --json out.json
    python benchmarks/speed/bench_scale.py --sizes 200000 --no-before --no-scipy --base /work/base --repeats-large 3

With ``--base`` each of casadical's methods runs from that tree too, right after this tree's, and a last table
puts the two side by side: CPU and peak memory (median and range), linearisations of every pose, and this
tree's answer against the base's (the largest parameter difference in the base's standard errors, the mean and
max error). Each tree has its own compiled-function cache in the run's folder, filled by an untimed run.

BLAS runs single-threaded (``OPENBLAS_NUM_THREADS=1`` unless set). The
compiled model functions come from the disk cache (one untimed run per
model at the smallest size fills it).
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
SIZES = [2_000, 20_000, 200_000]
MODELS = ["kinematic+compliance", "kinematic"]
#: IPOPT's tolerances before issue 21: on the summed objective (mm^2) whatever the number of poses, and
#: IPOPT's own tiny_step_tol (10 machine epsilons)
SUM_TOLERANCES = {"tol": 1e-8, "acceptable_tol": 1e-6, "compl_inf_tol": 1e-4, "acceptable_compl_inf_tol": 1e-2,
                  "barrier_tol_factor": 10, "tiny_step_tol": 10 * 2.0 ** -52}
METHODS = {"ipopt": "casadical IPOPT", "before": "casadical IPOPT, tolerances on the sum",
           "lm": "casadical LM", "scipy": "scipy least_squares lm, numpy model, batched FD Jacobian"}
LINEAR_RATIO = 2.0   # the target: time per pose at the largest size within 2x of the smallest's


# --- the children (run in their own process: python bench_scale.py --child ...) -----------------------


def _load(npz: str, N: int):
    from casadical.data import Measurements

    d = np.load(npz)
    return Measurements.from_arrays(d["q"][:N], d["xyz"][:N])


def _peak_mb() -> float:
    """Peak resident memory of this process (VmHWM: ru_maxrss would keep the parent's peak across exec)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return float(line.split()[1]) / 1024
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def child(method: str, npz: str, N: int, spec: str, free_json: str, out: str) -> None:
    """One timed call; writes time, CPU time, peak memory, iterations, RMS and the parameter values."""
    from casadical import calibrate, load_robot

    robot = load_robot("ys100")
    data = _load(npz, N)
    doc: dict = {}
    if method == "load":
        pass
    elif method == "scipy":
        doc = _scipy(robot, data, spec, json.loads(Path(free_json).read_text()))
    else:
        try:
            import casadical.calibration._solve as C
        except ImportError:     # before calibrate() became a pipeline (fe55b8a): PYTHONPATH at that tree
            import casadical.calibration as C
        from casadical.problem import CalibrationProblem
        from casadical.solvers import Ipopt

        linearize = CalibrationProblem.linearize
        lins = [0]

        def counting(self, values):     # linearisations of every pose (not of a subsample)
            lins[0] += self.n_poses == N
            return linearize(self, values)

        CalibrationProblem.linearize = counting

        solves, solve = [], C._solve

        def recorded(problem, x0, solver, opts, *warm):   # every solve of the noise-scale loop
            res, name = solve(problem, x0, solver, opts, *warm)
            solves.append(f"{res.iterations}" + ("" if problem.n_poses == N else f"@{problem.n_poses:,}"))
            return res, name

        C._solve = recorded
        ipopt_evals = []
        ipopt_solve = Ipopt.solve

        def counted(self, problem, x0=None):
            res = ipopt_solve(self, problem, x0)
            ipopt_evals.append(int(self._last.stats()["n_call_nlp_f"]))
            return res

        Ipopt.solve = counted
        solver = "lm" if method == "lm" else "ipopt"
        options = {"options": SUM_TOLERANCES} if method == "before" else None
        t0, c0 = time.perf_counter(), time.process_time()
        res = calibrate(robot, data, spec, solver, solver_options=options, warn=False)
        doc = {"time_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "linearisations": lins[0],
               "iterations": "/".join(f"{it}" + (f" ({nf})" if ipopt_evals else "")
                                      for it, nf in zip(solves, ipopt_evals or [None] * len(solves))),
               "status": res.solver.status, "rms_mm": res.calibration.rms_mm,
               "names": res.parameters.names, "values": res.parameters.values.tolist(),
               "scales": res.parameters.scales.tolist(), "base0": res.base0.tolist(),
               "stds": res.parameters.stds.tolist(), "mean_mm": res.calibration.mean_mm,
               "max_mm": res.calibration.max_mm,
               "free": [p.name for p in res.parameters if not p.fixed]}
    doc["peak_mb"] = _peak_mb()
    Path(out).write_text(json.dumps(doc))


def _scipy(robot, data, spec: str, free_doc: dict) -> dict:
    """The scipy reference: robust loss and noise-scale loop as ``calibrate``, least_squares(lm), numpy model."""
    sys.path.insert(0, str(HERE))
    from bench_calibration import NumpyProblem
    from scipy.optimize import least_squares

    from casadical.model import Model
    from casadical.problem import CHI3_MEDIAN, CalibrationProblem

    model = Model(robot, spec, jit=False)   # names, scales, covariates: the numpy model does the work
    params = model.parameters.copy()
    params.fix([n for n in params.names if n not in set(free_doc["free"])], reason="not free in casadical's fit")
    prob = CalibrationProblem(model, params, data.q, data.xyz, model.covariates(data), np.array(free_doc["base0"]))
    npp = NumpyProblem(robot, prob)
    t0, c0 = time.perf_counter(), time.process_time()

    def weights(r, delta):   # a pose's residual times sqrt(2 rho(u2) / u2): the pseudo-Huber loss
        u2 = np.einsum("ij,ij->i", r, r)
        s = np.sqrt(1.0 + delta * u2)
        return np.sqrt(2.0 / (s + 1.0)), u2, s

    def fun(x, delta):
        r = npp.fun(x).reshape(-1, 3)
        return (r * weights(r, delta)[0][:, None]).ravel()

    def jac(x, delta):   # d(w r)/dx with w = w(u2(x)), from the batched finite-difference Jacobian of r
        r = npp.fun(x).reshape(-1, 3)
        J = npp.jac(x).reshape(len(r), 3, -1)
        w, _, s = weights(r, delta)
        dw = -w ** 3 * delta / (8.0 * s)                    # dw/du2
        g = 2.0 * np.einsum("nk,nkp->np", r, J)             # du2/dx
        return (w[:, None, None] * J + (dw[:, None] * g)[:, None, :] * r[:, :, None]).reshape(-1, J.shape[2])

    x = np.zeros(len(prob.free))
    sigma, nfev = math.nan, []
    for _ in range(6):   # casadical.calibration._solve.ROBUST_LOOPS: re-estimate the noise scale until it settles
        r = npp.fun(x).reshape(-1, 3)
        new = max(float(np.median(np.linalg.norm(r, axis=1))) / CHI3_MEDIAN, 1e-12)
        if math.isfinite(sigma) and abs(new / sigma - 1) < 0.05:
            break
        sigma = new
        sol = least_squares(fun, x, jac=jac, method="lm", args=(1.0 / (3.0 * sigma) ** 2,))
        x = sol.x
        nfev.append(int(sol.nfev))
    t, c = time.perf_counter() - t0, time.process_time() - c0
    r = npp.fun(x).reshape(-1, 3)
    values = npp.values(x)
    return {"time_s": t, "cpu_s": c, "iterations": "/".join(map(str, nfev)), "status": "",
            "rms_mm": float(np.sqrt(np.mean(np.sum(r * r, axis=1))) * 1e3), "names": params.names,
            "values": values.tolist(), "scales": params.scales.tolist(), "base0": free_doc["base0"],
            "free": free_doc["free"]}


# --- the benchmark ----------------------------------------------------------------------------------------


def run(method: str, npz: Path, N: int, spec: str, tmp: Path, base: str | None = None) -> dict:
    """One child process; with ``base``, the casadical of that tree (PYTHONPATH) instead of this one. Each tree
    has its own compiled-function cache (``CASADICAL_CACHE`` in the run's folder), run from that folder."""
    out = tmp / f"{method}.json"
    cmd = [sys.executable, __file__, "--child", method, str(npz), str(N), spec, str(tmp / "free.json"), str(out)]
    tree = base or str(HERE.parents[1])
    env = dict(os.environ, PYTHONPATH=tree, CASADICAL_CACHE=str(tmp / ("cache-base" if base else "cache-this")))
    r = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env, cwd=tmp)
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{r.stderr}")
    return json.loads(out.read_text())


def side_by_side(rows: list[dict], base: str) -> None:
    """This tree against the base tree, method by method: CPU and peak memory (median and range of the runs,
    run in turn), and how far this tree's answer is from the base's (parameters in the base's standard
    errors, mean and max error)."""
    print(f"\nThis tree against {base} (CPU of the call; peak memory of the process; median (range)):\n")
    print("| poses | model | method | CPU, this | CPU, base | ratio | peak MB, this | peak MB, base | "
          "linearisations, this / base | max \\|dp\\| / std | mean, max vs base |")
    print("|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")

    def rng(xs, f):
        return f"{f(statistics.median(xs))} ({f(min(xs))}-{f(max(xs))})" if len(xs) > 1 else f(xs[0])

    for b in (r for r in rows if r["key"].endswith("@base")):
        t = next(r for r in rows if r["key"] == b["key"][:-5] and r["poses"] == b["poses"] and r["model"] == b["model"])
        dp, dmean = "-", "-"
        if b.get("stds"):
            std = np.array(b["stds"], float)
            ok = np.isfinite(std) & (std > 0)
            dp = f"{float(np.max(np.abs(np.array(t['values'])[ok] - np.array(b['values'])[ok]) / std[ok])):.1e}"
            dmean = f"{t['mean_mm'] / b['mean_mm'] - 1:+.1e}, {t['max_mm'] / b['max_mm'] - 1:+.1e}"
        print(f"| {t['poses']:,} | {t['model']} | {METHODS[t['key']]} | {rng(t['cpus_s'], fmt)} | "
              f"{rng(b['cpus_s'], fmt)} | {t['cpu_s'] / b['cpu_s']:.2f} | {rng(t['peak_mbs'], lambda x: f'{x:.0f}')} | "
              f"{rng(b['peak_mbs'], lambda x: f'{x:.0f}')} | {t['linearisations']} / {b['linearisations']} | "
              f"{dp} | {dmean} |")


def fmt(s: float) -> str:
    return f"{s:.2f} s" if s < 100 else f"{s:.0f} s"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--child", nargs=6, help=argparse.SUPPRESS)
    ap.add_argument("--sizes", type=int, nargs="+", default=SIZES)
    ap.add_argument("--models", nargs="+", default=MODELS)
    ap.add_argument("--repeats", type=int, default=3, help="runs per figure below 100,000 poses (default 3)")
    ap.add_argument("--repeats-large", type=int, default=1, help="runs per figure from 100,000 poses (default 1)")
    ap.add_argument("--no-before", action="store_true", help="skip IPOPT with the tolerances on the sum")
    ap.add_argument("--no-scipy", action="store_true", help="skip the scipy reference")
    ap.add_argument("--seed", type=int, default=None, help="simulation seed (default: the protocol's)")
    ap.add_argument("--json", metavar="PATH", help="also write the rows as JSON")
    ap.add_argument("--base", metavar="TREE", help="also run casadical's methods from this source tree (e.g. "
                    "/work/base, fe55b8a) in turn with this one, run by run")
    args = ap.parse_args()
    if args.child:
        method, npz, N, spec, free_json, out = args.child
        child(method, npz, int(N), spec, free_json, out)
        return 0

    from dataclasses import replace

    import casadi
    import scipy

    from casadical.data import load_protocol

    methods = ["ipopt"] + ([] if args.no_before else ["before"]) + ["lm"] + ([] if args.no_scipy else ["scipy"])
    if args.base:   # the base tree's casadical methods, each right after this tree's
        methods = [x for m in methods for x in ([m, m + "@base"] if m != "scipy" else [m])]
        for m in list(METHODS):
            METHODS[m + "@base"] = f"{METHODS[m]} ({args.base})"
    sizes = sorted(args.sizes)
    proto = load_protocol("ca-ys100")
    print(f"{os.cpu_count()} cores; Python {sys.version.split()[0]}, numpy {np.__version__}, scipy "
          f"{scipy.__version__}, CasADi {casadi.__version__}; load average {os.getloadavg()[0]:.2f} at start")
    t0 = time.perf_counter()
    sets, _ = replace(proto, sets={"calibration": sizes[-1]}).generate(args.seed)
    data = sets["calibration"]
    print(f"{proto.robot.name}, truth of the {proto.name} protocol ({sizes[-1]:,} poses simulated in "
          f"{time.perf_counter() - t0:.1f} s); one process per run, the call alone timed\n")
    rows = []
    with tempfile.TemporaryDirectory() as tmp_:
        tmp = Path(tmp_)
        npz = tmp / "poses.npz"
        np.savez(npz, q=data.q, xyz=data.xyz)
        for spec in args.models:   # untimed: compiles the model's functions into the disk cache if needed
            for tree in [None] + ([args.base] if args.base else []):
                run("ipopt", npz, min(sizes[0], 2_000), spec, tmp, tree)
                run("lm", npz, min(sizes[0], 2_000), spec, tmp, tree)
        print("| poses | model | method | time (median) | CPU | per 1k poses | x smallest | iterations | "
              "linearisations | peak MB | beyond load-only | RMS (mm) | max \\|dp\\| vs IPOPT | load |")
        print("|---:|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
        for spec in args.models:
            for N in sizes:
                load_mb = run("load", npz, N, spec, tmp)["peak_mb"]
                runs: dict[str, list[dict]] = {m: [] for m in methods}
                for _ in range(args.repeats if N < 100_000 else args.repeats_large):
                    for m in methods:   # interleaved, run by run
                        m_, _, base = m.partition("@")
                        d = run(m_, npz, N, spec, tmp, args.base if base else None)
                        d["load"] = os.getloadavg()[0]
                        runs[m].append(d)
                        if m == "lm":   # the scipy reference gets its free set and base pose
                            (tmp / "free.json").write_text(json.dumps({"free": d["free"], "base0": d["base0"]}))
                ref = runs["ipopt"][-1]
                for m in methods:
                    ds = runs[m]
                    last = ds[-1]
                    dp = np.abs(np.array(last["values"]) - np.array(ref["values"])) / np.array(ref["scales"])
                    row = {"poses": N, "model": spec, "method": METHODS[m], "key": m,
                           "time_s": statistics.median(d["time_s"] for d in ds),
                           "cpu_s": statistics.median(d["cpu_s"] for d in ds), "times_s": [d["time_s"] for d in ds],
                           "iterations": last["iterations"], "status": last["status"], "peak_mb": last["peak_mb"],
                           "peak_mbs": [d["peak_mb"] for d in ds], "cpus_s": [d["cpu_s"] for d in ds],
                           "linearisations": last.get("linearisations", "-"), "values": last["values"],
                           "stds": last.get("stds"), "mean_mm": last.get("mean_mm"), "max_mm": last.get("max_mm"),
                           "load_only_mb": load_mb, "rms_mm": last["rms_mm"], "dp_max": float(dp.max()),
                           "dp_name": ref["names"][int(np.argmax(dp))] if dp.max() > 0 else "",
                           "load": [d["load"] for d in ds]}
                    first = next((r for r in rows if r["model"] == spec and r["key"] == m), None)
                    row["per_pose_ratio"] = (row["time_s"] / N) / (first["time_s"] / first["poses"]) if first else 1.0
                    row["per_pose_ratio_cpu"] = (row["cpu_s"] / N) / (first["cpu_s"] / first["poses"]) if first else 1.0
                    rows.append(row)
                    print(f"| {N:,} | {spec} | {row['method']} | {fmt(row['time_s'])} | {fmt(row['cpu_s'])} | "
                          f"{1000 * row['time_s'] / N * 1000:.1f} ms | {row['per_pose_ratio']:.2f} | "
                          f"{row['iterations']} | {row['linearisations']} | {row['peak_mb']:.0f} | "
                          f"{row['peak_mb'] - load_mb:.0f} | "
                          f"{row['rms_mm']:.4f} | {row['dp_max']:.1e}"
                          + (f" ({row['dp_name']})" if row["dp_max"] >= 1e-6 else "") + " | "
                          f"{'-'.join(f'{x:.1f}' for x in sorted({min(row['load']), max(row['load'])}))} |",
                          flush=True)
                (tmp / "free.json").unlink(missing_ok=True)
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")
    if args.base:
        side_by_side(rows, args.base)
    if len(sizes) > 1:
        print(f"\nTime per pose at {sizes[-1]:,} poses over that at {sizes[0]:,}, wall (CPU) (target: at most "
              f"{LINEAR_RATIO}):")
        for spec in args.models:
            for m in methods:
                last = [r for r in rows if r["model"] == spec and r["key"] == m][-1]
                ok = max(last["per_pose_ratio"], last["per_pose_ratio_cpu"]) <= LINEAR_RATIO
                print(f"  {spec}, {METHODS[m]}: {last['per_pose_ratio']:.2f} ({last['per_pose_ratio_cpu']:.2f})"
                      + ("" if m == "scipy" else f" [{'MET' if ok else 'NOT MET'}]"))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
