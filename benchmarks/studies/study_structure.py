"""Structure is not bad data, every cause per session, nothing skipped in silence (issue 25 items 2-4): figures.

Each case is made by the independent truth (tests/truth) on robots that are not built in, as in
tests/diagnosis/test_structure.py, and diagnosed (or calibrated) by the casadical on the path: run it with the code of
another commit on ``PYTHONPATH`` to put its figures beside these (it reads only what every version reports:
the final model, the findings, the notes)::

    python benchmarks/studies/study_structure.py
    PYTHONPATH=/path/to/other/checkout python benchmarks/studies/study_structure.py

Per case and seed: what is named (cause, joint, harmonic, session), how many calibration poses the final fit
set aside and what the note calls them (``bad``: "likely bad measurements"; ``structure``), and for the
three sessions each session's validation mean against its noise floor (the mean norm of the truth's
noise, 2 sqrt(2/pi) x 20 um = 0.0319 mm).
"""

from __future__ import annotations

import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.append(str(ROOT))  # the tests' helpers as ``tests.helpers``, after the casadical on PYTHONPATH

from casadical import calibrate  # noqa: E402
from casadical.data import (
    Measurements,  # noqa: E402
    combine,  # noqa: E402
)
from casadical.diagnosis import DiagnosisSettings, diagnose  # noqa: E402
from casadical.robot import robot_from_dict  # noqa: E402
from tests.helpers.arms import ARM3, ARM4_BETA, ARM5, ARM7, ARM7_DH  # noqa: E402
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample  # noqa: E402

FLOOR_MM = 2 * math.sqrt(2 / math.pi) * 0.020


def read(shots, path) -> Measurements:
    shots.write_csv(path)
    return Measurements.read_csv(path)


def causes(rep) -> str:
    out = []
    for f in rep.findings:
        if not f.in_model or f.cause in ("geometric", "unexplained"):
            continue
        c = f.candidate
        out.append(c.label(short=True))
    return ", ".join(out) or "-"


def verdict(notes) -> str:
    note = next((n for n in notes if n.startswith("the robust loss set aside")), "")
    if not note:
        return "none set aside"
    n = note.split("set aside ", 1)[1].split(" ", 1)[0]
    return f"{n} set aside: " + ("structure" if "not bad measurements" in note else "bad")


def three_sessions(arm, seed, folder):
    rng = np.random.default_rng(seed)
    effects = Effects(stiffness={2: 4e5, 3: 2.5e5}, periodic=[(2, 17, math.radians(0.006), 0.3)])
    robot = TrueRobot.draw(Arm.from_dict(arm), effects, rng)
    own = robot.with_effects(Effects(stiffness=effects.stiffness,
                                     periodic=effects.periodic + [(1, 11, math.radians(0.01), 0.7)]))
    sessions = [(robot, Session("s1")),
                (robot, Session("s2", (1.2, -0.8, 0.1), (0.01, -0.02, 2.2), drift=(1e-6, 0.0, -1e-6), t_ref=40.0)),
                (own, Session("s3", (-0.9, 1.1, 0.0), (0.0, 0.01, -1.4)))]
    out = {}
    for kind, m in (("cal", 80), ("val", 120)):
        (folder / kind).mkdir()
        parts = []
        for truth, s in sessions:
            q = sample(truth, m, rng, floor_z=None)
            parts.append(read(measure(truth, q, rng, session=s, time_s=np.arange(m, dtype=float)),
                              folder / kind / f"{s.name}.csv"))
        out[kind] = combine(parts)
    return robot_from_dict(arm), out["cal"], out["val"]


def warm_up(arm, seed, folder, times=True, n=250):
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(stiffness={2: 6e4}), rng)
    q = sample(robot, n, rng, floor_z=None)
    t = np.arange(n) * 10.0
    shots = measure(robot, q, rng, time_s=t)
    shots.xyz += np.outer(np.exp(-t / 70.0), [0.25e-3, -0.15e-3, 0.2e-3])
    if not times:
        shots.columns.pop("time_s")
    data = read(shots, folder / "series.csv")
    cal = np.sort(np.random.default_rng(seed + 7).permutation(n)[:150])
    return robot_from_dict(arm), data.subset(cal), data.subset(np.setdiff1d(np.arange(n), cal))


def massless(arm: dict) -> dict:
    out = {**arm, "joint": [{k: v for k, v in j.items() if k not in ("mass_kg", "com_m")} for j in arm["joint"]]}
    out.pop("payload", None)
    return out


