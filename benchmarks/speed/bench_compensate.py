"""Benchmark: corrected joint targets, casadical's batched solver against per-row solvers.

YS100 ``kinematic+compliance`` calibrated on 100 simulated poses (random
geometric errors, stiffness k2, k3, tracker frame rotated and moved). The
program: N random poses ``q0`` and the tool points the nominal model gives
there, in the tracker frame. Every method solves the same 6 equations per
row (calibrated tool point = target, flange orientation = the nominal one at
``q0``) from ``q0``, on the same CasADi model:

- casadical ``compensate``: all rows at once, batched Levenberg-Marquardt
  with the exact joint Jacobians (``Model.predict_q_jacobian``,
  ``Model.flange_rotation_jacobian``); CasADi's virtual machine (VM) and
  compiled (JIT, the default from 300 rows when gcc is present);
- ``scipy.optimize.least_squares`` per row (``trf`` with the joint limits as
  bounds, and ``lm``), residual and exact Jacobian from one CasADi Function
  per row (VM; the orientation as ``vee(Rg^T R - R^T Rg) / 2``, same zeros);
- IPOPT per row (one ``nlpsol`` built once, the target a parameter, joint
  limits as bounds), minimising half the squared residual.

Reported: wall time of the first call (with JIT compilation) and the warm
time (median of repeats), rows per second, the largest position residual
and the largest joint difference to casadical's answer. The per-row
baselines run on the first ``--baseline-rows`` rows of each N (their time
per row does not depend on N) and their rate is extrapolated to say so.

Usage::

    python benchmarks/speed/bench_compensate.py              # N = 1,000 and 10,000 (~2 min)
    python benchmarks/speed/bench_compensate.py --sizes 1000 --baseline-rows 200 --json out.json
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import scipy  # noqa: E402
from bench_model import cpu_model  # noqa: E402  (this folder is on sys.path when run as a script)
from scipy.optimize import least_squares  # noqa: E402

from casadical import Measurements, Model, calibrate, load_robot  # noqa: E402
from casadical.apply import compensate  # noqa: E402
from casadical.data import Effects, sample_poses, simulate  # noqa: E402
from casadical.model import compiler_available  # noqa: E402

SPEC = "kinematic+compliance"
EFFECTS = Effects(stiffness={2: 1.73e6, 3: 1.2e6}, base_xyz=(2.0, -0.5, 0.3), base_rpy=(0.01, -0.02, 1.2))


def fmt_t(s: float) -> str:
    return f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s"


def timed(f, repeats: int) -> tuple[float, float, object]:
    """First call, median of ``repeats`` warm calls, and the last result."""
    t0 = time.perf_counter()
    out = f()
    first = time.perf_counter() - t0
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = f()
        ts.append(time.perf_counter() - t0)
    return first, statistics.median(ts) if ts else first, out


class PerRow:
    """The equations of one row as a CasADi Function of (q, target, R_goal), for per-row solvers."""

    def __init__(self, cal):
        model = cal.model
        n = model.robot.n
        # CasADi's virtual machine: IPOPT's exact Hessian of compiled calls would compile their
        # derivatives too, and the per-row time is Python's anyway
        fk = model.per_pose_function("fk")
        flange = model.per_pose_function("flange")
        q, target, rg = ca.MX.sym("q", n), ca.MX.sym("target", 3), ca.MX.sym("Rg", 3, 3)
        p, b0 = ca.DM(cal.parameters.values), ca.DM(cal.base0)
        cov = ca.DM(model.default_covariates(1).ravel())
        E = ca.mtimes(rg.T, flange(q, p, cov, b0))
        r = ca.vertcat(fk(q, p, cov, b0) - target, 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0],
                                                                     E[1, 0] - E[0, 1]))
        self.f = ca.Function("row", [q, target, rg], [r, ca.jacobian(r, q)])
        nlp = {"x": q, "p": ca.vertcat(target, ca.vec(rg)), "f": 0.5 * ca.dot(r, r)}
        self.ipopt = ca.nlpsol("row_ipopt", "ipopt", nlp, {
            "ipopt.print_level": 0, "print_time": False, "ipopt.tol": 1e-14, "ipopt.acceptable_tol": 1e-12,
            "ipopt.hessian_approximation": "exact"})
        self.limits = model.robot.limits

    def scipy(self, q0, target, Rg, method):
        def fun(q):
            return np.asarray(self.f(q, target, Rg)[0]).ravel()

        def jac(q):
            return np.asarray(self.f(q, target, Rg)[1])

        kw = {"bounds": (self.limits[:, 0], self.limits[:, 1])} if method == "trf" else {}
        return least_squares(fun, q0, jac=jac, method=method, xtol=1e-15, ftol=1e-15, gtol=1e-15,
                             max_nfev=200, **kw).x

    def nlp(self, q0, target, Rg):
        sol = self.ipopt(x0=q0, p=np.concatenate([target, Rg.T.ravel()]), lbx=self.limits[:, 0],
                         ubx=self.limits[:, 1])
        return np.asarray(sol["x"]).ravel()


def baseline(rows: PerRow, targets: Measurements, R_goal: np.ndarray, which: str) -> np.ndarray:
    q0, goal = targets.q, targets.xyz
    out = np.empty_like(q0)
    for i in range(len(q0)):
        if which == "ipopt":
            out[i] = rows.nlp(q0[i], goal[i], R_goal[i])
        else:
            out[i] = rows.scipy(q0[i], goal[i], R_goal[i], which)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000], help="numbers of targets")
    ap.add_argument("--baseline-rows", type=int, default=1000, help="rows each per-row baseline solves")
    ap.add_argument("--repeats", type=int, default=3, help="warm repeats of the batched solver")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    robot = load_robot("ys100")
    jit = compiler_available()
    info: dict = {"cpu": cpu_model(), "cores": os.cpu_count(), "python": platform.python_version(),
                  "numpy": np.__version__, "scipy": scipy.__version__, "casadi": ca.__version__,
                  "jit_available": jit, "rows": []}
    print(f"machine: {info['cpu']}, {info['cores']} cores; Python {info['python']}, numpy {info['numpy']}, "
          f"scipy {info['scipy']}, CasADi {info['casadi']}, JIT {'on' if jit else 'off'}; "
          f"load average {os.getloadavg()[0]:.2f} at start")
    data, truth = simulate(robot, 100, EFFECTS, seed=args.seed)
    cal = calibrate(robot, data, SPEC, "lm", warn=False)
    nominal = cal.parameters.nominal
    base = [k for k, prm in enumerate(cal.parameters) if prm.group == "base"]
    nominal[base] = cal.parameters.values[base]
    rows = PerRow(cal)
    rng = np.random.default_rng(args.seed + 1)
    print(f"{robot.name} {cal.model.spec}, calibrated on 100 simulated poses; orientation held (6 equations "
          "per row)\n")
    head = ["targets", "method", "rows solved", "first call", "warm", "rows/s", "max residual",
            "rows with |q - casadical| > 1e-6 deg (max)", "load"]
    print("| " + " | ".join(head) + " |")
    print("|" + "|".join("---" if i < 2 else "---:" for i in range(len(head))) + "|")
    for N in args.sizes:
        q0 = sample_poses(robot, N, rng)
        targets = Measurements.from_arrays(q0, Model(robot, "nominal").predict(q0, base0=truth.base0))
        R_goal = cal.model.flange_rotation(q0, nominal, None, cal.base0)
        results = {}
        for mode in (["VM", "JIT"] if jit else ["VM"]):
            cal.model.jit = mode == "JIT"
            cal.model._maps.clear()
            first, warm, res = timed(lambda: compensate(cal, targets, check=False), args.repeats)
            results[mode] = (N, first, warm, res.q, res.residual)
        cal.model.jit = None
        ref = results["JIT" if jit else "VM"][3]
        m = min(N, args.baseline_rows)
        sub = targets.subset(np.arange(m))
        for which, label in (("trf", "scipy least_squares trf (bounds), per row"),
                             ("lm", "scipy least_squares lm, per row"), ("ipopt", "IPOPT (bounds), per row")):
            t0 = time.perf_counter()
            q = baseline(rows, sub, R_goal[:m], which)
            t = time.perf_counter() - t0
            xyz = cal.predict(Measurements.from_arrays(q))
            results[label] = (m, t, t, q, np.linalg.norm(xyz - sub.xyz, axis=1))
        for label, (m, first, warm, q, resid) in results.items():
            name = f"casadical compensate ({label})" if label in ("VM", "JIT") else label
            diff = np.degrees(np.abs(q - ref[:m])).max(axis=1)
            load = os.getloadavg()[0]
            print(f"| {N:,} | {name} | {m:,} | {fmt_t(first)} | {fmt_t(warm)} | {m / warm:,.0f} | "
                  f"{resid.max() * 1e3:.1e} mm | {int((diff > 1e-6).sum())} ({diff.max():.1e} deg) | {load:.2f} |",
                  flush=True)
            info["rows"].append({"targets": N, "method": name, "rows_solved": m, "first_s": first, "warm_s": warm,
                                 "rows_per_s": m / warm, "max_residual_mm": resid.max() * 1e3,
                                 "max_diff_deg": diff.max(), "rows_differing": int((diff > 1e-6).sum()),
                                 "load": load})
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(info, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
