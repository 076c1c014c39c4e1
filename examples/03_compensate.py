"""Corrected joint targets: make a robot program reach its points with the calibrated model.

What it teaches: a robot program holds joints computed with the nominal model, so the
real robot misses the points it was meant to reach. compensate() finds, for each
target, the joints at which the CALIBRATED model (every term: geometry, compliance...)
puts the tool on the target point -- what `casadical compensate` writes to JOINTS.csv.
It also shows the calibration JSON round trip (save, then load_calibration).

Run from the repository root:  python examples/03_compensate.py
"""

import tempfile
from pathlib import Path

import numpy as np

from casadical import Measurements, calibrate, load_calibration, load_robot
from casadical.apply import compensate

robot = load_robot("ur10")
data = Measurements.read_csv("problems/datasets/ur10-ipa/series_b.csv", n_joints=robot.n, require_positions=True)
rng = np.random.default_rng(0)
order = rng.permutation(len(data))
cal_poses, program_poses = data.subset(np.sort(order[:300])), data.subset(np.sort(order[300:305]))

with tempfile.TemporaryDirectory() as tmp:
    # The calibration, saved and read back as a user would (`casadical calibrate ... --out cal.json`).
    fitted = calibrate(robot, cal_poses, "kinematic+compliance", solver="lm", position_only=True, warn=False)
    fitted.save(Path(tmp) / "ur10_cal.json")
    cal = load_calibration(Path(tmp) / "ur10_cal.json")

    # A "program": 5 joint targets. Its points are where the NOMINAL model says the tool goes, in the
    # tracker's frame (a base-only calibration places the nominal robot there): what the programmer meant.
    nominal = calibrate(robot, cal_poses, "nominal", solver="lm", position_only=True, warn=False)
    program = Measurements.from_arrays(program_poses.q)
    targets = program.with_positions(nominal.predict(program))

    result = compensate(cal, targets)     # raises TargetError (row, column) if a target cannot be reached
    print(result.summary())

    # result.q: corrected joints (rad); result.dq: the corrections; result.residual: the miss left (m).
    print()
    print("row  " + "  ".join(f"dq{j + 1} (deg)" for j in range(robot.n)) + "  miss before -> after (mm)")
    for i in range(len(targets)):
        dq = "  ".join(f"{np.degrees(x):+9.4f}" for x in result.dq[i])
        print(f"{i + 1:>3}  {dq}  {result.start_residual[i] * 1e3:.3f} -> {result.residual[i] * 1e3:.1e}")
    # result.joints() is the JOINTS.csv table: corrected q*_deg, programmed_q*_deg, dq*_deg, residual_mm.
    out = Path(tmp) / "joints.csv"
    result.joints().write_csv(out)
    print(f"\ncorrected program written to {out.name} ({len(result.joints())} rows) in a temporary folder")
