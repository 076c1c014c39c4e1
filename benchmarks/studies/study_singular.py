"""How often ``compensate``'s bound on joint motion per mm acts on real poses (docs/formats.md, compensate).

A kinematic calibration of the bundled UR10 data (series B, 300 poses: ``split -n 300 --seed 0``, positions,
Levenberg-Marquardt), then, at each of the 13,406 measured poses of series A and B, the singular values of the
equations ``compensate`` solves there: position (m) and, with the orientation held, the flange's rotation
(rad, weighing 1 m per rad). The joint motion per mm of correction along the weakest direction is
1 / (smallest singular value); the table gives the share of poses where it is beyond each bound
(``--max-deg-per-mm``), where the correction is damped. Last, the same at the singular pose of issue 28
(q2 = -90, q3 = 0, q5 = 0).

Usage::

    python benchmarks/studies/study_singular.py           # about 20 s
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from casadical import Measurements, calibrate, load_robot
from casadical.apply._inverse import _Equations

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "problems" / "datasets" / "ur10-ipa"
BOUNDS = (0.5, 1, 2, 5, 10)


def deg_per_mm(cal, q: np.ndarray, hold: bool) -> np.ndarray:
    """Joint motion per mm of correction along the weakest direction of the equations at ``q`` (deg/mm)."""
    targets = Measurements.from_arrays(q, np.zeros((len(q), 3)))
    J = _Equations(cal, targets, hold)(np.arange(len(q)), q, hold)[1]
    return np.degrees(1.0 / np.linalg.svd(J, compute_uv=False)[:, -1]) / 1e3


def main() -> None:
    robot = load_robot("ur10")
    b = Measurements.read_csv(DATA / "series_b.csv", n_joints=6)
    cal_rows = np.sort(np.random.default_rng(0).permutation(len(b))[:300])
    cal = calibrate(robot, b.subset(cal_rows), "kinematic", "lm", warn=False, position_only=True)
    cal.model.jit = False
    q = np.concatenate([Measurements.read_csv(DATA / f"series_{s}.csv", n_joints=6).q for s in "ab"])
    held, alone = deg_per_mm(cal, q, True), deg_per_mm(cal, q, False)
    print(f"UR10, {len(q):,} measured poses of series A and B: share beyond the bound")
    print()
    print("| --max-deg-per-mm | orientation held | point alone |")
    print("|---|---|---|")
    for g in BOUNDS:
        print(f"| {g:g} | {np.mean(held > g) * 100:.2f} % | {np.mean(alone > g) * 100:.2f} % |")
    singular = np.radians([[0, -90, 0, 0, 0, 0]])
    print()
    print(f"at q2 = -90, q3 = 0, q5 = 0: {deg_per_mm(cal, singular, True)[0]:.0f} deg per mm with the orientation "
          f"held, {deg_per_mm(cal, singular, False)[0]:.2f} with the point alone")


if __name__ == "__main__":
    main()
