"""The figures docs/guide.md quotes that its own commands do not print, on the bundled UR10 series B.

Both on the README's split (``casadical split series_b.csv -n 300 --seed 0``: 300 calibration poses, the
other 1,195 held out):

1. AIC and BIC of ``kinematic+compliance``, ``kinematic+joint_compliance[2,3]`` and ``kinematic``
   (positions, ``calibrate --position-only --validate``), with their validation mean (the guide's
   "What the numbers say");
2. the mean position error on the held-out poses of URDFs read by yourdfpy (an independent library):
   the README job's final model (``diagnose``) exported as ``export`` writes it by default (the
   geometry refitted to reproduce the full model), and as fitted (``--as-fitted``), against a kinematic
   calibration of the same poses exported (the guide's "Take the calibration to the robot").

    python benchmarks/docs/guide_figures.py           # about 30 s on 2 cores

``benchmarks/docs/regenerate_docs.py`` copies the tables into the guide and checks them.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SERIES_B = ROOT / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"


def cli(*args: str) -> None:
    """Run a casadical command in this process, quietly; fail loudly."""
    from casadical.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    if code != 0:
        raise SystemExit(f"casadical {' '.join(args)} exits with {code}:\n{out.getvalue()}\n{err.getvalue()}")


def urdf_mean_mm(path: Path, data) -> float:
    """Mean distance (mm) between the URDF's tool point (yourdfpy) and the measured points."""
    import yourdfpy

    u = yourdfpy.URDF.load(str(path), load_meshes=False)
    xyz = []
    for q in data.q:
        u.update_cfg(q)
        xyz.append(u.get_transform("tool_point", "measurement_frame")[:3, 3])
    return float(np.mean(np.linalg.norm(np.array(xyz) - data.xyz, axis=1)) * 1000)


def main() -> int:
    from casadical.data import Measurements

    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory(prefix="casadical-guide-figures-") as tmp:
        t = Path(tmp)
        cal, val = t / "cal.csv", t / "val.csv"
        cli("split", str(SERIES_B), "-n", "300", "--seed", "0", "--out-cal", str(cal), "--out-val", str(val))

        print("AIC and BIC on the 300 calibration poses of series B (positions, `calibrate --position-only`), "
              "validation mean on the other 1,195:\n")
        print("| model | free | AIC | BIC | validation mean mm |")
        print("|---|---|---|---|---|")
        for spec in ("kinematic+compliance", "kinematic+joint_compliance[2,3]", "kinematic"):
            out = t / f"{len(spec)}.json"
            cli("calibrate", "ur10", str(cal), "--model", spec, "--validate", str(val), "--position-only",
                "--out", str(out))
            d = json.loads(out.read_text())
            s = d["statistics"]
            print(f"| `{spec}` | {s['n_parameters']} | {s['aic']:.2f} | {s['bic']:.2f} "
                  f"| {d['validation']['mean_mm']:.4f} |")

        final, kin = t / "final.json", t / "kinematic.json"
        cli("diagnose", "ur10", str(cal), "--validate", str(val), "--json", str(t / "report.json"), "--out",
            str(final), "--quiet")
        cli("calibrate", "ur10", str(cal), "--model", "kinematic", "--out", str(kin))
        cli("export", str(final), "--urdf", str(t / "refitted.urdf"), "--quiet")
        cli("export", str(final), "--urdf", str(t / "as_fitted.urdf"), "--as-fitted", "--quiet")
        cli("export", str(kin), "--urdf", str(t / "kinematic.urdf"), "--quiet")
        data = Measurements.read_csv(val, n_joints=6, require_positions=True)
        print("\nURDF read by yourdfpy: mean position error on the 1,195 held-out poses of the README split\n")
        print("| URDF | held-out mean mm |")
        print("|---|---|")
        for label, name in (("the README job's final model, `export` (geometry refitted to the full model)",
                             "refitted"),
                            ("the same, `export --as-fitted` (the geometry as fitted with the other terms)",
                             "as_fitted"),
                            ("a kinematic calibration of the same 300 poses, `export`", "kinematic")):
            print(f"| {label} | {urdf_mean_mm(t / f'{name}.urdf', data):.4f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
