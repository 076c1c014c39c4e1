"""The errors of a linear axis (ISO 230-1) hidden on arms on a track and on a column, three seeds: what the truth
hid, what the diagnosis named, exact or not; and a position error of the axis outside the catalogue: located?

The data are made by the independent truth (tests/truth: no casadical code), 80 calibration and 200 validation
poses, the diagnosis runs with its full search (DiagnosisSettings defaults). A claim is exact when the named
causes (cause, joint, harmonic, a straightness' direction, a carriage's angle, scope) are the hidden ones, no
more and no less (tests/helpers/hidden.py :func:`linear_case`). The slow tests of
tests/diagnosis/test_linear_axis_effects.py assert the matrix as exact. The second table hides an error of the
axis' position along it that bows over the travel (0.1 mm P2 of the position: no catalogue cause) and asks for
nothing named and the structure located on the axis (``position`` of its own reading).

Usage::

    python benchmarks/studies/study_linear_axes.py              # 144 + 12 cases, about 2 min on 2 cores
    python benchmarks/studies/study_linear_axes.py --robots track --effects "straightness x" --seeds 0
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.append(str(ROOT))  # the tests' helpers as ``tests.helpers``, after any casadical on PYTHONPATH

from study_hidden_effects import fmt  # noqa: E402  (this folder: the claims in the same words)

from tests.helpers import hidden  # noqa: E402


def diagnosed(c):
    from casadical.diagnosis import DiagnosisSettings, diagnose
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c)
        return diagnose(rob, cal, val, DiagnosisSettings(seed=c.seed))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", nargs="+", default=list(hidden.LINEAR_ROBOTS))
    ap.add_argument("--effects", nargs="+", default=list(hidden.LINEAR_EFFECTS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    args = ap.parse_args()
    from tests.truth import Arm, Effects

    print(f"{'robot':<11} {'effect':<21} {'seed':>4}  {'named':<42} verdict")
    exact = n = 0
    t0 = time.process_time()
    for robot in args.robots:
        for effect in args.effects:
            for seed in args.seeds:
                c = hidden.linear_case(robot, effect, seed)
                v = hidden.judge(diagnosed(c), c.expected, c.allowed)
                exact += v.exact
                n += 1
                print(f"{robot:<11} {effect:<21} {seed:>4}  {fmt(v.named):<42} {v.text()}", flush=True)
    print(f"\n{exact} of {n} cases exact ({time.process_time() - t0:.0f} s CPU)\n")
    print("a position error along the axis bowing 0.1 mm over its travel (outside the catalogue):")
    print(f"{'robot':<11} {'seed':>4}  {'named':<28} located")
    clean = located = n = 0
    for robot in args.robots:
        arm = Arm.from_dict(hidden.robot_doc(robot))
        j = hidden.linear_axis(arm)
        for seed in args.seeds:
            c = hidden.Case(robot, "position bow", seed, Effects(reading_error={j: hidden.smooth(arm, j, bow=0.1e-3)}),
                            set())
            rep = diagnosed(c)
            v = hidden.judge(rep, set())
            where = [(f.candidate.joint, f.structure["covariate"], f.structure["effect"]) for f in rep.findings
                     if f.cause == "unexplained" and f.structure]
            on_axis = (j, f"q{j}", "position") in where
            n += 1
            clean += v.exact
            located += on_axis
            print(f"{robot:<11} {seed:>4}  {fmt(v.named):<28} {where or '-'}", flush=True)
    print(f"\nnothing named in {clean} of {n}; located as the axis' position error in {located} of {n}")


if __name__ == "__main__":
    main()
