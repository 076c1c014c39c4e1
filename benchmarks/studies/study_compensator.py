"""The GP compensator keeps its gains (issue 38): a lower mean without a higher worst case, and calibrated intervals.

Two sets, each against a kinematic calibration of the same poses and a kinematic calibration plus a plain
Gaussian process of its residual (one length scale per joint and per component, applied at every pose: the
"kinematic + GP hybrid"), on the held-out poses:

- **motoman**: a stand-in, from the independent truth (``tests.truth``), for the public 586-pose Motoman set
  of the issue (not in the repository): a six-axis arm that is not built in (``tests.helpers.arms.ARM6``
  with an industrial arm's joint ranges), a compliance of joint 2, a large smooth structure no catalogue
  cause explains (0.5 mm per axis, a function of joints 2 and 3, in the measurement frame; and joint 3's
  error a smooth step of joint 2's reading, 0.05 deg), a warm-up (thermal expansion 15 ppm/K over 15-35
  deg C in row order, the temperature recorded) and 4 bad shots (5 mm) among the calibration poses; 391
  calibration and 195 held-out poses as the issue's splits, seeds 0-2. Target: mean <= 0.6x kinematic and
  max <= 1.05x kinematic in every seed.
- **ur10**: UR10 series A and B (``problems/datasets/ur10-ipa``), 300 random calibration poses, the rest held
  out, seeds 0-2. Target: mean <= the hybrid, max <= 1.05x kinematic in every split (or the report's note
  says which poses and why). Where the report's ``worst case:`` note names corrections to drop, the diagnosis
  is run again with ``worst_case=True`` (``diagnose --worst-case``) and its final model's figures printed.

For each run: the diagnosis's final model (default settings), whether it kept the GP compensator and the
strength of its shrinkage, its held-out mean and max, the kinematic and hybrid figures, and the share of the
held-out poses inside the final model's 95 % intervals of a measured point (``final.interval_coverage``,
``predict --std``'s ``interval_mm``; target 90-98 %).

Usage::

    python benchmarks/studies/study_compensator.py                    # both sets, seeds 0-2 (~15 minutes)
    python benchmarks/studies/study_compensator.py --sets motoman --seeds 0
    python benchmarks/studies/study_compensator.py --json out.json
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from casadical import calibrate, load_robot  # noqa: E402
from casadical.compensators import ResidualGP  # noqa: E402
from casadical.data import Measurements  # noqa: E402
from casadical.diagnosis import DiagnosisSettings, diagnose  # noqa: E402

DATA = ROOT / "problems" / "datasets" / "ur10-ipa"


def baselines(robot, cal: Measurements, val: Measurements, seed: int) -> dict:
    """Held-out errors (mm) of a kinematic calibration and of it plus a plain GP of its residual."""
    kin = calibrate(robot, cal, "kinematic", "lm", warn=False)
    R = kin.base_matrix()[:3, :3]
    gp = ResidualGP.fit(cal.q, kin.residuals(cal) @ R, seed=seed)
    e_kin = np.linalg.norm(kin.predict(val) - val.xyz, axis=1) * 1000
    e_gp = np.linalg.norm(kin.predict(val) + gp.predict(val.q) @ R.T - val.xyz, axis=1) * 1000
    return {"kinematic_mm": float(e_kin.mean()), "kinematic_max_mm": float(e_kin.max()),
            "hybrid_mm": float(e_gp.mean()), "hybrid_max_mm": float(e_gp.max())}


def run(name: str, robot, cal: Measurements, val: Measurements, seed: int) -> dict:
    t0 = time.perf_counter()
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
    took = time.perf_counter() - t0
    comp = next((f for f in rep.findings if f.cause == "unexplained" and f.in_model and "cv_mm" in f.holds_up), None)
    step = next((s for s in rep.steps if s.model.endswith("gp_compensator")), None)
    out = {"set": name, "seed": seed, "n_cal": len(cal), "n_val": len(val), "final_model": rep.final_model,
           "final_mm": rep.final_validation.mean_mm, "final_max_mm": rep.final_validation.max_mm,
           "compensator": comp is not None, "shrink": comp.holds_up.get("shrink") if comp is not None else None,
           "student_t_nu": comp.holds_up.get("student_t_nu") if comp is not None else None,
           "compensator_reason": step.reason if step is not None and not step.accepted else "",
           "interval_coverage": getattr(rep, "interval_coverage", None), "time_s": took,
           "worst_notes": [n for n in rep.notes if n.startswith("judge only") or "worst" in n[:80]],
           **baselines(robot, cal, val, seed)}
    if any(n.startswith("worst case:") for n in rep.notes):
        again = diagnose(robot, cal, val, DiagnosisSettings(seed=seed, worst_case=True))
        out.update(worst_case_model=again.final_model, worst_case_mm=again.final_validation.mean_mm,
                   worst_case_max_mm=again.final_validation.max_mm)
    return out


def motoman(seed: int, structure_mm: float = 0.5, bad_mm: float = 5.0) -> tuple:
    """The Motoman stand-in: calibration (391 poses) and held-out (195) files of the true robot, and the robot file
    casadical reads (the arm's nominal geometry)."""
    import copy
    import tempfile

    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARM6
    from tests.helpers.hidden import BASE_RPY, BASE_XYZ, temperatures
    from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

    doc = copy.deepcopy(ARM6)       # an industrial arm's joint ranges (deg), not the collaborative arm's +-360
    for j, (lo, hi) in zip(doc["joint"], [(-170, 170), (-60, 120), (-80, 80), (-180, 180), (-120, 120), (-200, 200)]):
        j["min_deg"], j["max_deg"] = lo, hi
    A = math.radians(0.05)
    eff = Effects(stiffness={2: 4e4}, thermal_alpha=15e-6, t_ref=25.0,
                  cross_error={(3, 2): lambda q: A * np.tanh(2 * (q - 0.3))})
    rng = np.random.default_rng(seed)
    true = TrueRobot.draw(Arm.from_dict(doc), eff, rng)
    out = []
    with tempfile.TemporaryDirectory(prefix="motoman-") as tmp:
        for name, n in (("cal", 391), ("val", 195)):
            q = sample(true, n, rng, floor_z=None)
            shots = measure(true, q, rng, session=Session("A", base_xyz=BASE_XYZ, base_rpy=BASE_RPY),
                            temperature_c=temperatures(n, rng), bad=4 if name == "cal" else 0, bad_mm=bad_mm)
            # the large smooth structure no cause explains: 0.5 mm, of joints 2 and 3, in the measurement frame
            shots.xyz = shots.xyz + structure_mm * 1e-3 * np.column_stack([np.sin(q[:, 1] + 2 * q[:, 2]),
                                                              np.cos(q[:, 1] - q[:, 2]), np.sin(2 * q[:, 1])])
            out.append(Measurements.read_csv(shots.write_csv(Path(tmp) / f"{name}.csv"), n_joints=6))
    return robot_from_dict(doc, "arm6-industrial"), out[0], out[1]


def ur10(series: str, seed: int) -> tuple:
    robot = load_robot("ur10")
    src = Measurements.read_csv(DATA / f"series_{series}.csv", n_joints=6)
    idx = np.sort(np.random.default_rng(seed).permutation(len(src))[:300])
    return robot, src.subset(idx), src.subset(np.setdiff1d(np.arange(len(src)), idx))


def table(results: list[dict]) -> None:
    """The docs' table (docs/diagnosis.md, regenerated by benchmarks/docs/regenerate_docs.py)."""
    names = {"motoman": "Motoman stand-in", "a": "UR10 A", "b": "UR10 B"}
    print("\n### The GP compensator's study (held-out mean / max, mm)\n")
    print("| set, seed | kinematic | kinematic + GP | final model | final / kinematic | likelihood, strength p | "
          "95 % interval coverage | with --worst-case |")
    print("|---|---:|---:|---:|---:|---|---:|---:|")
    for r in results:
        nu = r.get("student_t_nu")
        like = "-" if not r["compensator"] else (
            ("Gaussian" if nu is None else f"Student-t {nu:g}") + f", {r['shrink']:g}")
        cov = "-" if r["interval_coverage"] is None else f"{r['interval_coverage']:.1%}"
        wc = (f"{r['worst_case_mm']:.3f} / {r['worst_case_max_mm']:.2f}" if "worst_case_mm" in r else "-")
        print(f"| {names.get(r['set'], r['set'])} {r['seed']} | {r['kinematic_mm']:.3f} / {r['kinematic_max_mm']:.2f} "
              f"| {r['hybrid_mm']:.3f} / {r['hybrid_max_mm']:.2f} | {r['final_mm']:.3f} / {r['final_max_mm']:.2f} | "
              f"{r['final_mm'] / r['kinematic_mm']:.2f} / {r['final_max_mm'] / r['kinematic_max_mm']:.2f} | {like} | "
              f"{cov} | {wc} |")
    print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="+", default=["motoman", "a", "b"], help="motoman, a, b (UR10 series)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--structure-mm", type=float, default=0.5, help="motoman: the smooth structure's size (0.5)")
    ap.add_argument("--bad-mm", type=float, default=5.0, help="motoman: the bad shots' size (5)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    results = []
    print("set seed | kinematic mean/max | hybrid mean/max | final mean/max | final/kin mean, max | compensator "
          "(shrink) | 95 % interval coverage | time")
    for name in args.sets:
        for seed in args.seeds:
            robot, cal, val = motoman(seed, args.structure_mm, args.bad_mm) if name == "motoman" else ur10(name, seed)
            r = run(name, robot, cal, val, seed)
            results.append(r)
            print(f"{name} {seed} | {r['kinematic_mm']:.4f} / {r['kinematic_max_mm']:.4f} | {r['hybrid_mm']:.4f} / "
                  f"{r['hybrid_max_mm']:.4f} | {r['final_mm']:.4f} / {r['final_max_mm']:.4f} | "
                  f"{r['final_mm'] / r['kinematic_mm']:.2f}, {r['final_max_mm'] / r['kinematic_max_mm']:.2f} | "
                  f"{'kept' if r['compensator'] else 'no'} ({r['shrink']}, nu {r.get('student_t_nu')}) | "
                  f"{'-' if r['interval_coverage'] is None else format(r['interval_coverage'], '.1%')}"
                  f" | {r['time_s']:.0f} s", flush=True)
            print(f"      {r['final_model']}")
            if "worst_case_mm" in r:
                print(f"      with --worst-case: {r['worst_case_mm']:.4f} / {r['worst_case_max_mm']:.4f} mm "
                      f"({r['worst_case_mm'] / r['kinematic_mm']:.2f}, "
                      f"{r['worst_case_max_mm'] / r['kinematic_max_mm']:.2f} of kinematic): {r['worst_case_model']}")
            if r["compensator_reason"]:
                print(f"      compensator rejected: {r['compensator_reason']}")
            for n in r["worst_notes"]:
                print(f"      note: {n[:1200]}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    mot = [r for r in results if r["set"] == "motoman"]
    ur = [r for r in results if r["set"] != "motoman"]
    if mot:
        ok = sum(r["final_mm"] <= 0.6 * r["kinematic_mm"] and r["final_max_mm"] <= 1.05 * r["kinematic_max_mm"]
                 for r in mot)
        print(f"\nmotoman-like: mean <= 0.6x and max <= 1.05x kinematic in {ok} of {len(mot)} seeds")
    if ur:
        mean_ok = sum(r["final_mm"] <= r["hybrid_mm"] for r in ur)
        max_ok = sum(r["final_max_mm"] <= 1.05 * r["kinematic_max_mm"] for r in ur)
        print(f"UR10: mean <= hybrid in {mean_ok} of {len(ur)} splits; max <= 1.05x kinematic in {max_ok} of "
              f"{len(ur)}")
        said = [r for r in ur if r["final_max_mm"] > 1.05 * r["kinematic_max_mm"]
                and any("why: " in n or "miss both models" in n for n in r["worst_notes"])]
        print(f"  of the other {len(ur) - max_ok}, the report says which poses and why in {len(said)} (poses both "
              "models miss beyond the noise, or a term no calibration pose checks there)")
        wc = [r for r in ur if "worst_case_mm" in r]
        if wc:
            ok = sum(r["worst_case_mm"] <= r["hybrid_mm"] and r["worst_case_max_mm"] <= 1.05 * r["kinematic_max_mm"]
                     for r in wc)
            print(f"  where the report's worst-case note applies ({len(wc)} splits), with --worst-case: mean <= "
                  f"hybrid and max <= 1.05x kinematic in {ok} of {len(wc)}")
    table(results)
    cov = [r["interval_coverage"] for r in results if r["interval_coverage"] is not None]
    if cov:
        print(f"95 % intervals: coverage {min(cov):.1%} - {max(cov):.1%} "
              f"({sum(0.90 <= c <= 0.98 for c in cov)} of {len(cov)} runs within 90-98 %)")


if __name__ == "__main__":
    main()
