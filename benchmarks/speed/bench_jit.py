"""JIT compile path: casadical's own compile (C from CasADi, compiler run as a child process that
Ctrl-C stops, result kept in the disk cache) against CasADi's built-in JIT (the baseline, compiler run
through system()), same run.

    python benchmarks/speed/bench_jit.py                 # YS100 kinematic+compliance, 2,000 poses

Rows: the VM; CasADi's JIT (-O2, the options casadical used before); casadical with an empty cache
(compiles, -O1, and stores); casadical with the entry in the cache (loads it). Target: the same
evaluation speed, no slower compile than the built-in JIT, and a cached load in milliseconds.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import casadi as ca
import numpy as np

from casadical import load_robot
from casadical.model import Model
from casadical.model import _jitcache as jitcache


def builtin_jit(fun: ca.Function, name: str, folder: str) -> ca.Function:
    """CasADi's own JIT with the options casadical used before."""
    ins = [ca.SX.sym(fun.name_in(i), fun.sparsity_in(i)) for i in range(fun.n_in())]
    opts = {"jit": True, "compiler": "shell", "jit_cleanup": False, "jit_name": name,
            "jit_options": {"flags": ["-O2"], "verbose": False, "directory": folder + os.sep, "cleanup": False}}
    return ca.Function(fun.name(), ins, fun.call(ins), opts)


def evaluate(fun: ca.Function, model: Model, N: int, repeat: int) -> float:
    q = np.random.default_rng(0).uniform(-1, 1, (N, model.robot.n))
    F = fun.map("m", "serial", N, [1, 3], [])
    args = (q.T, model.parameters.values, model.default_covariates(N).T, model.base0_nominal(),
            np.zeros((3, N)), 0.0)[:fun.n_in()]   # measured points and delta, for the least-squares functions
    F(*args)
    best = float("inf")
    for _ in range(repeat):   # the best CPU time of several: other processes share the cores
        t0 = time.process_time()
        F(*args)
        best = min(best, time.process_time() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    model = Model(load_robot("ys100"), "kinematic+compliance", jit=False)
    print(f"load average {os.getloadavg()[0]:.2f}; YS100 {model.spec}, {args.poses} poses")
    print(f"{'function':>9} {'path':>22} {'compile s':>10} {'eval ms (best CPU)':>19}")
    with tempfile.TemporaryDirectory() as folder:
        os.environ["CASADICAL_CACHE"] = os.path.join(folder, "cache")   # empty: the first load compiles
        for which in ("fk", "fk_jac", "cost"):
            vm = model.per_pose_function(which, False)
            for label, make in (("VM (no compile)", lambda: vm),
                                ("CasADi JIT (baseline)", lambda: builtin_jit(vm, f"base_{which}", folder)),
                                ("casadical, cold cache", lambda: jitcache.load(vm)),
                                ("casadical, warm cache", lambda: jitcache.load(vm, compile=False))):
                t0 = time.perf_counter()
                fun = make()
                t_compile = time.perf_counter() - t0
                t_eval = evaluate(fun, model, args.poses, args.repeat)
                print(f"{which:>9} {label:>22} {t_compile:10.2f} {t_eval * 1000:19.1f}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
