"""The open world: effects no catalogue cause describes, on arms that are not built in (docs/diagnosis.md).

Each effect of ``tests/helpers/hidden.py`` OUTSIDE is made by the independent truth (``tests/truth``) on
arm4 (MDH, no beta), arm5 (DH, beta on 3) and arm7-dh (DH, 7 axes), seeds 0-2, 80 calibration and 200
validation poses, 0.02 mm noise, and diagnosed with the default settings. For each arm and effect, over
the three seeds:

- **located**: the structure screen's strongest structure is where the effect lives (the joint, covariate
  and effect of docs/formats.md section 4 that the case states); for an effect the catalogue now holds, the
  cause is named exactly instead;
- **named**: seeds in which the final model names a catalogue cause the truth does not hold (a stand-in);
- **bad shots**: seeds in which a pose is called a likely bad measurement (the data hold none);
- **final / kinematic**: the final model's validation mean over the kinematic model's, mean of the seeds.

Noise alone (``none``) must give no structure. About two minutes on 2 cores::

    python benchmarks/studies/study_open_world.py
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[2]))  # the tests' helpers, after any casadical on PYTHONPATH

from casadical.diagnosis import DiagnosisSettings, diagnose  # noqa: E402
from tests.helpers import hidden  # noqa: E402

ROBOTS = ("arm4", "arm5", "arm7-dh")
SEEDS = (0, 1, 2)


def one(robot: str, effect: str, seed: int) -> dict:
    c = hidden.case(robot, effect, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c)
        report = diagnose(rob, cal, val, DiagnosisSettings(seed=seed, session_tools=c.sessions))
    structures = [(f.candidate.joint, f.structure["covariate"], f.structure["effect"]) for f in report.findings
                  if f.structure]
    named = hidden.named(report)
    return {"located": (structures[:1] == [c.unexplained]) if c.unexplained else named == set(c.expected),
            "structures": structures, "stand_in": bool(named - set(c.expected)),
            "bad": any("likely bad measurement" in n for n in report.notes),
            "ratio": report.final_validation.mean_mm / report.kinematic_validation.mean_mm}


def main() -> None:
    t0 = time.perf_counter()
    print("### Effects outside the catalogue\n")
    print("| effect | arm | located | named a stand-in | called bad shots | final / kinematic |")
    print("|---|---|---|---|---|---|")
    for effect in hidden.OUTSIDE:
        for robot in ROBOTS:
            runs = [one(robot, effect, s) for s in SEEDS]
            print(f"| {effect} | {robot} | {sum(r['located'] for r in runs)} of 3 | "
                  f"{sum(r['stand_in'] for r in runs)} of 3 | {sum(r['bad'] for r in runs)} of 3 | "
                  f"{np.mean([r['ratio'] for r in runs]):.2f} |", flush=True)
    print("\n### Noise alone\n")
    print("| arm | seeds with structure | named |")
    print("|---|---|---|")
    for robot in ROBOTS:
        runs = [one(robot, "none", s) for s in SEEDS]
        print(f"| {robot} | {sum(bool(r['structures']) for r in runs)} of 3 | {sum(r['stand_in'] for r in runs)} "
              "of 3 |", flush=True)
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
