"""JIT compile path: casadical's own compile (C from CasADi, compiler run as a child process that
Ctrl-C stops) against CasADi's built-in JIT (the baseline, compiler run through system()), same run.

    python benchmarks/bench_jit.py                 # YS100 kinematic+compliance, 2,000 poses

Target: the same evaluation speed and no slower compile than the built-in
JIT (the change is for Ctrl-C, not for speed); the VM is shown for scale.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import casadi as ca
import numpy as np

from casadical import load_robot
from casadical.model import Model, _compile


def builtin_jit(fun: ca.Function, name: str, folder: str) -> ca.Function:
    """CasADi's own JIT with the options casadical used before."""
    ins = [ca.SX.sym(fun.name_in(i), fun.sparsity_in(i)) for i in range(fun.n_in())]
    opts = {"jit": True, "compiler": "shell", "jit_cleanup": False, "jit_name": name,
            "jit_options": {"flags": ["-O2"], "verbose": False, "directory": folder + os.sep, "cleanup": False}}
    return ca.Function(fun.name(), ins, fun(*ins), opts)


def evaluate(fun: ca.Function, model: Model, N: int, repeat: int) -> float:
    q = np.random.default_rng(0).uniform(-1, 1, (N, model.robot.n))
    F = fun.map("m", "serial", N, [1, 3], [])
    args = (q.T, model.parameters.values, model.default_covariates(N).T, model.base0_nominal(),
            np.zeros((3, N)))[:fun.n_in()]   # measured points, for the least-squares functions
    F(*args)
    best = float("inf")
    for _ in range(repeat):   # the best of several: other processes share the cores
        t0 = time.perf_counter()
        F(*args)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    model = Model(load_robot("ys100"), "kinematic+compliance", jit=False)
    print(f"load average {os.getloadavg()[0]:.2f}; YS100 {model.spec}, {args.poses} poses")
    print(f"{'function':>9} {'path':>22} {'compile s':>10} {'eval ms (best)':>15}")
    with tempfile.TemporaryDirectory() as folder:
        for which in ("fk_jac", "grad"):
            vm = model.per_pose_function(which, False)
            for label, make in (("VM (no compile)", lambda: vm),
                                ("CasADi JIT (baseline)", lambda: builtin_jit(vm, f"base_{which}", folder)),
                                ("casadical compile", lambda: _compile(vm, f"new_{which}"))):
                t0 = time.perf_counter()
                fun = make()
                t_compile = time.perf_counter() - t0
                t_eval = evaluate(fun, model, args.poses, args.repeat)
                print(f"{which:>9} {label:>22} {t_compile:10.2f} {t_eval * 1000:15.1f}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
