"""Benchmark: casadical model evaluation against a plain numpy implementation.

Times, for N poses of the YS100 ``kinematic+compliance`` model (42
parameters):

- casadical forward kinematics (``Model.predict``) and positions + Jacobian
  (``Model.predict_jacobian``), with the CasADi virtual machine (``jit=False``)
  and compiled to C (``jit=True``);
- the numpy baseline of ``numpy_model.py``: the same model, vectorised over
  poses, and its Jacobian by forward finite differences (all 42 perturbed
  parameter vectors in one batch).

Warm timings (after a first call at that N), median of several repeats,
``time.perf_counter``. Both sides get the same inputs, covariates and base
pose passed explicitly, as a calibration loop does. Also reported: the
``Model(...)`` constructor time and the JIT compile time (first call).

Usage::

    python benchmarks/speed/bench_model.py            # N = 10 ... 100000 (~1-2 min)
    python benchmarks/speed/bench_model.py --quick    # N = 10, 100, 1000
    python benchmarks/speed/bench_model.py --json results.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from numpy_model import NumpyModel, check  # noqa: E402

from casadical.loading import load_robot  # noqa: E402
from casadical.model import Model, compiler_available  # noqa: E402

SPEC = "kinematic+compliance"
SIZES = [10, 100, 1000, 10000, 100000]
QUICK_SIZES = [10, 100, 1000]
GOAL_N, GOAL_S = 1000, 5e-3


def cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def timed(f, min_repeats: int, min_time: float, max_repeats: int) -> tuple[float, int]:
    """Median warm time of ``f`` (one untimed call first) and the number of repeats."""
    f()
    ts: list[float] = []
    while len(ts) < max_repeats and (len(ts) < min_repeats or sum(ts) < min_time):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), len(ts)


def once(f) -> float:
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


def fmt_t(s: float) -> str:
    if s != s:  # nan
        return "-"
    if s < 1e-3:
        return f"{s * 1e6:.0f} us"
    if s < 1.0:
        return f"{s * 1e3:.2f} ms"
    return f"{s:.2f} s"


def fmt_rate(r: float) -> str:
    if r != r:
        return "-"
    for unit, k in (("M", 1e6), ("k", 1e3)):
        if r >= k:
            return f"{r / k:.1f}{unit}"
    return f"{r:.0f}"


def inputs(robot, N: int, rng) -> tuple:
    lim = robot.limits
    q = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((N, robot.n))
    payload = rng.uniform(0.0, robot.payload_mass, N)
    return q, payload[:, None], payload


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help=f"only N = {QUICK_SIZES}")
    ap.add_argument("--sizes", type=int, nargs="+", help="pose counts (overrides --quick)")
    ap.add_argument("--robot", default="ys100", help="robot (default ys100; no four-bar loop)")
    ap.add_argument("--min-time", type=float, default=0.3,
                    help="repeat each warm timing until this many seconds are spent (default 0.3)")
    ap.add_argument("--repeats", type=int, default=5, help="least number of timed repeats (default 5)")
    ap.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    sizes = args.sizes or (QUICK_SIZES if args.quick else SIZES)
    rep = dict(min_repeats=args.repeats, min_time=args.min_time, max_repeats=50)
    rep_big = dict(min_repeats=3, min_time=args.min_time, max_repeats=50)

    robot = load_robot(args.robot)
    have_cc = compiler_available()
    info = {"cpu": cpu_model(), "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "casadi": ca.__version__, "robot": robot.name, "model": SPEC,
            "jit_available": have_cc}
    print(f"machine: {info['cpu']}, {info['cores']} cores; Python {info['python']}, "
          f"numpy {info['numpy']}, CasADi {info['casadi']}")

    # --- correctness of the baseline -------------------------------------------------
    chk = check(args.robot, N=200, seed=0)
    info["check"] = chk

    # --- construction and compilation ------------------------------------------------
    build = [once(lambda: Model(robot, SPEC)) for _ in range(5)]
    t_build = statistics.median(build)
    model_vm = Model(robot, SPEC, jit=False)
    P = len(model_vm.parameters)
    print(f"\n{robot.name} {SPEC}: {P} parameters, "
          f"{model_vm.fk.n_instructions()} FK / {model_vm.fk_jac.n_instructions()} FK+Jacobian "
          "instructions")
    print(f"Model(...) constructor: {fmt_t(t_build)} (median of 5)")
    rng = np.random.default_rng(args.seed)
    p = model_vm.parameters.values.copy()
    for i, par in enumerate(model_vm.parameters):  # a calibrated-looking parameter vector
        p[i] = p[i] + par.scale * rng.standard_normal() if par.term == "geometric" \
            else 10.0 * par.scale * rng.random()
    b0 = model_vm.base0_nominal()
    model_jit = None
    if have_cc:
        model_jit = Model(robot, SPEC, jit=True)
        q, cov, _ = inputs(robot, 10, rng)
        first_fk = once(lambda: model_jit.predict(q, p, cov, b0))
        first_jac = once(lambda: model_jit.predict_jacobian(q, p, cov, b0))
        warm_fk = timed(lambda: model_jit.predict(q, p, cov, b0), **rep)[0]
        warm_jac = timed(lambda: model_jit.predict_jacobian(q, p, cov, b0), **rep)[0]
        info["jit_compile_s"] = {"fk": first_fk - warm_fk, "fk_jac": first_jac - warm_jac}
        print(f"JIT compile (first call, gcc -O2, once per model): FK {fmt_t(first_fk - warm_fk)}, "
              f"FK+Jacobian {fmt_t(first_jac - warm_jac)}")
    else:
        print("JIT: no C compiler found (or CASADICAL_JIT=0); JIT columns skipped")
    info["build_s"] = t_build

    # --- the table ---------------------------------------------------------------------
    nm = NumpyModel(robot, model_vm.parameters.names, [x.scale for x in model_vm.parameters])
    rows = []
    nan = float("nan")
    for N in sizes:
        q, cov, payload = inputs(robot, N, rng)
        r = rep if N <= 10000 else rep_big
        row = {"N": N}
        row["ca_fk_vm"] = timed(lambda: model_vm.predict(q, p, cov, b0), **r)[0]
        row["ca_jac_vm"] = timed(lambda: model_vm.predict_jacobian(q, p, cov, b0), **r)[0]
        if model_jit is not None:
            row["ca_fk_jit"] = timed(lambda: model_jit.predict(q, p, cov, b0), **r)[0]
            row["ca_jac_jit"] = timed(lambda: model_jit.predict_jacobian(q, p, cov, b0), **r)[0]
        else:
            row["ca_fk_jit"] = row["ca_jac_jit"] = nan
        row["np_fk"] = timed(lambda: nm.predict(q, p, payload, b0), **r)[0]
        row["np_jac"] = timed(lambda: nm.predict_jacobian(q, p, payload, b0), **r)[0]
        best_fk = min(row["ca_fk_vm"], row["ca_fk_jit"]) if model_jit else row["ca_fk_vm"]
        best_jac = min(row["ca_jac_vm"], row["ca_jac_jit"]) if model_jit else row["ca_jac_vm"]
        row["speedup_fk"] = row["np_fk"] / best_fk
        row["speedup_jac_vm"] = row["np_jac"] / row["ca_jac_vm"]
        row["speedup_jac_jit"] = row["np_jac"] / row["ca_jac_jit"]
        row["jac_poses_per_s"] = N / best_jac
        row["np_jac_poses_per_s"] = N / row["np_jac"]
        rows.append(row)
    info["rows"] = rows

    head = ["N", "FK VM", "FK JIT", "Jac VM", "Jac JIT", "numpy FK", "numpy FD Jac",
            "FK x", "Jac x (VM)", "Jac x (JIT)", "Jac poses/s", "numpy poses/s"]
    table = [[f"{w['N']:,}", fmt_t(w["ca_fk_vm"]), fmt_t(w["ca_fk_jit"]), fmt_t(w["ca_jac_vm"]),
              fmt_t(w["ca_jac_jit"]), fmt_t(w["np_fk"]), fmt_t(w["np_jac"]),
              f"{w['speedup_fk']:.2f}", f"{w['speedup_jac_vm']:.1f}",
              "-" if w["speedup_jac_jit"] != w["speedup_jac_jit"] else f"{w['speedup_jac_jit']:.1f}",
              fmt_rate(w["jac_poses_per_s"]), fmt_rate(w["np_jac_poses_per_s"])] for w in rows]
    print("\nWarm times, median of repeats (casadical: Model.predict / predict_jacobian; "
          "x = numpy time / casadical time,\nFK x against the faster casadical mode; "
          "poses/s of the Jacobian, casadical's faster mode vs numpy FD):\n")
    print("| " + " | ".join(head) + " |")
    print("|" + "|".join("---:" for _ in head) + "|")
    for t in table:
        print("| " + " | ".join(t) + " |")

    goal = next((w for w in rows if w["N"] == GOAL_N), None)
    if goal is not None:
        t = goal["ca_jac_jit"] if model_jit is not None else goal["ca_jac_vm"]
        mode = "JIT" if model_jit is not None else "VM"
        met = t < GOAL_S
        info["goal"] = {"text": "the Jacobian of 1,000 poses in under 5 ms", "time_s": t,
                        "mode": mode, "met": met}
        print(f"\nGoal \"the Jacobian of 1,000 poses in under 5 ms\": "
              f"{'MET' if met else 'NOT MET'} ({mode}: {fmt_t(t)}; "
              + (f"VM: {fmt_t(goal['ca_jac_vm'])}; " if model_jit is not None else "")
              + f"numpy FD: {fmt_t(goal['np_jac'])})")
    if args.json:
        Path(args.json).write_text(json.dumps(info, indent=2))
        print(f"results written to {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
