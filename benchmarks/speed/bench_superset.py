"""One compiled superset model per robot and data kind (issue 26 item 1): sizes, compile times, evaluation.

The superset (``casadical/model/_superset.py``, docs/speed.md) holds every term a model of the robot may have and
a chain-angle offset per pose; every model the diagnosis tries is a mask of it. Reported, per robot and data
kind (position; full pose):

- sizes: parameters, CasADi instructions of its two functions (``fk``: the measured quantities; ``jac``:
  them and their Jacobian w.r.t. the parameters and the chain offsets; full pose adds the orientation
  residual), the compile time of the pair at -O1 on an empty cache (the two compilers side by side), the
  load time from the warm cache, and the evaluation per pose on CasADi's VM and compiled;
- per candidate model, positions (and orientations) and their Jacobian per pose, best CPU time of several
  repeats: today's per-candidate function on the VM (what the diagnosis evaluated before: it kept every
  candidate uncompiled), the candidate compiled on its own (what a compile per candidate would buy, at its
  compile time), and the candidate through the compiled superset (``Model.predict_jacobian`` /
  ``pose_jacobian``: the superset's evaluation, the candidate's columns picked out and the periodic
  columns made in numpy); their ratio is the masked columns' overhead;

Usage::

    python benchmarks/speed/bench_superset.py                      # UR10 and the 7-axis test arm, ~3 min
    python benchmarks/speed/bench_superset.py --robots ur10 --poses 300
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
sys.path.append(str(HERE.parents[1]))  # the tests' helpers as ``tests.helpers``, after any casadical on PYTHONPATH

from casadical import load_robot  # noqa: E402
from casadical.data import sample_poses  # noqa: E402
from casadical.model import (
    Batch,  # noqa: E402
    Model,  # noqa: E402
    superset_for,  # noqa: E402
)
from casadical.model import (
    _jitcache as jitcache,
)
from casadical.robot import robot_from_dict  # noqa: E402

#: two simple candidates and the README job's final parametric model
CANDIDATES = ["kinematic", "kinematic+compliance",
              "kinematic+joint_compliance[2]+joint_periodic[1:15,2:8,2:17,3:3,3:17,5:21]+encoder_scale[2]"]


def batch(f: ca.Function, N: int, bcast=(1, 3), reduce=()) -> Batch:
    return Batch(f.map(f"m{N}", "serial", N, list(bcast), list(reduce)), N)


def best_cpu(fn, repeats: int) -> float:
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def robots(names):
    from tests.helpers import arms
    for n in names:
        yield robot_from_dict(arms.ARMS[n], n) if n in arms.ARMS else load_robot(n)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="+", default=["ur10", "arm7"])
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    os.environ["CASADICAL_CACHE"] = tempfile.mkdtemp(prefix="bench-superset-")
    os.environ["CASADICAL_JIT"] = "1"
    N = args.poses
    print(f"CasADi {ca.__version__}, numpy {np.__version__}, gcc {' '.join(jitcache.FLAGS)}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f}; {N:,} poses, best CPU of {args.repeats}")
    for robot in robots(args.robots):
        rng = np.random.default_rng(0)
        q = sample_poses(robot, N, rng, floor_z=None)
        R = np.tile(np.eye(3), (N, 1, 1))
        sup = superset_for(lambda terms: Model(robot, terms, jit=False), robot)
        P = len(sup.graph.parameters)
        for kind in ("", "pose_"):
            label = "full pose" if kind else "position"
            names = [kind + "fk", kind + "jac"]
            t0 = time.perf_counter()
            vm = [sup.function(w) for w in names]
            t_graph = time.perf_counter() - t0
            t0 = time.perf_counter()
            compiled = jitcache.load_all(vm)
            t_compile = time.perf_counter() - t0
            t0 = time.perf_counter()
            jitcache.load_all(vm, compile=False)
            t_load = time.perf_counter() - t0
            print(f"\n### {robot.name} ({robot.n} joints), {label}: superset of {P} parameters, "
                  f"{len(sup.graph.covariate_names)} covariates ({robot.n} chain offsets); graphs {t_graph:.2f} s, "
                  f"the pair compiled side by side in {t_compile:.2f} s (-O1, empty cache), loaded from the cache in "
                  f"{t_load * 1e3:.0f} ms\n")
            print("| function | instructions | VM per pose | compiled per pose |")
            print("|---|---:|---:|---:|")
            sargs = [q, sup.graph.parameters.values, sup.graph.default_covariates(N), sup.graph.base0_nominal()] + (
                [R.reshape(N, 9)] if kind else [])
            for w, f, fc in zip(names, vm, compiled):
                t_vm = best_cpu(lambda: batch(f, N)(*sargs), 3) / N
                t_c = best_cpu(lambda b=batch(fc, N): b.evaluate(*sargs), args.repeats) / N
                print(f"| {w} | {f.n_instructions():,} | {t_vm * 1e6:.1f} us | {t_c * 1e6:.2f} us |")
            print(f"\nCandidates: positions{' and orientations' if kind else ''} and their Jacobian, per pose:\n")
            print("| candidate | parameters | today: own function, VM | own function compiled (its compile) | "
                  "through the compiled superset | superset / own compiled |")
            print("|---|---:|---:|---:|---:|---:|")
            for spec in CANDIDATES:
                full = spec + ("+tool_orientation" if kind else "")
                own, engine = Model(robot, full, jit=False), Model(robot, full, jit=True)
                which = "pose_fk_jac" if kind else "fk_jac"
                ins, outs, _, _ = own._graph(which)
                f = ca.Function(which, ins, outs)
                values = own.parameters.values
                cargs = [q, values, own.default_covariates(N), own.base0_nominal()] + ([R.reshape(N, 9)] if kind
                                                                                         else [])
                t_vm = best_cpu(lambda: batch(f, N)(*cargs), 3) / N
                t0 = time.perf_counter()
                fc = jitcache.load(f)
                t_own = time.perf_counter() - t0
                t_oc = best_cpu(lambda b=batch(fc, N): b.evaluate(*cargs), args.repeats) / N
                if kind:
                    t_sup = best_cpu(lambda: engine.pose_jacobian(q, R, values), args.repeats) / N
                else:
                    t_sup = best_cpu(lambda: engine.predict_jacobian(q, values), args.repeats) / N
                print(f"| {full} | {len(own.parameters)} | {t_vm * 1e6:.1f} us | {t_oc * 1e6:.2f} us ({t_own:.1f} s) "
                      f"| {t_sup * 1e6:.2f} us | {t_sup / t_oc:.2f} |")
    print(f"\nload average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
