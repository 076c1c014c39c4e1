"""The IPOPT solve of a kinematic + compliance calibration of 80 poses, and what it costs (issue 26 item 2).

YS100 ``kinematic+compliance`` on 80 simulated poses (the stiffnesses of ``bench_calibration.py``, 20 um
noise): the problem ``calibrate`` solves (free set after the identifiability analysis, scales, aligned base
pose), solved warm from nominal (the solver built, the model compiled). CPU time, median of ``--repeats``:

- casadical IPOPT, with the time of each of its callbacks from CasADi's statistics (objective, gradient,
  Gauss-Newton Hessian) and the rest (IPOPT itself): the model as ``calibrate`` evaluates it (compiled:
  ``jit=True``), and on CasADi's VM (``jit=False``, no compiler);
- casadical ``auto`` (Levenberg-Marquardt, IPOPT only if LM leaves the bounds) and LM;
- scipy ``least_squares`` on the same model (casadical's residuals, compiled): trf with its default 2-point
  Jacobian, trf with the model's exact Jacobian, MINPACK's lm with the 2-point Jacobian; and the ratio of
  each to casadical IPOPT's time.

``--base DIR`` runs the same script on the code of DIR (``PYTHONPATH``; default /work/base, fe55b8a)
after this tree, in turn (``--pairs`` times), and prints both tables. Under another CasADi, run it from a
venv with that version (``casadi==3.6.7``) and ``PYTHONPATH`` at the repository.

Usage::

    python benchmarks/speed/bench_ipopt.py
    python benchmarks/speed/bench_ipopt.py --base /work/base --pairs 2
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

EFFECTS = {2: 1.73e6, 3: 1.203e6, 4: 0.299e6, 5: 0.5724e6}


def cpu_median(fn, repeats: int):
    out = fn()
    ts = []
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        ts.append(time.process_time() - t0)
    return statistics.median(ts), out


def table(N: int, repeats: int) -> None:
    import casadi as ca
    from scipy.optimize import least_squares

    from casadical import load_robot
    from casadical.calibration import calibrate
    try:
        from casadical.calibration._solve import _solve
    except ImportError:     # before calibrate() became a pipeline (fe55b8a)
        from casadical.calibration import _solve
    from casadical.data import Effects, simulate
    from casadical.model import Model
    from casadical.problem import CalibrationProblem
    from casadical.solvers import make_solver

    warnings.simplefilter("ignore")
    robot = load_robot("ys100")
    data, _ = simulate(robot, N, Effects(stiffness=EFFECTS), seed=1)
    print(f"CasADi {ca.__version__}, load average {os.getloadavg()[0]:.2f}; YS100 kinematic+compliance, {N} poses, "
          f"CPU time, median of {repeats}\n")
    print("| method | CPU | iterations | objective / gradient / Hessian (calls, CPU) | rest | scipy / IPOPT | "
          "max abs dx vs IPOPT |")
    print("|---|---:|---:|---|---:|---:|---:|")
    ref = t_ip = None
    for label, jit in (("casadical IPOPT (the model compiled)", True), ("casadical IPOPT, CasADi's VM", False)):
        model = Model(robot, "kinematic+compliance", jit=jit)
        res = calibrate(robot, data, model, "lm", warn=False)
        prob = CalibrationProblem(model, res.parameters.copy(), data.q, data.xyz, model.covariates(data), res.base0)
        x0 = np.zeros(len(prob.free))
        s = make_solver("ipopt")
        t, r = cpu_median(lambda: s.solve(prob, x0), repeats)
        st = s._last.stats()
        if ref is None:
            ref, t_ip, compiled = r.x, t, prob
        parts = [(st[f"n_call_nlp_{k}"], st[f"t_proc_nlp_{k}"]) for k in ("f", "grad_f", "hess_l")]
        print(f"| {label} | {t * 1e3:.1f} ms | {r.iterations} | "
              + " / ".join(f"{n}, {c * 1e3:.1f} ms" for n, c in parts)
              + f" | {(t - sum(c for _, c in parts)) * 1e3:.1f} ms | | {np.abs(r.x - ref).max():.1e} |")
    prob = compiled
    for label, solver in (("casadical auto (LM, IPOPT if it leaves the bounds)", "auto"),
                          ("casadical Levenberg-Marquardt", "lm")):
        t, (r, name) = cpu_median(lambda: _solve(prob, x0, solver, {}), repeats)
        print(f"| {label} | {t * 1e3:.1f} ms | {r.iterations} ({name}) | | | | {np.abs(r.x - ref).max():.1e} |")

    def fun(x):
        return prob.residuals(prob.values_from_x(x))

    def jac(x):
        return prob.residuals_jacobian(prob.values_from_x(x))[1]

    for label, kw in (("scipy least_squares trf, 2-point Jacobian (its default)", {}),
                      ("scipy least_squares trf, the model's exact Jacobian", {"jac": jac}),
                      ("scipy least_squares lm (MINPACK), 2-point Jacobian", {"method": "lm"})):
        t, r = cpu_median(lambda: least_squares(fun, x0, **kw), max(3, repeats // 2))
        print(f"| {label} | {t * 1e3:.1f} ms | {r.nfev} evaluations | | | {t / t_ip:.1f} | "
              f"{np.abs(r.x - ref).max():.1e} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=80)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--base", help="also the code of this tree (PYTHONPATH), in turn")
    ap.add_argument("--pairs", type=int, default=1)
    ap.add_argument("--table", action="store_true", help=argparse.SUPPRESS)   # the child of --base
    args = ap.parse_args()
    if args.table or not args.base:
        table(args.poses, args.repeats)
        return 0
    here = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    for k in range(args.pairs):
        for label, tree in (("this tree", here), ("base", os.path.abspath(args.base))):
            print(f"\n## {label} ({tree}), pair {k + 1}\n", flush=True)
            subprocess.run([sys.executable, __file__, "--table", "--poses", str(args.poses), "--repeats",
                            str(args.repeats)], env=dict(os.environ, PYTHONPATH=tree), check=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
