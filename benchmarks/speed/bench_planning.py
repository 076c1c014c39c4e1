"""Scale benchmark of the D-optimal pose planner (docs/planning.md, "Scale").

For pools of 10^2 ... 10^5 candidate poses of the YS100 (model
kinematic+compliance, 32 identifiable parameters), measures

- the first-order relaxation (capped multiplicative algorithm): time to a
  certified gap of ``--tol`` per parameter (default 1e-3, the issue's target);
- cvxpy (CLARABEL) on the same relaxation, in a subprocess with a time limit
  (``--cvxpy-timeout``), up to ``--cvxpy-max`` candidates: time, its gap
  (certified with the same bound), and the log det difference per parameter;
- the exact design of M = 2p poses: rounding + Fedorov exchange, its
  certified D-efficiency and time;
- memory: tracemalloc peak of relaxation + exchange, and the process's
  maximum resident set size.

Usage::

    python benchmarks/speed/bench_planning.py                      # all sizes, ~3-10 min
    python benchmarks/speed/bench_planning.py --sizes 100 1000 --json out.json

BLAS threads are set to ``--threads`` (default 1) before numpy is imported:
the matrices are small (p = 32), and several BLAS threads on a shared
machine mostly wait on each other.
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def _parse() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10_000, 100_000])
    ap.add_argument("--robot", default="ys100")
    ap.add_argument("--model", default="kinematic+compliance")
    ap.add_argument("--tol", type=float, default=1e-3, help="certified gap per parameter to reach")
    ap.add_argument("--cvxpy-max", type=int, default=10_000, help="largest pool given to cvxpy")
    ap.add_argument("--cvxpy-timeout", type=float, default=600.0, help="seconds per cvxpy solve")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--json", default=None, help="write the results here")
    return ap.parse_args()


ARGS = _parse() if __name__ == "__main__" else None
if ARGS is not None:
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.threads)

import multiprocessing as mp  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402

import numpy as np  # noqa: E402


def _pool(robot_name: str, model_spec: str, N: int, seed: int):
    from casadical.data import sample_poses
    from casadical.loading import load_robot
    from casadical.model import Model
    from casadical.planning import design_problem

    robot = load_robot(robot_name)
    model = Model(robot, model_spec)
    t0 = time.perf_counter()
    q = sample_poses(robot, N, np.random.default_rng(seed))
    t1 = time.perf_counter()
    prob = design_problem(model, q)
    t2 = time.perf_counter()
    return prob, t1 - t0, t2 - t1


def _cvxpy_worker(path: str, m: int, queue) -> None:
    from casadical.planning import relax_cvxpy

    A = np.load(path)
    try:
        r = relax_cvxpy(A, m)
        queue.put({"method": r.method, "log_det": r.log_det, "upper_bound": r.upper_bound, "gap": r.gap_per_parameter,
                   "time_s": r.time_s, "status": r.status, "iterations": r.iterations,
                   "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024})
    except Exception as e:  # report, do not hang the parent
        queue.put({"error": f"{type(e).__name__}: {e}"})


def _run_cvxpy(A: np.ndarray, m: int, timeout: float) -> dict:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "A.npy")
        np.save(path, A)
        ctx = mp.get_context("spawn")
        q = ctx.Queue()
        proc = ctx.Process(target=_cvxpy_worker, args=(path, m, q))
        t0 = time.perf_counter()
        proc.start()
        proc.join(timeout)
        if proc.is_alive():
            proc.terminate()  # our own child, by its handle
            proc.join()
            return {"error": f"no answer within {timeout:g} s (stopped)",
                    "time_s": time.perf_counter() - t0}
        return q.get() if not q.empty() else {"error": f"worker exited with code {proc.exitcode}"}


def main() -> int:
    from casadical.planning import (
        RelaxationSettings,
        d_efficiency,
        relax_multiplicative,
        round_and_exchange,
        upper_bound,
    )

    args = ARGS
    rows = []
    for N in args.sizes:
        prob, t_sample, t_jac = _pool(args.robot, args.model, N, args.seed)
        A, p = prob.A, prob.n_parameters
        m = 2 * p
        row = {"N": N, "p": p, "M": m, "sample_s": t_sample, "jacobian_s": t_jac,
               "maxrss_after_jacobian_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
        tracemalloc.start()
        rel = relax_multiplicative(A, m, RelaxationSettings(tol=args.tol))
        ex = round_and_exchange(A, m, rel.weights)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        w = np.zeros(N)
        w[ex.indices] = 1.0
        ub = min(rel.upper_bound, upper_bound(A, m, w))
        row.update({"fo_time_s": rel.time_s, "fo_iterations": rel.iterations, "fo_gap": rel.gap_per_parameter,
                    "fo_log_det": rel.log_det, "fo_status": rel.status, "fo_support": rel.n_support,
                    "exchange_s": ex.time_s, "swaps": ex.swaps, "starts": ex.starts, "exact_log_det": ex.log_det,
                    "d_efficiency": d_efficiency(ex.log_det, ub, p),
                    "tracemalloc_peak_mb": peak / 2**20, "A_mb": A.nbytes / 2**20,
                    "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024})
        if N <= args.cvxpy_max:
            cv = _run_cvxpy(A, m, args.cvxpy_timeout)
            row["cvxpy"] = cv
            if "log_det" in cv:
                row["cvxpy_minus_fo_per_param"] = (cv["log_det"] - rel.log_det) / p
        else:
            row["cvxpy"] = {"skipped": f"N > --cvxpy-max {args.cvxpy_max}"}
        rows.append(row)
        print(json.dumps(row), flush=True)

    print()
    print("| candidates | p | M | Jacobian (s) | first-order time (s) | iterations | certified gap / param "
          "| cvxpy time (s) | cvxpy gap / param | cvxpy - FO log det / param | exact D-eff (M = 2p) "
          "| exchange (s), starts | tracemalloc peak (MB) | max RSS after Jacobian / after design (MB) |")
    print("|" + "---|" * 14)
    for r in rows:
        cv = r["cvxpy"]
        if "time_s" in cv and "log_det" in cv:
            ct = f"{cv['time_s']:.2f} ({cv['method'].split(':')[1]})"
            cg, cd = f"{cv['gap']:.1e}", f"{r['cvxpy_minus_fo_per_param']:+.1e}"
        else:
            ct, cg, cd = cv.get("error", cv.get("skipped", "-")), "-", "-"
        print(f"| {r['N']:,} | {r['p']} | {r['M']} | {r['jacobian_s']:.2f} | {r['fo_time_s']:.2f} "
              f"| {r['fo_iterations']} | {r['fo_gap']:.1e} | {ct} | {cg} | {cd} | {r['d_efficiency']:.4f} "
              f"| {r['exchange_s']:.2f}, {r['starts']} | {r['tracemalloc_peak_mb']:.0f} "
              f"| {r['maxrss_after_jacobian_mb']:.0f} / {r['maxrss_mb']:.0f} |")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
