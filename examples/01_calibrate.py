"""Calibrate a UR10 on real laser-tracker data and judge it on poses it never saw.

What it teaches: load a built-in robot, read a measurement CSV, hold poses out,
calibrate two models (geometry alone; geometry + joint compliance) and compare
them on the held-out poses -- the only fair way to compare models.

Run from the repository root:  python examples/01_calibrate.py
"""

from pathlib import Path

import numpy as np

from casadical import Measurements, calibrate, load_robot

DATA = Path("problems/datasets/ur10-ipa/series_b.csv")   # 1,495 poses of a real UR10 (MIT licence)

robot = load_robot("ur10")                                 # built-in: problems/robots/ur10.toml
data = Measurements.read_csv(DATA, n_joints=robot.n, require_positions=True)

# Hold poses out: 300 to calibrate on, the other 1,195 to judge with (what `casadical split -n 300` does).
chosen = np.sort(np.random.default_rng(0).permutation(len(data))[:300])
cal, val = data.subset(chosen), data.subset(np.setdiff1d(np.arange(len(data)), chosen))
print(f"{DATA}: {len(data)} poses; calibrating on {len(cal)}, judging on {len(val)} held-out poses")

# The tracker also measured the probe's orientation; position_only=True fits the points alone.
# solver="lm" (Levenberg-Marquardt) is fast; "ipopt" honours the parameter bounds.
# warn=False: the notes (correlations, parameters at a bound) are in the summary instead of warnings.
kinematic = calibrate(robot, cal, "kinematic", solver="lm", position_only=True, warn=False)
compliant = calibrate(robot, cal, "kinematic+compliance", solver="lm", position_only=True, warn=False)

print()
print(compliant.summary())           # identified vs nominal, stiffness, errors on the calibration poses

# Errors on the calibration poses flatter a model; the held-out poses tell the truth.
print()
print("held-out position errors:")
for name, res in [("kinematic", kinematic), ("kinematic+compliance", compliant)]:
    print(f"  {name:<22} {res.stats(val).line()}")
gain = kinematic.stats(val).mean_mm - compliant.stats(val).mean_mm
print(f"joint compliance lowers the held-out mean error by {gain:.4f} mm")
