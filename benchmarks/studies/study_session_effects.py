"""What differs between sessions (issue 49), simulated: an arm on a column at four heights, and on a tilting floor.

Each case is made by the independent truth (tests/truth: no casadical code) on arms that are not built in
(tests/helpers/hidden.py ``session_case``: the hidden-effect matrix's session cases, which
tests/diagnosis/test_session_effects.py asserts), and diagnosed by the casadical on the path with every session at
once (``diagnose`` with one base pose per session): run it with another commit's code on ``PYTHONPATH`` to put its
figures beside these. The cases:

- ``column``: the arm stands on top of a lifting column, measured at four heights (1.0, 1.6, 2.2, 2.8 m), each
  height a session (the tracker stays, the arm's base rises: its own base pose) with the session column
  ``height_m``. The column bends under the moment of the arm's weights: the mount's compliance grows with the
  height, ``C = c0 h`` (truth ``Effects.mount_law``), 0.3 mrad at the largest moment at the top height; beside
  it the compliance of joint 2 (0.4 mrad at its largest torque). What a diagnosis should name: the mount
  compliance and its law over ``height_m``, the compliance of joint 2 of the robot, no joint property of one
  session.
- ``floor``: the arm on a mobile base whose floor tilts from pose to pose, about the base's x and y axes, each
  uniform within +-2 mrad; a tilt sensor on the base reads it (columns ``tilt_x_rad``, ``tilt_y_rad``, noise 20
  urad), beside a sensor column that follows nothing (``acc_spare_x``); four stations, each a session with its own
  base pose. Nothing of the catalogue to name; the structure should be located on the tilt sensor's columns.

Per case, arm and seed: 60 calibration and 100 held-out poses per session (noise 20 um per axis: a floor of
0.0319 mm, the mean norm of the noise); every finding (cause, joint, scope, session), the joint properties named "of
one session", whether the claims are exact (the hidden matrix's judge) and the structure located, the final model's
held-out mean and max per session against the floor and against a kinematic
calibration of that session's 60 poses alone, and what the structure screen names (covariate, effect, joint).

Usage::

    python benchmarks/studies/study_session_effects.py                       # 2 cases x 3 arms x 3 seeds
    python benchmarks/studies/study_session_effects.py --cases floor --arms arm6 --seeds 0 --noise-mm 0.02
    python benchmarks/studies/study_session_effects.py --json out.json
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
sys.path.append(str(ROOT))  # the tests' helpers as ``tests.helpers``, after any casadical on PYTHONPATH

from tests.helpers import hidden  # noqa: E402

#: arms that are not built in: 6 axes standard DH (three parallel axes), 7 axes modified DH, 7 axes standard DH
ARMS = list(hidden.SESSION_ROBOTS)
CASES = hidden.SESSION_EFFECTS
N_CAL, N_VAL = 60, 100
NOISE = 20e-6
FLOOR_MM = 2 * math.sqrt(2 / math.pi) * NOISE * 1000
#: the column's tilt at the largest moment at the top height (rad)
MOUNT_TILT = 0.3e-3
#: a joint's own property: one value for the robot, whatever the session (issue 49)
JOINT_CAUSES = ("joint_compliance", "nonlinear_stiffness", "encoder_scale", "joint_periodic", "backlash",
                "joint_coupling", "bearing_compliance")


def make(case: str, arm: str, seed: int, tilt: float = MOUNT_TILT):
    """The case (tests/helpers/hidden.session_case), its robot file, calibration and held-out poses (every
    session, read back from the truth's files), and each session's pair of them."""
    c = hidden.session_case(arm, case, seed, tilt)
    robot, cal, val, _ = hidden.make_data(c, n_cal=N_CAL, n_val=N_VAL)
    pairs = [(cal.subset(cal.sessions == s), val.subset(val.sessions == s)) for s in cal.session_names]
    return c, robot, cal, val, pairs


def finding(f) -> dict:
    c = f.candidate
    d = f.to_dict()
    return {"cause": f.cause, "joint": c.joint, "scope": f.scope, "session": c.session, "in_model": f.in_model,
            "label": f.label() if f.cause == "unexplained" else c.label(short=True),
            **{k: d[k] for k in ("covariate", "effect") if k in d}}


def one(case: str, arm_name: str, seed: int, noise_mm: float | None = None, tilt: float = MOUNT_TILT) -> dict:
    from casadical import calibrate
    from casadical.diagnosis import DiagnosisSettings, diagnose
    c, robot, cal, val, pairs = make(case, arm_name, seed, tilt)
    t0 = time.perf_counter()
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed, noise_mm=noise_mm))
    took = time.perf_counter() - t0
    kin = {}
    for cc, v in pairs:
        k = calibrate(robot, cc, "kinematic", warn=False)
        e = k.errors(v)
        kin[cc.session_names[0]] = (float(e.mean() * 1000), float(e.max() * 1000))
    found = [finding(f) for f in rep.findings]
    own = [f for f in found if f["in_model"] and f["scope"] == "session" and f["cause"] in JOINT_CAUSES]
    verdict = hidden.judge(rep, c.expected, c.allowed)
    located = {(f["joint"], f["covariate"], f["effect"]) for f in found if "covariate" in f}
    return {"case": case, "arm": arm_name, "seed": seed, "time_s": took, "final_model": rep.final_model,
            "exact": verdict.exact, "verdict": verdict.text(), "located": all(x in located for x in c.located),
            "follows_nothing_unrelated": not any(f.get("covariate") == "acc_spare_x" for f in found),
            "final": (rep.final_validation.mean_mm, rep.final_validation.max_mm),
            "final_sessions": {s: (st.mean_mm, st.max_mm) for s, st in rep.final_sessions.items()},
            "kinematic_sessions": kin, "findings": found, "joint_properties_of_one_session": len(own),
            "notes": list(rep.notes)}


def show(r: dict) -> None:
    named = [f for f in r["findings"] if f["in_model"] and f["cause"] not in ("geometric", "unexplained")]
    screen = [f for f in r["findings"] if "covariate" in f]
    print(f"\n{r['case']} {r['arm']} seed {r['seed']} ({r['time_s']:.0f} s): final "
          f"{r['final'][0]:.4f} / {r['final'][1]:.4f} mm (mean / max; noise floor {FLOOR_MM:.4f} mm, "
          f"{r['final'][0] / FLOOR_MM:.1f}x)")
    print("  named: " + (", ".join(f"{f['label']} [{f['scope']}]" for f in named) or "nothing"))
    print(f"  joint properties of one session: {r['joint_properties_of_one_session']}; claims {r['verdict']}; "
          f"structure located: {'yes' if r['located'] else 'NO'}")
    print("  structure screen: " + ("; ".join(f"{f['covariate']} / {f['effect']} / joint {f['joint'] or '-'}"
                                              for f in screen) or "nothing"))
    other = [f["label"] for f in r["findings"] if f["cause"] == "unexplained" and "covariate" not in f]
    if other:
        print("  other unexplained: " + "; ".join(other))
    for n in r["notes"]:
        print("  note: " + n[:300])
    print("  held-out mean / max (mm) per session: diagnosis | kinematic of the session alone")
    for s, (m, x) in r["final_sessions"].items():
        km, kx = r["kinematic_sessions"].get(s, (float("nan"), float("nan")))
        print(f"    {s:<6} {m:.4f} / {x:.4f} | {km:.4f} / {kx:.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    ap.add_argument("--arms", nargs="+", default=list(ARMS), choices=list(ARMS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--noise-mm", type=float, help="state the noise to the diagnosis (diagnose --noise-mm)")
    ap.add_argument("--mount-mrad", type=float, default=MOUNT_TILT * 1e3,
                    help="the column's tilt at the largest moment at the top height, mrad (default %(default)s)")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    results = []
    for case in args.cases:
        for arm in args.arms:
            for seed in args.seeds:
                r = one(case, arm, seed, args.noise_mm, args.mount_mrad * 1e-3)
                results.append(r)
                show(r)
                sys.stdout.flush()
    print("\ncase   arm     seed  exact  located  final/floor  final/kinematic  joint properties of one session  "
          "mount named  screen")
    for r in results:
        kin = np.mean([m for m, _ in r["kinematic_sessions"].values()])
        mount = [f["label"] + (f" {f['session']}" if f["session"] else "") for f in r["findings"]
                 if f["cause"] == "mount_compliance" and f["in_model"]]
        screen = ",".join(f"{f['covariate']}/{f['effect']}" for f in r["findings"] if "covariate" in f) or "-"
        print(f"{r['case']:<6} {r['arm']:<7} {r['seed']:>4}  {'yes' if r['exact'] else 'NO':>5}  "
              f"{'yes' if r['located'] else 'NO':>7}  {r['final'][0] / FLOOR_MM:>11.1f}  "
              f"{r['final'][0] / kin:>15.2f}  {r['joint_properties_of_one_session']:>31}  "
              f"{'; '.join(mount) or 'no':>11}  {screen}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=float))


if __name__ == "__main__":
    main()
