"""Cross-series study on the real UR10 data: do the diagnosis' findings hold up on another series?

Series A and B (problems/datasets/ur10-ipa) are two measurement sessions of one robot, on different
days with the tracker elsewhere. For each source series and seed:

1. ``diagnose`` on N random poses of the source series (the rest of it judges in-series: validation
   poses never fitted);
2. the final model and the plain kinematic model are taken to the other series two ways: the base pose
   re-estimated on 30 of its poses (a new tracker set-up; every other pose judges), and the geometry
   refitted on N of its poses with the findings frozen (the rest judges);
3. every finding (and every structure kept out of the model as unexplained) is labelled by whether it
   transferred: the model with it beats the model without it, both ways.

``--before DIR`` also takes the final models of the diagnosis before this change (calibration JSONs
written by the old code, one per source series and seed: before_<s><N>_s<seed>_final.json) to the other
series the same way, for the side-by-side table of docs/diagnosis.md.

Usage::

    python benchmarks/study_transfer.py                       # A and B, N = 300, seeds 0..2 (~5 min)
    python benchmarks/study_transfer.py --seeds 0 --series b  # one run
    python benchmarks/study_transfer.py --json out.json --before /path/to/old/finals
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

from casadical import load_calibration, load_robot  # noqa: E402
from casadical.data import Measurements  # noqa: E402
from casadical.diagnosis import DiagnosisSettings, diagnose  # noqa: E402
from casadical.diagnosis.transfer import Split, travel  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "problems" / "datasets" / "ur10-ipa"


def label(f: dict) -> str:
    parts = [f["cause"]]
    if f.get("joint") is not None:
        parts.append(f"j{f['joint']}")
    if f.get("harmonic") is not None:
        parts.append(f"h{f['harmonic']}")
    if f.get("source") == "motion":
        parts.append("(motion)")
    return " ".join(parts)


def one(robot, src: Measurements, other: Measurements, name: str, n: int, seed: int, before: Path | None) -> dict:
    idx = np.sort(np.random.default_rng(seed).permutation(len(src))[:n])
    rest = np.setdiff1d(np.arange(len(src)), idx)
    cal, val = src.subset(idx), src.subset(rest)
    t0 = time.perf_counter()
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=seed, position_only=True), other=other)
    doc = rep.to_dict()
    out = {"series": name, "n": n, "seed": seed, "time_s": time.perf_counter() - t0,
           "kinematic_val_mm": rep.kinematic_validation.mean_mm, "final_val_mm": rep.final_validation.mean_mm,
           "final_model": rep.final_model, "transfer": doc["transfer"],
           "findings": [{"label": label(f), "in_model": f["in_model"], "gain_mm": f["gain_mm"],
                         **({k: f["transfer"][k] for k in ("base_gain_mm", "refit_gain_mm", "verdict")}
                            if f.get("transfer") else {})} for f in doc["findings"]]}
    if before is not None:
        path = before / f"before_{name}{n}_s{seed}_final.json"
        if path.exists():
            old = load_calibration(path)
            old.model.jit = False
            split = Split.of(len(other), 30, min(n, len(other) // 2), seed)
            out["before"] = {"model": old.model.spec, "val_mm": old.stats(val).mean_mm,
                             **travel(old, other, split).to_dict()}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--series", default="ab", help="source series: a, b or ab (default)")
    ap.add_argument("-n", type=int, default=300, help="calibration poses (default 300)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--before", type=Path, help="folder of the old diagnosis' final models")
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--plot", help="write the side-by-side figure (PNG) here")
    ap.add_argument("--from-json", help="plot results written before by --json instead of running")
    args = ap.parse_args()
    if args.from_json:
        plot(json.loads(Path(args.from_json).read_text()), args.plot)
        return
    warnings.simplefilter("ignore")
    robot = load_robot("ur10")
    series = {s: Measurements.read_csv(DATA / f"series_{s}.csv", n_joints=6) for s in "ab"}
    results = []
    for name in args.series:
        other = series["b" if name == "a" else "a"]
        for seed in args.seeds:
            r = one(robot, series[name], other, name, args.n, seed, args.before)
            results.append(r)
            t = r["transfer"]
            print(f"\n== source {name.upper()} ({args.n} poses, seed {seed}), {r['time_s']:.0f} s: {r['final_model']}")
            print(f"   in-series validation mean: kinematic {r['kinematic_val_mm']:.4f} mm, diagnosed "
                  f"{r['final_val_mm']:.4f} mm")
            print(f"   on series {'B' if name == 'a' else 'A'}: base re-estimated on 30 poses: kinematic "
                  f"{t['kinematic']['base_mm']:.4f}, diagnosed {t['final']['base_mm']:.4f} mm; geometry refitted: "
                  f"kinematic {t['kinematic']['refit_mm']:.4f}, diagnosed {t['final']['refit_mm']:.4f} mm")
            if "before" in r:
                b = r["before"]
                print(f"   before this change: in-series {b['val_mm']:.4f} mm; base {b['base_mm']:.4f}, refit "
                      f"{b['refit_mm']:.4f} mm ({b['model']})")
            for f in r["findings"]:
                if "verdict" in f:
                    print(f"     {f['label']:<28} {'in model' if f['in_model'] else 'kept out':<9} "
                          f"base {f['base_gain_mm']:+.4f}  refit {f['refit_gain_mm']:+.4f}  {f['verdict']}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if args.plot:
        plot(results, args.plot)


def plot(results: list[dict], path: str) -> None:
    """Mean error per run: in series, other series with the base re-estimated, with the geometry refitted."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    panels = [("in the same series (held-out poses)", "val"), ("other series, base pose re-estimated", "base"),
              ("other series, geometry refitted", "refit")]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), sharey=True)
    labels = [f"{r['series'].upper()} {r['seed']}" for r in results]
    x = np.arange(len(results))
    for ax, (title, key) in zip(axes, panels):
        def val(r, who):
            if key == "val":
                return {"kinematic": r["kinematic_val_mm"], "diagnosed": r["final_val_mm"],
                        "before": r.get("before", {}).get("val_mm", np.nan)}[who]
            if who == "before":
                return r.get("before", {}).get(f"{key}_mm", np.nan)
            return r["transfer"]["kinematic" if who == "kinematic" else "final"][f"{key}_mm"]
        for k, (who, colour) in enumerate((("kinematic", "#bbbbbb"), ("before", "#ee8866"),
                                           ("diagnosed", "#4477aa"))):
            ax.bar(x + (k - 1) * 0.27, [val(r, who) for r in results], 0.27, color=colour,
                   label={"before": "diagnosed, before this change"}.get(who, who))
        ax.set_xticks(x, labels)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("source series, seed")
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("mean position error (mm)")
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="upper center", ncol=3, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
