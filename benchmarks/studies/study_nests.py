"""A tool of several points on the independent truth: three reflector nests, two balls (issue 45 item 2).

For each seed, on the six-axis DH arm of tests/helpers/arms.py (not built in), with the data of
tests/helpers/nests.py (each nest's true offset its nominal plus 2 mm per axis; the tracker's noise 20 um per
axis):

1. **three nests, one calibration**: 40 poses x 3 nests calibrated (``calibrate``'s default, IPOPT, model
   kinematic), 60 held out: the held-out mean against the noise floor (the truth's own error on those rows), the
   parameters at a bound, the largest error of a distance between two nests (um);
2. **the same without [tool.NAME]** in the robot file (every nest starting at ``[tool]``, unbounded);
3. **a hidden encoder scale** of joint 2 (400 ppm): what ``diagnose`` names (LM, its default), its final
   held-out mean against the noise floor, the nominal model's baseline;
4. **two balls** in a fixture's two sockets, three placements calibrated and two held out: their consistency
   against the contact noise's (10 um per axis), the fixture's distance error.

The test suite asserts the same on each seed (tests/calibration/test_tool_points.py,
tests/diagnosis/test_nests.py); this script prints the figures. About 30 s per seed on 2 cores.

Usage::

    python benchmarks/studies/study_nests.py               # seeds 0, 1, 2
    python benchmarks/studies/study_nests.py --seeds 0 5
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import itertools  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from casadical import calibrate  # noqa: E402
from casadical.diagnosis import DiagnosisSettings, diagnose  # noqa: E402
from casadical.rows import read_fixture_file  # noqa: E402
from casadical.stats import inside_bounds  # noqa: E402
from tests.helpers import hidden  # noqa: E402
from tests.helpers.nests import three_nests, two_balls  # noqa: E402
from tests.truth import Effects  # noqa: E402


def quiet(f, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return f(*args, **kw)


def at_bounds(res) -> int:
    return len(inside_bounds(res.parameters, [p.name for p in res.parameters if not p.fixed]))


def distance_error_um(res, points) -> float:
    """The largest error of a distance between two tool points, fitted against true (um)."""
    fit = {k: np.array([res.parameters[f"tool_{c}:{k}"].value for c in "xyz"]) for k in points}
    return max(abs(np.linalg.norm(fit[a] - fit[b]) - np.linalg.norm(points[a] - points[b])) * 1e6
               for a, b in itertools.combinations(points, 2))


def nests_row(seed: int, declared: bool) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        data = three_nests(seed, tmp, declared=declared)
        robot, cal, val = data.read()
        res = quiet(calibrate, robot, cal, "kinematic", "ipopt")
        mean = res.stats(val).mean_mm
        return (f"| {seed} | {'[tool.NAME]' if declared else '[tool] only'} | {mean:.4f} | {data.floor_mm:.4f} | "
                f"{mean / data.floor_mm:.2f} | {at_bounds(res)} | {distance_error_um(res, data.points):.1f} |")


def diagnosis_row(seed: int) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        data = three_nests(seed, tmp, Effects(encoder_scale={2: 4e-4}))
        robot, cal, val = data.read()
        report = quiet(diagnose, robot, cal, val, DiagnosisSettings(seed=seed))
        named = ", ".join(f"{c} {j}" for c, j, _, _ in sorted(hidden.named(report), key=str)) or "nothing"
        v = hidden.judge(report, {("encoder_scale", 2, None, "robot")})
        mean = report.final_validation.mean_mm
        return (f"| {seed} | {named} | {'exact' if v.exact else v.text()} | {mean:.4f} | {data.floor_mm:.4f} | "
                f"{mean / data.floor_mm:.2f} | {report.steps[0].validation.mean_mm:.3f} |")


def balls_row(seed: int) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        data = two_balls(seed, tmp)
        robot, cal, val = data.read()
        fixture = read_fixture_file(data.folder / "fixture.toml")
        res = quiet(calibrate, robot, cal.with_fixtures(fixture), "kinematic", "ipopt")
        held = res.stats(val.with_fixtures(fixture)).touch
        return (f"| {seed} | {held['consistency_mm']:.4f} | {data.floor_mm:.4f} | "
                f"{held['consistency_mm'] / data.floor_mm:.2f} | {held['distance_error_mm']:.4f} | {at_bounds(res)} | "
                f"{distance_error_um(res, data.points):.1f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    args = ap.parse_args(argv)
    print("three nests, one calibration (IPOPT): held-out mean against the noise floor (mm)\n")
    print("| seed | robot file | held-out mean | noise floor | ratio | at a bound | nest distances, worst (um) |")
    print("|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        for declared in (True, False):
            print(nests_row(seed, declared), flush=True)
    print("\na hidden encoder scale of joint 2 (400 ppm) through three nests: diagnose (mm)\n")
    print("| seed | named | verdict | final held-out mean | noise floor | ratio | nominal baseline |")
    print("|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        print(diagnosis_row(seed), flush=True)
    print("\ntwo balls in a fixture's sockets, two placements held out (mm)\n")
    print("| seed | consistency | contact noise's | ratio | distance error | at a bound | ball distance (um) |")
    print("|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        print(balls_row(seed), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
