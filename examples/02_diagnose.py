"""Diagnose: let the data name what the kinematic model gets wrong.

What it teaches: simulate a robot with errors you know (casadical.data._simulate), hide two
physical effects in it, and run the diagnosis. It screens candidate causes (joint
compliance, periodic gear errors, encoder scale, backlash, ...), accepts one only
where held-out folds and the validation poses show it helps, and says what to do
about each. Here you know the answer, so you can check it names exactly the hidden
effects.

Run from the repository root:  python examples/02_diagnose.py
"""

import math

from casadical import load_robot
from casadical.data import Effects, simulate
from casadical.diagnosis import DiagnosisSettings, diagnose

robot = load_robot("ys100")        # built-in 6-axis arm (the papers' Yaskawa)

# The hidden truth: random link errors (Effects' defaults), 20 um tracker noise, and two effects:
hidden = Effects(
    stiffness={3: 1.2e6},                                  # joint 3 gives way under gravity: k3 = 1.2e6 N m/rad
    periodic=[(2, 23, math.radians(0.008), 1.0)],          # joint 2's gear: 0.008 deg, 23 cycles per turn
)
print("hidden: compliance of joint 3 (k3 = 1.2e6 N m/rad), periodic error of joint 2 (23 cycles/turn)")

# One true robot measured twice: poses to calibrate on, and other poses to judge every step with.
cal, truth = simulate(robot, 80, hidden, seed=0)
val, _ = simulate(robot, 200, truth=truth, seed=1)

report = diagnose(robot, cal, val, DiagnosisSettings(seed=0))
print()
print(report.summary())              # the findings, what to do about each, the final model's errors

# The findings are data too (report.findings; report.to_dict() is the JSON of `casadical diagnose --json`).
print()
named = [f.label() for f in report.findings if f.in_model and f.cause != "geometric"]
print("named causes:", ", ".join(named) or "none")
