"""The IPOPT solve of a kinematic + compliance calibration of 80 poses, and what it costs (issue 26 item 2).

YS100 ``kinematic+compliance`` on 80 simulated poses (the stiffnesses of
``bench_calibration.py``, 20 um noise): the problem ``calibrate`` solves
(free set after the identifiability analysis, scales, aligned base pose),
solved warm from nominal (the solver built). Rows, CPU time (median of
``--repeats``):

- casadical IPOPT as it stands, with the time of each callback from
  CasADi's statistics (objective, gradient, Gauss-Newton Hessian) and the
  rest (IPOPT itself); with the model's functions on CasADi's VM (80 poses
  are below ``JIT_MIN_POSES``) and compiled;
- IPOPT with callbacks on the problem's linearisation (``--prototype``);
- casadical Levenberg-Marquardt;
- scipy ``least_squares`` on the same model (casadical's residuals): trf
  with its default 2-point Jacobian, trf with the model's exact Jacobian,
  and MINPACK's lm with the 2-point Jacobian.

Run it under another CasADi (a venv with ``casadi==3.6.7`` and
``PYTHONPATH`` at the repository) for the version column of docs/speed.md.

Usage::

    python benchmarks/bench_ipopt.py --prototype
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from casadical import load_robot  # noqa: E402
from casadical.calibration import calibrate  # noqa: E402
from casadical.model import Model  # noqa: E402
from casadical.problem import CalibrationProblem  # noqa: E402
from casadical.simulate import Effects, simulate  # noqa: E402
from casadical.solvers import make_solver  # noqa: E402
from casadical.solvers import ipopt as ipopt_mod  # noqa: E402

EFFECTS = Effects(stiffness={2: 1.73e6, 3: 1.203e6, 4: 0.299e6, 5: 0.5724e6})


def cpu_median(fn, repeats: int):
    out = fn()
    ts = []
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        ts.append(time.process_time() - t0)
    return statistics.median(ts), out


class _Linearization:
    """The problem linearised at the last IPOPT iterate (shared by the gradient and the Hessian)."""

    def __init__(self, prob):
        self.prob, self.x, self.lin = prob, None, None

    def at(self, x):
        if self.x is None or not np.array_equal(x, self.x):
            self.x, self.lin = x.copy(), self.prob.linearize(self.prob.values_from_x(x))
        return self.lin

    def cost(self, x):
        if self.x is not None and np.array_equal(x, self.x):
            return self.lin.cost
        r = self.prob.residuals(self.prob.values_from_x(x)).reshape(-1, 3)
        return float(self.prob.loss.rho(np.einsum("ij,ij->i", r, r)).sum())


class _Callback(ca.Callback):
    def __init__(self, name, lin, nf, kind):
        ca.Callback.__init__(self)
        self.lin, self.nf, self.kind = lin, nf, kind
        self.construct(name, {"enable_fd": False})

    def get_n_in(self):
        return 2 if self.kind == "h" else 1

    def get_n_out(self):
        return 2 if self.kind == "g" else 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.nf) if i == 0 else ca.Sparsity.dense(1)

    def get_sparsity_out(self, i):
        if self.kind == "h":
            return ca.Sparsity.upper(self.nf)
        return ca.Sparsity.dense(self.nf) if (self.kind == "g" and i == 1) else ca.Sparsity.dense(1)

    def eval(self, arg):
        x = np.asarray(arg[0]).ravel()
        if self.kind == "f":
            return [self.lin.cost(x)]
        lin = self.lin.at(x)
        if self.kind == "g":
            return [lin.cost, lin.g]
        return [ca.triu(ca.DM(float(arg[1]) * lin.A))]


def prototype_ipopt(prob, N):
    """IPOPT with the objective, gradient and Gauss-Newton Hessian from ``prob.linearize`` (the design's)."""
    L, nf = _Linearization(prob), len(prob.free)
    cbs = [_Callback(k, L, nf, k) for k in "fgh"]
    x, p = ca.MX.sym("x", nf), ca.MX.sym("p", 0)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", 0)
    tol = 1e-8
    opts = {"print_time": False, "no_nlp_grad": True,
            "grad_f": ca.Function("nlp_grad_f", [x, p], list(cbs[1](x)), ["x", "p"], ["f", "grad_f_x"]),
            "hess_lag": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [cbs[2](x, lam_f)],
                                    ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]),
            "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 200, "tol": tol * N,
                      "acceptable_tol": ipopt_mod.ACCEPTABLE_TOL * N, "compl_inf_tol": tol / ipopt_mod.OBJ_SCALE,
                      "acceptable_compl_inf_tol": ipopt_mod.ACCEPTABLE_TOL / ipopt_mod.OBJ_SCALE,
                      "barrier_tol_factor": ipopt_mod.BARRIER_TOL_FACTOR * N, "tiny_step_tol": ipopt_mod.TINY_STEP,
                      "acceptable_iter": ipopt_mod.ACCEPTABLE_ITER, "obj_scaling_factor": ipopt_mod.OBJ_SCALE}}
    solver = ca.nlpsol("prototype", "ipopt", {"x": x, "f": cbs[0](x)}, opts)
    lbx, ubx = prob.bounds_x()

    def solve():   # (holds the callbacks: CasADi keeps no reference to them)
        L.x, _ = None, cbs
        sol = solver(x0=np.zeros(nf), lbx=lbx, ubx=ubx)
        return np.array(sol["x"]).ravel(), solver.stats()
    return solve


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=80)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--prototype", action="store_true", help="also IPOPT with callbacks on the linearisation")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    robot = load_robot("ys100")
    N = args.poses
    data, _ = simulate(robot, N, EFFECTS, seed=1)
    print(f"CasADi {ca.__version__}, load average {os.getloadavg()[0]:.2f}; YS100 kinematic+compliance, {N} poses, "
          f"CPU time, median of {args.repeats}\n")
    print("| method | CPU | iterations | objective / gradient / Hessian (calls, CPU) | rest | max |dx| vs IPOPT |")
    print("|---|---:|---:|---|---:|---:|")
    ref = None
    for label, jit in (("casadical IPOPT, VM (as below 100 poses)", False), ("casadical IPOPT, compiled", True)):
        model = Model(robot, "kinematic+compliance", jit=jit)
        res = calibrate(robot, data, model, "lm", warn=False)
        prob = CalibrationProblem(model, res.parameters.copy(), data.q, data.xyz, model.covariates(data), res.base0)
        x0 = np.zeros(len(prob.free))
        s = make_solver("ipopt")
        t, r = cpu_median(lambda: s.solve(prob, x0), args.repeats)
        st = s._last.stats()
        ref = r.x if ref is None else ref
        parts = [(st[f"n_call_nlp_{k}"], st[f"t_proc_nlp_{k}"]) for k in ("f", "grad_f", "hess_l")]
        print(f"| {label} | {t * 1e3:.1f} ms | {r.iterations} | "
              + " / ".join(f"{n}, {c * 1e3:.1f} ms" for n, c in parts)
              + f" | {(t - sum(c for _, c in parts)) * 1e3:.1f} ms | {np.abs(r.x - ref).max():.1e} |")
    if args.prototype:
        t, (x, st) = cpu_median(prototype_ipopt(prob, N), args.repeats)
        parts = [(st[f"n_call_nlp_{k}"], st[f"t_proc_nlp_{k}"]) for k in ("f", "grad_f", "hess_l")]
        print(f"| IPOPT, callbacks on the linearisation (compiled model) | {t * 1e3:.1f} ms | {st['iter_count']} | "
              + " / ".join(f"{n}, {c * 1e3:.1f} ms" for n, c in parts)
              + f" | {(t - sum(c for _, c in parts)) * 1e3:.1f} ms | {np.abs(x - ref).max():.1e} |")
    lm = make_solver("lm")
    t, r = cpu_median(lambda: lm.solve(prob, x0), args.repeats)
    print(f"| casadical LM | {t * 1e3:.1f} ms | {r.iterations} | | | {np.abs(r.x - ref).max():.1e} |")

    def fun(x):
        return prob.residuals(prob.values_from_x(x))

    def jac(x):
        return prob.residuals_jacobian(prob.values_from_x(x))[1]

    for label, kw in (("scipy least_squares trf, 2-point Jacobian", {}),
                      ("scipy least_squares trf, the model's Jacobian", {"jac": jac}),
                      ("scipy least_squares lm, 2-point Jacobian", {"method": "lm"})):
        t, r = cpu_median(lambda: least_squares(fun, x0, **kw), max(3, args.repeats // 2))
        print(f"| {label} | {t * 1e3:.1f} ms | {r.nfev} evaluations | | | {np.abs(r.x - ref).max():.1e} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
