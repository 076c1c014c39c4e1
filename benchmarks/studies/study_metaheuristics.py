"""What the metaheuristics cost and buy: CA / GA / TLBO alone, IPOPT alone, IPOPT started from them.

Two cases, each on several simulated YS100 robots (the CA paper's protocol,
25 calibration / 45 validation poses, stiffness of joints 2-5):

A. **Compliance from a rigid start** (the papers' setting). The compliances
   ``c = 1/k`` enter the model linearly and are bounded, so IPOPT from
   ``c = 0`` is a local solver on an (almost) convex problem. Compared:
   IPOPT alone (SKCM); the two-phase loop with CA, GA or TLBO alone (the CA
   paper's method: least squares for the kinematics, the metaheuristic for
   the stiffnesses); and IPOPT started from each metaheuristic's best points.

B. **A joint offset far from nominal** (a mis-mastered joint: the zero of
   joint 2 is 90 deg off, or that of joint 3 150 deg off, e.g. after a motor
   swap), plus the compliances. The model's geometric box is widened to
   +-180 deg so that the truth is admissible. The residual is periodic in
   the offset, with spurious minima: a local solver from nominal can end in
   one. Compared: Levenberg-Marquardt and IPOPT from nominal; IPOPT from 10
   random offsets (plain multi-start, the cheap global baseline); the
   metaheuristics alone (best point + one Gauss-Newton step of the other
   parameters); IPOPT from their 3 best points.

Success = validation mean error below 0.1 mm (the noise floor is ~0.04 mm).

Usage::

    python benchmarks/studies/study_metaheuristics.py            # 5 robots per case (~3 min)
    python benchmarks/studies/study_metaheuristics.py --quick    # 2 robots
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings

import numpy as np

os.environ.setdefault("CASADICAL_JIT", "0")

from casadical.calibration import calibrate  # noqa: E402
from casadical.data import load_protocol  # noqa: E402
from casadical.methods import (
    Inputs,  # noqa: E402
    global_start,  # noqa: E402
    run_method,  # noqa: E402
    two_phase,  # noqa: E402
)
from casadical.model import Model  # noqa: E402
from casadical.terms import make_term  # noqa: E402

JOINTS = [2, 3, 4, 5]
SUCCESS_MM = 0.1


def say(*a):
    print(*a, flush=True)


def k_error(stiffness: dict, truth) -> float:
    """Largest relative stiffness error (%) over joints 2-5."""
    return max(abs(stiffness[j] * truth.value(f"c{j}") - 1.0) * 100 for j in JOINTS)


def stiffness_of(result) -> dict:
    return {j: k for j, (k, _) in result.stiffness().items()}


class Tally:
    """Per-approach records: time, validation mean, success, evaluations, stiffness error."""

    def __init__(self):
        self.rows: dict[str, list[dict]] = {}

    def add(self, name, **rec):
        self.rows.setdefault(name, []).append(rec)

    def table(self) -> str:
        out = ["| approach | success | validation mean (mm), median | worst | time (s), mean | "
               "evaluations, mean | max stiffness error, median |",
               "|---|---|---|---|---|---|---|"]
        for name, recs in self.rows.items():
            v = np.array([r["val_mm"] for r in recs])
            ok = int(np.sum(v < SUCCESS_MM))
            t = np.mean([r["time_s"] for r in recs])
            nf = [r.get("nfev") for r in recs if r.get("nfev") is not None]
            ke = [r.get("k_err") for r in recs if r.get("k_err") is not None]
            out.append(f"| {name} | {ok}/{len(recs)} | {np.median(v):.4g} | {v.max():.4g} | {t:.2f} | "
                       + (f"{np.mean(nf):.0f}" if nf else "-") + " | "
                       + (f"{np.median(ke):.2f} %" if ke else "-") + " |")
        return "\n".join(out)


def case_a(n_robots: int) -> Tally:
    say("\n## A. Compliance from a rigid start (ca-ys100)\n")
    proto = load_protocol("ca-ys100")
    tally = Tally()
    for k in range(n_robots):
        seed = proto.seed + k
        sets, truth = proto.generate(seed)
        cal, val = sets["calibration"], sets["validation"]
        r = run_method("SKCM", proto.robot, cal, val, seed=seed)
        tally.add("IPOPT alone (SKCM)", val_mm=r.validation.mean_mm, time_s=r.time_s,
                  nfev=r.result.solver.iterations, k_err=k_error(r.stiffness(), truth))
        for alg in ("CA", "GA", "TLBO"):
            t0 = time.perf_counter()
            o = two_phase(Inputs(proto.robot, cal, None, seed), alg, JOINTS)
            t = time.perf_counter() - t0
            tally.add(f"{alg} alone (two-phase: LS + {alg})", val_mm=o.result.stats(val).mean_mm, time_s=t,
                      nfev=o.nfev, k_err=k_error(stiffness_of(o.result), truth))
        for alg in ("CA", "GA", "TLBO"):
            r = run_method(f"SKCM-IPOPT-{alg}", proto.robot, cal, val, seed=seed)
            tally.add(f"IPOPT from {alg}", val_mm=r.validation.mean_mm, time_s=r.time_s, nfev=r.info["nfev"],
                      k_err=k_error(r.stiffness(), truth))
    say(tally.table())
    say("\n(evaluations: IPOPT iterations for IPOPT alone; objective evaluations of the metaheuristic "
        "otherwise)")
    return tally


def offset_data(proto, seed: int, joint: int, offset_deg: float):
    """Protocol data of a robot whose joint ``joint`` zero is ``offset_deg`` off."""
    sets, truth = proto.generate(seed)
    values = truth.values.copy()
    values[truth.model.parameters.index(f"theta{joint}")] += math.radians(offset_deg)
    rng = np.random.default_rng(seed)
    out = {}
    for name, d in sets.items():
        xyz = truth.model.predict(d.q, values, truth.model.covariates(d), truth.base0)
        out[name] = d.with_positions(xyz + rng.normal(0.0, proto.effects.noise, xyz.shape))
    return out, truth


def case_b(n_robots: int) -> Tally:
    say("\n## B. A joint zero far off: joint 2 +90 deg, joint 3 +150 deg (ca-ys100 robots)\n")
    proto = load_protocol("ca-ys100")
    robot = proto.robot
    tally = Tally()
    for k in range(n_robots):
        seed = proto.seed + k
        for joint, offset in ((2, 90.0), (3, 150.0)):
            sets, truth = offset_data(proto, seed, joint, offset)
            cal, val = sets["calibration"], sets["validation"]
            model = Model(robot, [make_term("kinematic", angle_box=math.pi),
                                  make_term("joint_compliance", joints=JOINTS)])
            for solver, name in (("lm", "Levenberg-Marquardt from nominal"), ("ipopt", "IPOPT from nominal")):
                t0 = time.perf_counter()
                try:
                    # the nominal model misses these poses by a third of the reach: the robot file is this far
                    # off on purpose (issue 21's check refuses it unless told; marked, the poses pass below too)
                    r = calibrate(robot, cal, model, solver, warn=False, allow_mismatch=True)
                    v = r.stats(val).mean_mm
                except Exception:   # noqa: BLE001 - a failed local solve counts as a failure
                    v = math.inf
                tally.add(name, val_mm=v, time_s=time.perf_counter() - t0)
            # plain multi-start: IPOPT from 10 random offsets
            rng = np.random.default_rng(seed)
            t0 = time.perf_counter()
            best, best_cost = None, math.inf
            for th in rng.uniform(-math.pi, math.pi, 10):
                t1 = time.perf_counter()
                try:
                    r = calibrate(robot, cal, model, "ipopt", start={f"theta{joint}": th}, warn=False,
                                  allow_mismatch=True)
                except Exception:   # noqa: BLE001
                    tally.add("IPOPT from one random offset", val_mm=math.inf, time_s=time.perf_counter() - t1)
                    continue
                tally.add("IPOPT from one random offset", val_mm=r.stats(val).mean_mm,
                          time_s=time.perf_counter() - t1)
                if r.solver.cost < best_cost:
                    best, best_cost = r, r.solver.cost
            tally.add("IPOPT from 10 random offsets", val_mm=best.stats(val).mean_mm if best else math.inf,
                      time_s=time.perf_counter() - t0, nfev=10)
            box = {f"theta{joint}": (-math.pi, math.pi)}
            for alg in ("CA", "GA", "TLBO"):
                o = global_start(Inputs(robot, cal, None, seed), alg, JOINTS, model=model, params_box=box)
                tally.add(f"{alg} alone (best point + one GN step)", val_mm=o.alone.stats(val).mean_mm,
                          time_s=o.time_s["start"] + o.time_s["search"], nfev=o.optim.nfev)
                tally.add(f"IPOPT from {alg} (3 starts)", val_mm=o.best.stats(val).mean_mm,
                          time_s=o.time_s["total"], nfev=o.optim.nfev)
    say(tally.table())
    say("\n(evaluations: objective evaluations of the metaheuristic, each one alignment, one Jacobian and "
        "two model evaluations of the 25 poses; for the random multi-start, IPOPT runs)")
    return tally


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="2 simulated robots per case")
    ap.add_argument("--robots", type=int, default=None, help="simulated robots per case (default 5)")
    ap.add_argument("--json", help="write the records as JSON")
    args = ap.parse_args(argv)
    n = args.robots or (2 if args.quick else 5)
    warnings.simplefilter("ignore")
    say(f"# Metaheuristics against IPOPT ({n} simulated robots per case; success = validation mean "
        f"< {SUCCESS_MM} mm)")
    t0 = time.perf_counter()
    a = case_a(n)
    b = case_b(n)
    say(f"\ntotal {time.perf_counter() - t0:.0f} s")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"A": a.rows, "B": b.rows}, fh, indent=1,
                      default=lambda o: o.item() if hasattr(o, "item") else str(o))
    return 0


if __name__ == "__main__":
    sys.exit(main())
