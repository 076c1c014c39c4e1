"""Full-pose against position-only calibration on the real UR10 data (series A and B, 6-DoF probe).

For each source series and seed, N random poses of it are calibrated twice, on the positions alone
(``--position-only``) and on the full pose (position and orientation weighted by their noise scales
from the data); both are judged on poses they never saw:

- in-series: every other pose of the source series;
- across, base re-estimated: the calibration taken to the other series with its base pose (and, full
  pose, the probe's mounting) re-estimated on 30 of its poses (``calibrate CAL.json OTHER.csv --model
  base``), judged on every other pose there;
- across, geometry refitted: the same with the geometry refitted on N of its poses (``--model
  kinematic``), judged on the rest.

Position error: distance from the predicted to the measured point. Orientation error: angle of
R_meas^T R_pred. A position-only calibration has no probe mounting: for its orientation error the
mounting alone is fitted in closed form to the orientations of the poses it was calibrated on (the
chordal mean of flange^T R_meas, what a position-only calibration can offer), nothing else changes.

Usage::

    python benchmarks/studies/study_fullpose.py                       # A and B, N = 300, seeds 0..2 (~1 min)
    python benchmarks/studies/study_fullpose.py --seeds 0 --model kinematic+compliance[2,3] --json out.json
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from casadical import calibrate, load_robot  # noqa: E402
from casadical.calibration import mean_mounting  # noqa: E402
from casadical.data import Measurements  # noqa: E402
from casadical.result import rotation_angles_between  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"
BASE_POSES = 30


def split(data: Measurements, n: int, seed: int) -> tuple[Measurements, Measurements]:
    idx = np.sort(np.random.default_rng(seed).permutation(len(data))[:n])
    rest = np.setdiff1d(np.arange(len(data)), idx)
    return data.subset(idx), data.subset(rest)


def errors(res, fitted_on: Measurements, judge: Measurements) -> dict:
    """Mean and rms position (mm) and orientation (deg) errors of ``res`` on ``judge``."""
    e = res.errors(judge) * 1000
    if res.has_orientation:
        a = np.degrees(res.orientation_errors(judge))
    else:   # the mounting alone, in closed form on the poses the calibration was fitted to
        m = res.model
        flange = lambda d: m.flange_rotation(d.q, res.parameters.values, m.covariates(d), res.base0)  # noqa: E731
        M = mean_mounting(flange(fitted_on), fitted_on.rotations)
        a = np.degrees(rotation_angles_between(judge.rotations, flange(judge) @ M))
    return {"pos_mean_mm": float(e.mean()), "pos_rms_mm": float(np.sqrt((e ** 2).mean())),
            "ori_mean_deg": float(a.mean()), "ori_rms_deg": float(np.sqrt((a ** 2).mean())), "n": len(e)}


def one(robot, series: dict[str, Measurements], src: str, other: str, model: str, n: int, seed: int,
        solver: str) -> list[dict]:
    cal, val = split(series[src], n, seed)
    base_fit, base_judge = split(series[other], BASE_POSES, seed)
    refit, refit_judge = split(series[other], n, seed)
    rows = []
    for how, position_only in (("position-only", True), ("full pose", False)):
        t0 = time.perf_counter()
        res = calibrate(robot, cal, model, solver, warn=False, position_only=position_only)
        moved = calibrate(res, base_fit, "base", solver, warn=False, position_only=position_only)
        again = calibrate(res, refit, "kinematic", solver, warn=False, position_only=position_only)
        rows.append({"source": src, "seed": seed, "calibration": how, "model": res.model.spec,
                     "in_series": errors(res, cal, val), "base": errors(moved, base_fit, base_judge),
                     "refit": errors(again, refit, refit_judge), "time_s": time.perf_counter() - t0,
                     "sigma_mm": res.loss.sigma * 1000,
                     "sigma_deg": float(np.degrees(res.loss.sigma_rot)) if not position_only else None})
    return rows


def table(rows: list[dict]) -> str:
    out = ["| source | seed | calibration | in-series mm | in-series deg | base re-est. mm | base re-est. deg "
           "| geometry refit mm | geometry refit deg |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        cells = [f"{r[k]['pos_mean_mm']:.4f} | {r[k]['ori_mean_deg']:.4f}" for k in ("in_series", "base", "refit")]
        out.append(f"| {r['source'].upper()} | {r['seed']} | {r['calibration']} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def ranges(rows: list[dict]) -> str:
    """Smallest-largest over the seeds, per source series and calibration (the table of docs/ur10.md)."""
    out = ["| calibrated on -> other | calibration | in-series mm | in-series deg | base re-est. mm | base re-est. deg "
           "| geometry refit mm | geometry refit deg |", "|---|---|---|---|---|---|---|---|"]
    for src in dict.fromkeys(r["source"] for r in rows):
        for how in ("position-only", "full pose"):
            sel = [r for r in rows if r["source"] == src and r["calibration"] == how]
            cells = [f"{min(r[k][m] for r in sel):.4f}-{max(r[k][m] for r in sel):.4f}"
                     for k in ("in_series", "base", "refit") for m in ("pos_mean_mm", "ori_mean_deg")]
            other = "b" if src == "a" else "a"
            out.append(f"| {src.upper()} -> {other.upper()} | {how} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--series", nargs="+", default=["a", "b"], choices=["a", "b"], help="source series")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("-n", "--poses", type=int, default=300, help="calibration poses (default: %(default)s)")
    ap.add_argument("--model", default="kinematic", help="model specification (default: %(default)s)")
    ap.add_argument("--solver", default="lm", choices=["lm", "ipopt"])
    ap.add_argument("--json", help="write the rows as JSON")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    robot = load_robot("ur10")
    series = {s: Measurements.read_csv(DATA / f"series_{s}.csv", n_joints=6) for s in ("a", "b")}
    rows = []
    t0 = time.perf_counter()
    for src in args.series:
        for seed in args.seeds:
            rows += one(robot, series, src, "b" if src == "a" else "a", args.model, args.poses, seed, args.solver)
            print(f"  {src.upper()} seed {seed} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    print(f"\nmodel {args.model}, {args.poses} calibration poses, mean errors on poses never fitted "
          "(position mm, orientation deg):\n")
    print(table(rows))
    print(f"\nranges over the seeds ({', '.join(map(str, args.seeds))}), smallest-largest mean error:\n")
    print(ranges(rows))
    if args.json:
        Path(args.json).write_text(json.dumps({"model": args.model, "poses": args.poses, "rows": rows}, indent=1))
    print(f"\n{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
