"""Real UR10 sessions: the GP compensator against a plain GP, and a diagnosed model taken to another session.

The sessions: series A cut where the tracker stopped for more than an hour (the pieces of 600 poses or more:
three sessions, A1-A3) and series B. For each source session and seed, on 300 random calibration poses of it
(the rest of the session judges, never fitted):

1. **in series**: ``diagnose`` (the default: full pose, the GP compensator); the final model's mean and max
   error on the untouched poses, the model the compensator extends (the named causes), a kinematic calibration of the
   same poses and it plus a plain Gaussian process of its residual (:class:`casadical.compensators._gp.ResidualGP`
   applied at every pose);
2. **taken to each other session** as ``calibrate FINAL.json OTHER.csv --model kinematic`` does (the geometry
   refitted on 300 poses there, the rest judging), against a kinematic calibration of the same 300 poses
   (``calibrate ur10 OTHER.csv --model kinematic``): better, tied (within 1 %) or worse.

Run it with another version's code in turn (``PYTHONPATH=/path/to/other``) for a side-by-side.

Usage::

    python benchmarks/studies/study_sessions.py                  # 4 sessions x 3 seeds, 36 transfers (about 10 minutes)
    python benchmarks/studies/study_sessions.py --sessions A3 --seeds 0 --no-transfer
    python benchmarks/studies/study_sessions.py --json out.json
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from casadical import calibrate, load_robot  # noqa: E402
from casadical.compensators import ResidualGP  # noqa: E402
from casadical.data import Measurements  # noqa: E402
from casadical.diagnosis import DiagnosisSettings, diagnose  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"
#: a pause of the tracker longer than this (s) ends a session of series A
GAP_S = 3600.0
MIN_POSES = 600
N_CAL = 300
#: a transfer within this share of the kinematic refit's mean is a tie
TIE = 0.01


def sessions() -> dict[str, Measurements]:
    """Series A's sessions (A1, A2, ...) and series B."""
    a = Measurements.read_csv(DATA / "series_a.csv", n_joints=6)
    t = a.get("time_s")
    cuts = np.flatnonzero(np.diff(t) > GAP_S) + 1
    out = {}
    for idx in np.split(np.arange(len(a)), cuts):
        if len(idx) >= MIN_POSES:
            out[f"A{len(out) + 1}"] = a.subset(idx)
    out["B"] = Measurements.read_csv(DATA / "series_b.csv", n_joints=6)
    return out


def split(n_all: int, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    idx = np.sort(np.random.default_rng(seed).permutation(n_all)[:n])
    return idx, np.setdiff1d(np.arange(n_all), idx)


def stats(errors_m: np.ndarray) -> tuple[float, float]:
    return float(np.mean(errors_m) * 1000), float(np.max(errors_m) * 1000)


def plain_gp(robot, cal: Measurements, val: Measurements, seed: int):
    """A kinematic calibration and it plus a Gaussian process of its residual, applied at every pose: the
    errors (m) of both on ``val``."""
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False)
    R = kin.base_matrix()[:3, :3]
    gp = ResidualGP.fit(cal.q, kin.residuals(cal) @ R, seed=seed)
    pred = kin.predict(val) + gp.predict(val.q) @ R.T
    return kin.errors(val), np.linalg.norm(pred - val.xyz, axis=1)


def one(robot, name: str, src: Measurements, others: dict, seed: int) -> dict:
    idx, rest = split(len(src), N_CAL, seed)
    cal, val = src.subset(idx), src.subset(rest)
    t0 = time.perf_counter()
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    took = time.perf_counter() - t0
    final = rep.final
    kin_e, gp_e = plain_gp(robot, cal, val, seed)
    compensator = next((s for s in rep.steps if s.model.endswith("gp_compensator")), None)
    parent = rep.steps[compensator.parent] if compensator is not None and compensator.parent is not None \
        else None
    out = {"source": name, "seed": seed, "time_s": took, "final_model": rep.final_model,
           "final": stats(final.errors(val)), "kinematic": stats(kin_e), "kinematic_gp": stats(gp_e),
           "compensator_kept": bool(compensator is not None and compensator.accepted),
           "parametric": (parent.validation.mean_mm, parent.validation.max_mm) if parent is not None else None,
           "notes": rep.notes, "transfers": {}}
    for other, data in others.items():
        fit, test = split(len(data), N_CAL, seed)
        d_fit, d_test = data.subset(fit), data.subset(test)
        plain = calibrate(robot, d_fit, "kinematic", warn=False)
        try:
            carried = take(final, d_fit)
            got = carried.stats(d_test).mean_mm
            note = [n for n in carried.notes if "carried" in n or "dropped" in n]
        except Exception as e:   # noqa: BLE001 (a refusal is a result here)
            got, note = None, [f"{type(e).__name__}: {e}"[:300]]
        out["transfers"][other] = {"carried_mm": got, "kinematic_mm": plain.stats(d_test).mean_mm, "notes": note}
    return out


def take(final, data: Measurements):
    """``calibrate FINAL.json OTHER.csv --model kinematic``: the library call the command makes."""
    try:
        from casadical.apply import carry  # the transfer that judges what it carries
    except ImportError:
        return calibrate(final, data, "kinematic", warn=False)
    return carry(final, data, "kinematic", warn=False)


def verdict(t: dict) -> str:
    if t["carried_mm"] is None:
        return "refused"
    d = t["carried_mm"] - t["kinematic_mm"]
    return "tied" if abs(d) <= TIE * t["kinematic_mm"] else ("better" if d < 0 else "worse")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sessions", nargs="+", help="source sessions (default: every one)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--no-transfer", action="store_true", help="in series only")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    robot = load_robot("ur10")
    sess = sessions()
    print("sessions: " + ", ".join(f"{k} {len(v)} poses" for k, v in sess.items()))
    print("source seed | in series (mean / max, mm): kinematic | kin + plain GP | named causes | final (compensator) "
          "| transfers to the other sessions: carried vs kinematic refit (mm)")
    results = []
    for name in args.sessions or list(sess):
        others = {} if args.no_transfer else {k: v for k, v in sess.items() if k != name}
        for seed in args.seeds:
            r = one(robot, name, sess[name], others, seed)
            results.append(r)
            par = "%.4f / %.4f" % tuple(r["parametric"]) if r["parametric"] else "-"
            tr = "  ".join(f"{k} {t['carried_mm'] if t['carried_mm'] is None else round(t['carried_mm'], 4)} vs "
                           f"{t['kinematic_mm']:.4f} {verdict(t)}" for k, t in r["transfers"].items())
            print(f"{name} {seed} | {r['kinematic'][0]:.4f} / {r['kinematic'][1]:.4f} | {r['kinematic_gp'][0]:.4f} / "
                  f"{r['kinematic_gp'][1]:.4f} | {par} | {r['final'][0]:.4f} / {r['final'][1]:.4f} "
                  f"({'kept' if r['compensator_kept'] else 'not kept'}) | {tr} | {r['time_s']:.0f} s", flush=True)
    counts = {v: 0 for v in ("better", "tied", "worse", "refused")}
    for r in results:
        for t in r["transfers"].values():
            counts[verdict(t)] += 1
    if any(counts.values()):
        print("transfers: " + ", ".join(f"{v} {n}" for v, n in counts.items()))
    at_least = sum(r["final"][0] <= r["kinematic_gp"][0] * 1.01 for r in results)
    print(f"final within 1 % of the plain GP or better in {at_least} of {len(results)} splits; final max above "
          f"the kinematic max by more than 5 % in {sum(r['final'][1] > 1.05 * r['kinematic'][1] for r in results)}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
