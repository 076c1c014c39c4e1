"""One compiled superset model per robot and data kind (issue 26 item 1): the figures the design rests on.

The superset holds every term the diagnosis can try (the geometry, the
compliance, progressive stiffness, encoder scale and both backlash kinds of
every joint, thermal expansion (global and per link), a drift, the probe's
mounting for full pose) and one chain-angle input per joint: a periodic
error of any harmonic enters there as ``s sin(h q_j) + c cos(h q_j)``,
computed in numpy, and its columns are the Jacobian w.r.t. that input times
``sin`` and ``cos`` (exact: the offset is added to the chain angle and to
nothing else). A candidate model is then a mask of free parameters over it.

Reported, per robot and data kind (position; full pose):

- sizes: parameters, CasADi instructions of the functions evaluated
  (``fk``: positions; ``jac``: positions and their Jacobian w.r.t. the
  parameters and the chain inputs; full pose adds the orientation residual
  and its Jacobian), the compile time of each at -O1 (an empty cache), the
  load time from a warm cache;
- evaluation per pose, best CPU time of several repeats on one thread:
  today's per-candidate function on CasADi's virtual machine (the diagnosis
  keeps candidates uncompiled), the candidate compiled on its own (what a
  compile per candidate would buy, 1-10 s each), and the compiled superset
  with the candidate's columns picked out in numpy (the masked columns'
  overhead is the difference to the compiled candidate);
- Gauss-Newton matrices: per-pose matrices summed in compiled code (what
  IPOPT evaluates today) against the compiled superset's Jacobian and
  ``J^T W J`` over the free columns in numpy (what Levenberg-Marquardt does).

Usage::

    python benchmarks/bench_superset.py                      # UR10 and the 7-axis test arm, ~3 min cold
    python benchmarks/bench_superset.py --robots ur10 --poses 300

The superset here is a prototype built from the library's terms (the
design note: docs/speed.md); the engine replaces it.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from casadical import jitcache, load_robot  # noqa: E402
from casadical.model import Model, _Batch, parse_spec  # noqa: E402
from casadical.robot import robot_from_dict  # noqa: E402
from casadical.simulate import sample_poses  # noqa: E402
from casadical.terms import ErrorTerm  # noqa: E402

#: the README job's final parametric model, and two simpler ones
CANDIDATES = ["kinematic", "kinematic+compliance",
              "kinematic+joint_compliance[2]+joint_periodic[1:15,2:8,2:17,3:3,3:17,5:21]+encoder_scale[2]"]


class ChainInput(ErrorTerm):
    """Prototype: one per-pose input added to each chain angle (covariates ``dq1..dqn``)."""

    name = "chain_input"

    def __init__(self, n: int):
        super().__init__(None)
        self.n = n

    @property
    def covariates(self):
        return tuple(f"dq{j}" for j in range(1, self.n + 1))

    def spec(self) -> str:
        return self.name

    def joint_offsets(self, ctx):
        return {j: ctx.cov[f"dq{j}"] for j in range(1, self.n + 1)}


def superset(robot, full_pose: bool) -> Model:
    links = [j for j, jt in enumerate(robot.joints, 1) if abs(jt.a) + abs(jt.d) + abs(jt.b or 0) > 0]
    spec = ("kinematic+compliance+nonlinear_stiffness+encoder_scale+backlash+backlash_motion+thermal+thermal["
            + ",".join(map(str, links)) + "]+drift" + ("+tool_orientation" if full_pose else ""))
    return Model(robot, parse_spec(spec) + [ChainInput(robot.n)], jit=False)


def orientation_residual(probe, Rm):
    E = ca.mtimes(ca.reshape(Rm, 3, 3), probe)
    return 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])


def superset_functions(m: Model, full_pose: bool) -> dict:
    S = m._sym
    q, p, c, b0 = S["q"], S["p"], S["c"], S["b0"]
    dq = ca.vertcat(*[c[m.covariate_names.index(f"dq{j}")] for j in range(1, m.robot.n + 1)])
    ins = [q, p, c, b0]
    y = S["xyz"]
    if full_pose:
        Rm = ca.SX.sym("Rm", 9)
        ins.append(Rm)
        y = ca.vertcat(y, orientation_residual(S["probe"], Rm))
    kind = "pose_" if full_pose else ""
    # one Jacobian w.r.t. the parameters and the chain inputs together (fewer instructions than apart)
    return {kind + "fk": ca.Function(f"sup_{kind}fk", ins, [y]),
            kind + "jac": ca.Function(f"sup_{kind}jac", ins, [y, ca.densify(ca.jacobian(y, ca.vertcat(p, dq)))])}


def batch(f: ca.Function, N: int, bcast=(1, 3), reduce=()) -> _Batch:
    return _Batch(f.map("m", "serial", N, list(bcast), list(reduce)), N)


def best_cpu(fn, repeats: int) -> float:
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def compiled(f: ca.Function) -> tuple[ca.Function, float, float]:
    """Compile into an empty cache (-O1) and time it; then time a load from the warm cache."""
    t0 = time.perf_counter()
    fc = jitcache.load(f)
    t_compile = time.perf_counter() - t0
    t0 = time.perf_counter()
    jitcache.load(f, compile=False)
    return fc, t_compile, time.perf_counter() - t0


def robots(names):
    import arms
    for n in names:
        yield robot_from_dict(arms.ARMS[n], n) if n in arms.ARMS else load_robot(n)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="+", default=["ur10", "arm7"])
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    os.environ["CASADICAL_CACHE"] = tempfile.mkdtemp(prefix="bench-superset-")
    N = args.poses
    print(f"CasADi {ca.__version__}, numpy {np.__version__}, gcc {jitcache.FLAGS}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f}; {N:,} poses, best CPU of {args.repeats}")
    for robot in robots(args.robots):
        rng = np.random.default_rng(0)
        q = sample_poses(robot, N, rng, floor_z=None)
        Rm = np.tile(np.eye(3).ravel(), (N, 1))
        for full_pose in (False, True):
            kind = "full pose" if full_pose else "position"
            t0 = time.perf_counter()
            sup = superset(robot, full_pose)
            funs = superset_functions(sup, full_pose)
            t_build = time.perf_counter() - t0
            P = len(sup.parameters)
            print(f"\n### {robot.name} ({robot.n} joints), {kind}: superset of {P} parameters, "
                  f"{len(sup.covariate_names)} covariates ({robot.n} chain inputs); graphs built in {t_build:.2f} s\n")
            print("| function | instructions | compile -O1 | load (warm cache) | VM per pose | compiled per pose |")
            print("|---|---:|---:|---:|---:|---:|")
            sargs = [q, sup.parameters.values, sup.default_covariates(N), sup.base0_nominal()] + ([Rm] if full_pose
                                                                                                  else [])
            comp = {}
            for name, f in funs.items():
                fc, tc, tl = compiled(f)
                comp[name] = fc
                vm = best_cpu(lambda: batch(f, N)(*sargs), 3) / N
                cc = best_cpu(lambda b=batch(fc, N): b.evaluate(*sargs), args.repeats) / N
                print(f"| {name} | {f.n_instructions():,} | {tc:.2f} s | {tl * 1e3:.1f} ms | {vm * 1e6:.1f} us | "
                      f"{cc * 1e6:.2f} us |")
            jac = comp[("pose_" if full_pose else "") + "jac"]
            sb = batch(jac, N)
            print(f"\nCandidates, positions{' and orientations' if full_pose else ''} and their Jacobian, per pose "
                  "(superset: its evaluation, then the candidate's columns picked out and the periodic columns "
                  "made in numpy):\n")
            print("| candidate | parameters | today: own function, VM | own function compiled (compile) | "
                  "compiled superset | superset / own compiled |")
            print("|---|---:|---:|---:|---:|---:|")
            for spec in CANDIDATES:
                m = Model(robot, spec + ("+tool_orientation" if full_pose else ""), jit=False)
                which = "pose_fk_jac" if full_pose else "fk_jac"
                ins, outs, _, _ = m._graph(which)
                own = ca.Function(which, ins, outs)
                cargs = [q, m.parameters.values, m.default_covariates(N), m.base0_nominal()] + (
                    [Rm] if full_pose else [])
                vm = best_cpu(lambda: batch(own, N)(*cargs), 3) / N
                ownc, tc, _ = compiled(own)
                oc = best_cpu(lambda b=batch(ownc, N): b.evaluate(*cargs), args.repeats) / N
                idx = [sup.parameters.index(n) for n in m.parameters.names if n in sup.parameters]
                per = m.term("joint_periodic")
                harm = per.harmonics if per is not None else []
                ny = 6 if full_pose else 3

                def via_superset():
                    dq = np.zeros((N, robot.n))
                    cov = sup.default_covariates(N)
                    for j, h in harm:
                        dq[:, j - 1] += 1e-5 * (np.sin(h * q[:, j - 1]) + np.cos(h * q[:, j - 1]))
                    cov[:, -robot.n:] = dq
                    sb.evaluate(q, sup.parameters.values, cov, sup.base0_nominal(), *([Rm] if full_pose else []))
                    J = sb.res[1].reshape(N, P + robot.n, ny)
                    cols = [J[:, idx, :]]
                    for j, h in harm:
                        JA = J[:, P + j - 1, :]
                        cols.append(np.stack([JA * np.sin(h * q[:, j - 1])[:, None],
                                              JA * np.cos(h * q[:, j - 1])[:, None]], axis=1))
                    return np.concatenate(cols, axis=1)

                sc = best_cpu(via_superset, args.repeats) / N
                print(f"| {spec + (' + tool_orientation' if full_pose else '')} | {len(m.parameters)} | "
                      f"{vm * 1e6:.1f} us | {oc * 1e6:.2f} us ({tc:.1f} s) | {sc * 1e6:.2f} us | {sc / oc:.2f} |")
            # Gauss-Newton matrices: per pose in compiled code (IPOPT today) vs J^T W J in numpy
            m = Model(robot, CANDIDATES[1] + ("+tool_orientation" if full_pose else ""), jit=False)
            gn = "pose_gn_hess" if full_pose else "gn_hess"
            ins, outs, bc, red = m._graph(gn)
            ownc, tc, _ = compiled(ca.Function(gn, ins, outs))
            gargs = [q, m.parameters.values, m.default_covariates(N), m.base0_nominal(), np.zeros((N, 3))] + (
                [Rm, 0.0, 1.0] if full_pose else [0.0])
            gb = batch(ownc, N, bc, red)
            t_gn = best_cpu(lambda: gb.evaluate(*gargs), args.repeats) / N
            free = [sup.parameters.index(n) for n in m.parameters.names]
            w = np.ones(N)

            def jtj():
                sb.evaluate(*sargs)
                J = sb.res[1].reshape(N, P + robot.n, -1)[:, free, :]
                Jw = (J * np.sqrt(w)[:, None, None]).transpose(0, 2, 1).reshape(-1, len(free))
                return Jw.T @ Jw

            t_jtj = best_cpu(jtj, args.repeats) / N
            print(f"\nGauss-Newton matrix of {m.spec} ({len(free)} columns), per pose: per-pose matrices summed in "
                  f"compiled code {t_gn * 1e6:.2f} us (compile {tc:.1f} s); compiled superset Jacobian + J^T W J in "
                  f"numpy {t_jtj * 1e6:.2f} us")
    print(f"\nload average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
