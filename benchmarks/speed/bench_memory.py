"""Peak memory of a kinematic calibration against the number of poses.

Simulated UR10 poses (geometric errors, 20 um noise) are written to a
measurement CSV; a fresh Python process per size and solver then reads the
file (``Measurements.read_csv``) and runs ``calibrate`` with the robust loss
(identifiability analysis, Kabsch start, robust loop, uncertainty, coverage
record: everything the command does), and reports its peak resident memory
(``resource.getrusage(RUSAGE_SELF).ru_maxrss``). The baseline in the same
run is a process that only imports casadical and reads the file, so the
difference is what the calibration itself holds.

Usage::

    python benchmarks/speed/bench_memory.py                       # 10k, 50k, 200k poses; lm and ipopt
    python benchmarks/speed/bench_memory.py --sizes 10000 --solvers lm

BLAS runs single-threaded (``OPENBLAS_NUM_THREADS=1`` unless set).
Target (issue 10): 200,000 poses within 1 GB, growing linearly and modestly.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

TARGET_MB = 1000.0

SIMULATE = """
import sys
from casadical import load_robot
from casadical.data._simulate import simulate
data, _ = simulate(load_robot("ur10"), int(sys.argv[1]), seed=int(sys.argv[2]))
data.write_csv(sys.argv[3], overwrite=True)
"""

MEASURE = """
import json, resource, sys, time
t0 = time.perf_counter()
from casadical import load_robot, calibrate
from casadical.data import Measurements
robot = load_robot("ur10")
data = Measurements.read_csv(sys.argv[1], n_joints=6, require_positions=True)
t1 = time.perf_counter()
out = {"read_s": t1 - t0}
if sys.argv[2] != "none":
    res = calibrate(robot, data, "kinematic", sys.argv[2], warn=False)
    out.update(rms_mm=res.calibration.rms_mm, iterations=res.solver.iterations, status=res.solver.status)
out["time_s"] = time.perf_counter() - t1
out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def run(code: str, *args) -> str:
    r = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"child failed:\n{r.stderr}")
    return r.stdout


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 50_000, 200_000])
    ap.add_argument("--solvers", nargs="+", default=["lm", "ipopt"], choices=["lm", "ipopt", "gn", "auto"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="save the rows")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}; UR10 kinematic, robust loss (pseudo-Huber); peak RSS per "
          "process (MB)\n")
    print("| poses | CSV (MB) | read only (baseline) | solver | peak | peak - baseline | per 1k poses | time | "
          "RMS (mm) | within 1 GB |")
    print("|---:|---:|---:|---|---:|---:|---:|---:|---:|---|")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for N in args.sizes:
            csv = Path(tmp) / f"ur10_{N}.csv"
            run(SIMULATE, N, args.seed, csv)
            base = json.loads(run(MEASURE, csv, "none"))
            for solver in args.solvers:
                m = json.loads(run(MEASURE, csv, solver))
                extra = m["peak_mb"] - base["peak_mb"]
                row = {"poses": N, "csv_mb": csv.stat().st_size / 1e6, "baseline_mb": base["peak_mb"],
                       "solver": solver, **m, "extra_mb": extra, "load": os.getloadavg()[0]}
                rows.append(row)
                print(f"| {N:,} | {row['csv_mb']:.1f} | {base['peak_mb']:.0f} | {solver} | {m['peak_mb']:.0f} | "
                      f"{extra:.0f} | {1000 * extra / N:.2f} | {m['time_s']:.1f} s | {m['rms_mm']:.4f} | "
                      f"{'yes' if m['peak_mb'] <= TARGET_MB else 'NO'} |", flush=True)
    print(f"\nload average {os.getloadavg()[0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