def one_joint_at_a_time(arm, seed, folder):
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(arm), Effects(stiffness={2: 6e4}), rng)
    lim = robot.arm.limits
    home = lim.mean(axis=1)
    q = []
    for j in range(robot.arm.n):
        for v in np.linspace(lim[j, 0] + 0.1, lim[j, 1] - 0.1, 36 // robot.arm.n):
            q.append(home.copy())
            q[-1][j] = v
    data = read(measure(robot, np.array(q), rng), folder / "sweeps.csv")
    cal = np.sort(rng.permutation(len(q))[:2 * len(q) // 3])
    return data.subset(cal), data.subset(np.setdiff1d(np.arange(len(q)), cal))


def main() -> None:
    warnings.simplefilter("ignore")
    print("three sessions: robot compliance j2, j3 and gear j2 h17; s2 drifts; s3's own gear j1 h11")
    for name, arm, seed in (("arm4-beta", ARM4_BETA, 0), ("arm5", ARM5, 1), ("arm7-dh", ARM7_DH, 2)):
        with tempfile.TemporaryDirectory() as tmp:
            robot, cal, val = three_sessions(arm, seed, Path(tmp))
            rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
        ratios = ", ".join(f"{s} {st.mean_mm / FLOOR_MM:.2f}x" for s, st in rep.final_sessions.items())
        print(f"  {name} seed {seed}: {causes(rep)} | {verdict(rep.notes)} | sessions at {ratios} their floor")
    print("warm-up: the first poses 0.35 mm off, dying away in 70 s; a pose every 10 s")
    for name, arm, seed in (("arm4-beta", ARM4_BETA, 0), ("arm7", ARM7, 1), ("arm7-dh", ARM7_DH, 2)):
        for times in (True, False):
            with tempfile.TemporaryDirectory() as tmp:
                robot, cal, val = warm_up(arm, seed, Path(tmp), times)
                rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed))
            print(f"  {name} seed {seed} {'with' if times else 'without'} time_s: {causes(rep)} | "
                  f"{verdict(rep.notes)} | validation {rep.final_validation.mean_mm:.4f} mm")
    print("36 poses one joint at a time, compliant joint 2, the robot file without masses (24 calibrate)")
    for seed in range(3):
        with tempfile.TemporaryDirectory() as tmp:
            cal, val = one_joint_at_a_time(ARM5, seed, Path(tmp))
        rep = diagnose(robot_from_dict(massless(ARM5)), cal, val, DiagnosisSettings(seed=seed))
        said = [n["cause"] for n in rep.to_dict().get("not_tried", [])]
        print(f"  arm5 seed {seed}: {causes(rep)} | {verdict(rep.notes)} | compliance not tried said: "
              f"{any('compliance' in c for c in said)}")
    print("calibrate --model kinematic, a gear error of joint 1 (0.012 deg, 11 cycles), no bad measurement")
    for name, arm, seed in (("arm4-beta", ARM4_BETA, 0), ("arm3", ARM3, 1), ("arm3", ARM3, 3)):
        rng = np.random.default_rng(seed)
        robot = TrueRobot.draw(Arm.from_dict(arm), Effects(periodic=[(1, 11, math.radians(0.012), 0.4)]), rng)
        with tempfile.TemporaryDirectory() as tmp:
            data = read(measure(robot, sample(robot, 60, rng, floor_z=None), rng), Path(tmp) / "cal.csv")
        res = calibrate(robot_from_dict(arm), data, "kinematic", "lm", warn=False)
        print(f"  {name} seed {seed}: {verdict(res.notes)}")
    print("the same gear error and 4 bad shots (1.5 mm): diagnose")
    for name, arm, seed in (("arm4-beta", ARM4_BETA, 0), ("arm7", ARM7, 1), ("arm7-dh", ARM7_DH, 2)):
        rng = np.random.default_rng(seed)
        robot = TrueRobot.draw(Arm.from_dict(arm), Effects(periodic=[(1, 11, math.radians(0.012), 0.4)]), rng)
        shots = measure(robot, sample(robot, 120, rng, floor_z=None), rng, bad=4, bad_mm=1.5)
        with tempfile.TemporaryDirectory() as tmp:
            data = read(shots, Path(tmp) / "series.csv")
        cal, val = data.subset(np.arange(80)), data.subset(np.arange(80, 120))
        rep = diagnose(robot_from_dict(arm), cal, val, DiagnosisSettings(seed=seed))
        print(f"  {name} seed {seed}: {causes(rep)} | {verdict(rep.notes)} | bad shots in the calibration poses: "
              f"{int(np.sum(shots.bad < 80))}")


if __name__ == "__main__":
    main()
