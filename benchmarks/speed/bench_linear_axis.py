"""A 6-axis arm on a linear track diagnosed, against the same arm without the track: CPU time, same run.

    python benchmarks/speed/bench_linear_axis.py                  # 2,000 + 500 poses, 3 runs each, ~5 min
    python benchmarks/speed/bench_linear_axis.py --poses 300 --repeats 1

Robots: the YS100 (``problems/robots/ys100.toml``) and the YS100 on a 4 m track
(``problems/robots/track6.toml``: joint 1 the track, the arm's joints 2-7). Data:
the independent truth (``tests/truth``) of each, drawn geometry errors, the
same hidden effects of the arm on both (its shoulder's compliance, 0.4 mrad at
its largest torque; a gear error of its elbow, 9 cycles per turn, 0.01 deg;
an encoder scale of its joint 3, 400 ppm; joints 2, 3, 4 of the YS100, 3, 4,
5 of the track's), the track itself perfect; the same number of calibration
poses (``--poses``) and validation poses (500), seed 0. Each diagnosis
(``diagnose`` with its defaults) runs in a fresh process after one run of
each has filled the cache of compiled functions; the figure is its CPU time
(user + system of the process, every thread), median of ``--repeats`` runs,
the two robots in turn. The ratio track / arm alone is the figure of issue
39 (target: at most 1.5).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ROBOTS = {"arm alone": "ys100", "arm on a track": "track6"}


def one(robot: str, poses: int, seed: int = 0) -> dict:
    """Diagnose ``robot`` on truth data in this process; its CPU time (s) and what it named."""
    import warnings

    import numpy as np

    from casadical.data import Measurements
    from casadical.diagnosis import DiagnosisSettings, diagnose
    from casadical.robot import robot_from_dict
    from tests.helpers import hidden
    from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

    doc = hidden.robot_doc(robot)
    arm = Arm.from_dict(doc)
    shift = 1 if arm.links[0].prismatic else 0      # the arm's joints after the track
    rng = np.random.default_rng(seed)
    t = TrueRobot(arm)
    tau = np.abs(t.state(sample(t, 200, np.random.default_rng(0), floor_z=None)).drive_torque).max(axis=0)
    eff = Effects(stiffness={2 + shift: tau[1 + shift] / 0.4e-3}, periodic=[(3 + shift, 9, math.radians(0.01), 0.7)],
                  encoder_scale={4 + shift: 4e-4})
    true = TrueRobot.draw(arm, eff, rng)
    session = Session("A", base_xyz=hidden.BASE_XYZ, base_rpy=hidden.BASE_RPY)
    sets = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n in (poses, 500):
            shots = measure(true, sample(true, n, rng, floor_z=None), rng, session=session)
            path = shots.write_csv(Path(os.environ.get("TMPDIR", "/tmp")) / f"bench-linear-{robot}-{n}.csv")
            sets.append(Measurements.read_csv(path, n_joints=arm.n, require_positions=True))
        rob = robot_from_dict(doc, robot)
        t0 = time.process_time()
        report = diagnose(rob, sets[0], sets[1], DiagnosisSettings(seed=seed))
        cpu = time.process_time() - t0
    named = sorted(f.candidate.label(short=True) for f in report.findings
                   if f.in_model and f.cause not in ("geometric", "unexplained"))
    return {"cpu_s": cpu, "named": named, "validation_mm": report.steps[-1].validation.mean_mm}


def run(robot: str, poses: int) -> dict:
    """:func:`one` in a fresh process."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"))
    out = subprocess.run([sys.executable, __file__, "--one", robot, "--poses", str(poses)], cwd=ROOT, env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=2000, help="calibration poses (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each robot (default: %(default)s)")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one, args.poses)))
        return
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; {args.poses} calibration + 500 "
          "validation poses, the same hidden effects of the arm")
    for label, robot in ROBOTS.items():       # fill the cache of compiled functions
        run(robot, args.poses)
    runs: dict[str, list] = {label: [] for label in ROBOTS}
    for _ in range(args.repeats):
        for label, robot in ROBOTS.items():
            runs[label].append(run(robot, args.poses))
    cpu = {label: statistics.median(r["cpu_s"] for r in rs) for label, rs in runs.items()}
    print(f"{'robot':<16} {'CPU s (median)':>15} {'runs':>22}  {'validation mm':>13}  named")
    for label, rs in runs.items():
        each = ", ".join(f"{r['cpu_s']:.1f}" for r in rs)
        print(f"{label:<16} {cpu[label]:>15.1f} {each:>22}  {rs[-1]['validation_mm']:>13.4f}  "
              + ", ".join(rs[-1]["named"]))
    print(f"ratio, arm on a track / arm alone: {cpu['arm on a track'] / cpu['arm alone']:.2f} (target <= 1.5)")


if __name__ == "__main__":
    main()
