"""Take a calibration to the robot cell: a URDF and the DH parameter table.

What it teaches: a URDF and a controller's DH table hold geometry only. A model with more
than geometry (here joint compliance) fitted its geometry together with its other terms,
so that geometry alone is not the best one to export: geometric_equivalent() refits the
geometry to reproduce the full model over the calibration poses (what `casadical export`
does), and says how much of the full model it leaves. Then robot_to_urdf() and
parameter_table() write the two files.

Run from the repository root:  python examples/04_export.py
"""

import tempfile
from pathlib import Path

import numpy as np

from casadical import Measurements, calibrate, load_robot
from casadical.apply import geometric_equivalent, parameter_table
from casadical.urdf import robot_to_urdf

robot = load_robot("ur10")
data = Measurements.read_csv("problems/datasets/ur10-ipa/series_b.csv", n_joints=robot.n, require_positions=True)
chosen = np.sort(np.random.default_rng(0).permutation(len(data))[:300])
cal, val = data.subset(chosen), data.subset(np.setdiff1d(np.arange(len(data)), chosen))

full = calibrate(robot, cal, "kinematic+compliance", solver="lm", position_only=True, warn=False)

# The best geometry for a URDF: refitted to the full model (pass payload_kg= for another load than the robot's).
eq = geometric_equivalent(full)
print("exported:", eq.text())
geometry = eq.result                 # a CalibrationResult of model "kinematic"
print(f"held-out mean error: full model {full.stats(val).mean_mm:.4f} mm, "
      f"exported geometry {geometry.stats(val).mean_mm:.4f} mm (compensate uses the full model)")

description = f"UR10 series B, model {full.model.spec}: {eq.text()}"
# The table: a row per parameter, nominal, identified and their difference (the offset a controller takes).
table = parameter_table(geometry, description)
with tempfile.TemporaryDirectory() as tmp:
    urdf = Path(tmp) / "ur10_calibrated.urdf"
    urdf.write_text(robot_to_urdf(geometry, description))
    (Path(tmp) / "ur10_table.csv").write_text(table.to_csv())        # full precision, for a controller
    print(f"\nwrote {urdf.name} ({urdf.stat().st_size} bytes) and ur10_table.csv to a temporary folder")

print(f"\n{table.heading} (identified rows; fixed ones stay nominal, the CSV says why):")
print(f"  {'joint':>5}  {'name':<7} {'nominal':>10} {'identified':>11} {'difference':>11} {'std':>8}")
for r in table.rows:
    if r.joint is not None and not r.fixed:
        print(f"  {r.joint:>5}  {r.name:<7} {r.nominal:>10.4f} {r.identified:>11.4f} {r.difference:>+11.4f} "
              f"{r.std:>8.4f} {r.unit}")
