"""A robot program filtered with a calibration: the shop floor's deliverable.

What it teaches: `casadical compensate CAL.json PROGRAM --out FILTERED` takes the robot program itself (here a
URScript for the UR10; KUKA KRL .src/.dat and ABB RAPID .mod work the same way) and replaces each target by the
one at which the CALIBRATED robot reaches what the program meant, keeping every other byte:

- a joint target means the tool pose the nominal model reaches there: it becomes the joints at which the
  calibrated model's tool is there;
- a Cartesian target (p[x, y, z, rx, ry, rz]) means the pose the nominal controller reaches: it becomes the pose
  the nominal controller turns into those corrected joints.

The calibration here measured positions alone, so the tool point is held and the orientation left as it falls
(--hold-orientation would hold it). The report lists each target's miss before (mm) and how much it changed.

Run from the repository root:  python examples/09_program.py
"""

import difflib
import json
import tempfile
from pathlib import Path

import numpy as np

from casadical import Measurements, calibrate, load_robot
from casadical.cli import main
from casadical.model import Model, pose_to_base0
from casadical.programs import matrix_rotvec

robot = load_robot("ur10")
data = Measurements.read_csv("problems/datasets/ur10-ipa/series_b.csv", n_joints=robot.n, require_positions=True)
rng = np.random.default_rng(0)
order = rng.permutation(len(data))
cal_poses, program_poses = data.subset(np.sort(order[:300])), data.subset(np.sort(order[300:306]))

with tempfile.TemporaryDirectory() as tmp:
    tmp = Path(tmp)
    calibrate(robot, cal_poses, "kinematic", solver="lm", position_only=True, warn=False).save(tmp / "cal.json")

    # The program: three joint targets and three poses (their nominal tool poses, a 120 mm tool), as a
    # programmer writes them.
    q = program_poses.q
    tool = np.eye(4)
    tool[2, 3] = 0.12
    nominal = Model(robot, "nominal", jit=False)
    identity = pose_to_base0(np.eye(4))
    lines = ["def cell():", "  set_tcp(p[0.0, 0.0, 0.12, 0.0, 0.0, 0.0])"]
    for i, row in enumerate(q):
        if i < 3:
            lines.append("  movej([" + ", ".join(f"{v:.5f}" for v in row) + "], a=1.4, v=1.05)")
        else:
            params = nominal.parameters.values.copy()
            params[nominal.parameters.index("tool_z")] = 0.12
            xyz = nominal.predict(row[None], params, None, identity)[0]
            rv = matrix_rotvec(nominal.flange_rotation(row[None], params, None, identity)[0])
            lines.append("  movel(p[" + ", ".join(f"{v:.6f}" for v in [*xyz, *rv]) + "], a=1.2, v=0.25)")
        lines.append("  sleep(0.5)")
    lines.append("end")
    (tmp / "cell.script").write_text("\n".join(lines) + "\n")

    main(["compensate", str(tmp / "cal.json"), str(tmp / "cell.script"), "--out", str(tmp / "filtered.script"),
          "--json", str(tmp / "report.json")])
    print("\nthe lines that changed (every other byte is kept):")
    before, after = (tmp / "cell.script").read_text(), (tmp / "filtered.script").read_text()
    for line in difflib.unified_diff(before.splitlines(), after.splitlines(), lineterm="", n=0):
        if line.startswith(("-  ", "+  ")):
            print(line[:110])
    report = json.loads((tmp / "report.json").read_text())
    print(f"filtered program: {report['corrected']} of {len(report['targets'])} targets corrected")
