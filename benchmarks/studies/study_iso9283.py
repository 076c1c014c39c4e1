"""ISO 9283 on the bundled series D of the UR10 data, before and after compensation: the figures docs/guide.md
("ISO 9283") quotes.

A kinematic calibration of series B (all 1,495 poses), then ``casadical iso9283`` of series D with it: the mean and
largest AP_p over the 632 poses, and the mean over the 70 cubes of each cube's largest, before (the nominal model)
and after compensation as the calibration predicts it.

    python benchmarks/studies/study_iso9283.py
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "problems" / "datasets" / "ur10-ipa"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cal = Path(tmp) / "b.json"
        run = [sys.executable, "-m", "casadical"]
        subprocess.run(run + ["calibrate", "ur10", str(DATA / "series_b.csv"), "--model", "kinematic", "--out",
                              str(cal), "--quiet"], check=True, capture_output=True)
        out = subprocess.run(run + ["iso9283", str(cal), str(DATA / "series_d.csv"), "--json", "-"], check=True,
                             capture_output=True, text=True).stdout
    rep = json.loads(out)
    for state in rep["states"]:
        poses = np.array([p["AP_p"] for p in rep[state]["poses"]])
        cubes = np.array([c["AP_p"] for c in rep[state]["cubes"] if c["cube"] != "0"])
        print(f"{state:18s} AP_p per pose mean {poses.mean():.2f} mm, max {poses.max():.2f} mm; "
              f"per cube largest, mean over {len(cubes)} cubes {cubes.mean():.2f} mm")


if __name__ == "__main__":
    main()
