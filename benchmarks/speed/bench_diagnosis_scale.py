"""A diagnosis of 20,000 poses against the same arm's of 2,000: CPU, wall and peak memory (issue 37).

The independent truth (tests/truth) simulates an arm that is not built in (``arm7-dh``: 7 axes, DH, beta on
joint 4) with two hidden effects, the compliance of joint 2 and a gear error of joint 3 (9 cycles per turn,
0.01 deg), as the hidden-effect matrix sizes them (tests/helpers/hidden.py). Each size is diagnosed in its own
process (``casadical diagnose ARM.toml cal.csv --validate val.csv --json``, no HTML), after one untimed run that
fills the cache of compiled functions; CPU is user + system of the process and its children, peak memory its
maximum resident set. Target: the 20,000-pose diagnosis runs, and costs at most 10x the 2,000-pose one.

    python benchmarks/speed/bench_diagnosis_scale.py                   # 2,000 and 20,000 poses
    python benchmarks/speed/bench_diagnosis_scale.py --sizes 2000 5000 --robot arm5
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from tests.helpers.arms import to_toml  # noqa: E402
from tests.helpers.hidden import Case, make_data, robot_doc  # noqa: E402
from tests.truth import Arm, Effects, TrueRobot, sample  # noqa: E402

#: run in the child: the diagnosis, then its own CPU (with its children's) and peak memory, as JSON on stderr
CHILD = """
import json, resource, sys
from casadical.cli import main
code = main(sys.argv[1:])
me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"code": code, "cpu_s": me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime,
                  "peak_mb": max(me.ru_maxrss, kids.ru_maxrss) / 1024}), file=sys.stderr)
"""


def run(args: list[str], env: dict, cwd: Path) -> dict:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", CHILD, *args], env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(args)}\n{r.stderr[-3000:]}")
    out = json.loads(r.stderr.strip().splitlines()[-1])
    out["wall_s"], out["stdout"] = wall, r.stdout
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2000, 20000])
    ap.add_argument("--robot", default="arm7-dh")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; {args.robot}, compliance of joint 2 and "
          "a gear error of joint 3 hidden\n")
    print("| calibration poses | validation poses | CPU | wall | peak memory | named |")
    print("|---:|---:|---:|---:|---:|---|")
    base = None
    with tempfile.TemporaryDirectory(prefix="diag-scale-") as tmp:
        env = dict(os.environ, PYTHONPATH=str(ROOT), CASADICAL_CACHE=str(Path(tmp) / "cache"))
        doc = robot_doc(args.robot)
        (Path(tmp) / "arm.toml").write_text(to_toml(doc))
        true = TrueRobot(Arm.from_dict(doc))     # the joint 2 torque that sizes the compliance
        tau2 = np.abs(true.state(sample(true, 200, np.random.default_rng(0), floor_z=None)).drive_torque).max(axis=0)[1]
        effects = Effects(stiffness={2: tau2 / 0.4e-3}, periodic=[(3, 9, math.radians(0.01), 0.7)])
        for n in args.sizes:
            folder = Path(tmp) / str(n)
            folder.mkdir()
            c = Case(args.robot, "compliance and gear error", args.seed, effects, set())
            make_data(c, n_cal=n, n_val=max(1000, n // 10), folder=folder)
            cmd = ["diagnose", str(Path(tmp) / "arm.toml"), "cal.csv", "--validate", "val.csv", "--json",
                   "report.json", "--force"]
            run(cmd, env, folder)                       # fills the cache
            r = run(cmd, env, folder)
            rep = json.loads((folder / "report.json").read_text())
            named = ", ".join(f"{f['cause']}" + (f" {f['joint']}" if f.get("joint") else "")
                              + (f" h{f['harmonic']}" if f.get("harmonic") else "")
                              for f in rep["findings"] if f["cause"] not in ("geometric",))
            print(f"| {n:,} | {max(1000, n // 10):,} | {r['cpu_s']:.1f} s | {r['wall_s']:.1f} s | "
                  f"{r['peak_mb']:.0f} MB | {named} |", flush=True)
            base = base or r
        if len(args.sizes) > 1:
            print(f"\n{args.sizes[-1]:,} poses cost {r['cpu_s'] / base['cpu_s']:.1f}x the CPU of {args.sizes[0]:,} "
                  f"(target <= 10x); load average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
