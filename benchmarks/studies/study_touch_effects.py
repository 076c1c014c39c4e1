"""The hidden-effect matrix on touch data: what the truth hid, what the diagnosis named, exact or not.

A ball on the flange held in the two sockets of a block 50 mm apart (the fixture file's), the block at three
placements for the calibration (25 rows per socket) and two others for validation (15), the ball in the socket
to 20 um per axis: the readings are what the encoders say when the independent truth's robot (tests/truth: no
casadical code), with every drive effect, puts the ball in the socket. The robots are not built in (a 7-axis DH
arm, a 6-axis MDH arm, both with masses); the effects those of the tracker matrix that touch data can show
(geometry alone, the compliance of joint 2, a gear error of joint 3, an encoder scale of joint 2). The slow test
tests/diagnosis/test_touch_effects.py asserts every case this prints as exact.

Usage::

    python benchmarks/studies/study_touch_effects.py                      # 24 cases (about 15 min on 2 cores)
    python benchmarks/studies/study_touch_effects.py --robots arm7-dh --effects compliance --seeds 0
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.append(str(ROOT))  # the tests' helpers as ``tests.helpers``, after any casadical on PYTHONPATH

from tests.diagnosis.test_touch_effects import EFFECTS, ROBOTS  # noqa: E402
from tests.helpers import hidden  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS))
    ap.add_argument("--effects", nargs="+", default=list(EFFECTS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    args = ap.parse_args(argv)
    from casadical.diagnosis import DiagnosisSettings, diagnose

    exact = total = 0
    print(f"{'robot':9s} {'effect':14s} seed  verdict  named                                   consistency  "
          f"distance   nominal    s")
    for robot in args.robots:
        for effect in args.effects:
            for seed in args.seeds:
                c = hidden.case(robot, effect, seed)
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    rob, cal, val, _ = hidden.make_touch_data(c)
                    report = diagnose(rob, cal, val, DiagnosisSettings(seed=seed))
                v = hidden.judge(report, c.expected, c.allowed)
                final, nominal = report.final_validation, report.steps[0].validation
                named = ", ".join(f"{k[0]} j{k[1]}" + (f" h{k[2]}" if k[2] else "") for k in sorted(v.named, key=str))
                print(f"{robot:9s} {effect:14s} {seed:4d}  {'exact' if v.exact else 'NOT':7s}  {named or '-':38s}  "
                      f"{final.touch['consistency_mm']:8.4f} mm  {final.touch['distance_error_mm']:6.4f}  "
                      f"{nominal.touch['consistency_mm']:7.4f}  {time.perf_counter() - t0:4.0f}", flush=True)
                exact, total = exact + v.exact, total + 1
    print(f"exact: {exact} of {total} (held-out consistency and distance error in mm on the validation "
          "placements, their sockets fitted to their own rows; nominal: the robot file's model)")
    return 0 if exact == total else 1


if __name__ == "__main__":
    sys.exit(main())
