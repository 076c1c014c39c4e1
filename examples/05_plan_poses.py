"""Plan poses: choose which poses to measure before going to the robot.

What it teaches: a tracker campaign costs time per pose, and poses are not equally
informative. select_poses() picks M of many candidate poses so that together they
determine the model's parameters best (D-optimal design: largest det(J^T J) of the
scaled identification Jacobian; `casadical plan-poses` does the same). Then a
simulated robot shows what it buys: the same number of measured poses, planned
versus random, and the error each calibration leaves on poses it never saw.

Run from the repository root:  python examples/05_plan_poses.py
"""

import numpy as np

from casadical import Model, calibrate, load_robot
from casadical.data import Effects, sample_poses, simulate
from casadical.planning import select_poses

robot = load_robot("ys100")
model = Model(robot, "kinematic+compliance")      # the model the poses must identify

# Candidates: 2,000 reachable poses within the joint limits, tool point 0.2 m above the floor
# (`casadical candidates ys100 -n 2000 --floor-z 0.2`). In practice: poses your cell can reach.
candidates = sample_poses(robot, 2000, np.random.default_rng(0), floor_z=0.2)

planned = select_poses(model, candidates, 40, "d-optimal")
random = select_poses(model, candidates, 40, "random", seed=0)
print("D-optimal:", planned.summary(), sep="\n")
print("\nrandom, for comparison:", random.summary(), sep="\n")

# What it buys: simulated robots (random link errors, compliant joints 2 and 3) measured at each set of
# 40 poses and calibrated. Judged against the truth, which a simulation knows: how far the calibrated
# model's tool point is from the true robot's over 300 other poses, and how well k2 is determined.
print("\ncalibrated on 40 measured poses (mean of 3 simulated robots):")
print("  poses       model error vs truth   std of k2")
for name, plan in [("D-optimal", planned), ("random", random)]:
    errors, k2_std = [], []
    for seed in range(3):
        held_out, truth = simulate(robot, 300, Effects(stiffness={2: 2e6, 3: 1.5e6}), seed=10 + seed)
        measured, _ = simulate(robot, candidates[plan.indices], truth=truth, seed=20 + seed)
        res = calibrate(robot, measured, "kinematic+compliance", solver="lm", warn=False)
        errors.append(np.linalg.norm(res.predict(held_out) - truth.predict(held_out), axis=1).mean() * 1e3)
        k2_std.append(res.stiffness()[2][1] / res.stiffness()[2][0] * 100)
    print(f"  {name:<10}  {np.mean(errors):.4f} mm              {np.mean(k2_std):.2f} %")
