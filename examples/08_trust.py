"""How far to trust the final model: its 95 % intervals, and its worst case.

What it teaches: a diagnosis's final model lowers the mean error, but a correction can raise the
error where no calibration pose checks it. The report says so (the `worst case:` note: the pose,
what to drop to restore the kinematic model's worst error, what that costs in the mean, and why),
and `worst_case=True` (`diagnose --worst-case`) makes that the final model: a safe worst case chosen
over a lower mean. Each prediction also has a 95 % interval of a measured point (`predict --std`'s
`interval_mm`): the radius around it that holds the measured point 95 times in 100.

Real data: 300 poses of the UR10's series A to calibrate on, the other 11,611 held out.

Run from the repository root:  python examples/08_trust.py
"""

from pathlib import Path

import numpy as np

from casadical import Measurements, load_robot
from casadical.diagnosis import DiagnosisSettings, diagnose
from casadical.prediction import prediction_interval

DATA = Path("problems/datasets/ur10-ipa/series_a.csv")   # 11,911 poses of a real UR10 (MIT licence)

robot = load_robot("ur10")
data = Measurements.read_csv(DATA, n_joints=robot.n, require_positions=True)
chosen = np.sort(np.random.default_rng(0).permutation(len(data))[:300])
cal, val = data.subset(chosen), data.subset(np.setdiff1d(np.arange(len(data)), chosen))

report = diagnose(robot, cal, val, DiagnosisSettings(seed=0))
kinematic = next(s for s in report.steps if s.model == "kinematic").validation
final = report.final_validation
print(f"held-out mean / worst: kinematic {kinematic.mean_mm:.3f} / {kinematic.max_mm:.3f} mm, "
      f"final model {final.mean_mm:.3f} / {final.max_mm:.3f} mm")

# The note says which pose, what to drop, what it costs and why (here: a harmonic of joint 2 that no
# calibration pose checks near that pose's reading of joint 2).
note = next((n for n in report.notes if n.startswith("worst case:")), None)
print()
print(note or "the final model's worst error is within 5 % of the kinematic model's")

# A measured point lies within the interval around its prediction 95 times in 100.
radius = prediction_interval(report.final, val) * 1000
errors = np.linalg.norm(report.final.predict(val) - val.xyz, axis=1) * 1000
print()
print(f"95 % intervals: median radius {np.median(radius):.3f} mm; they hold {np.mean(errors <= radius):.1%} "
      f"of the {len(val)} held-out measured points")
for i in (0, 1, 2):
    print(f"  {val.file(i)} line {val.line(i)}: error {errors[i]:.3f} mm, interval {radius[i]:.3f} mm")

if note:     # the user's choice: the safe worst case
    safe = diagnose(robot, cal, val, DiagnosisSettings(seed=0, worst_case=True))
    print()
    print(f"with worst_case=True: {safe.final_model}")
    print(f"worst case restored: held-out mean / worst {safe.final_validation.mean_mm:.3f} / "
          f"{safe.final_validation.max_mm:.3f} mm (kinematic worst {kinematic.max_mm:.3f} mm)")
