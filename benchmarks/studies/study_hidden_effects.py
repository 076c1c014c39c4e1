"""Every hidden effect on every test robot, three seeds: what the truth hid, what the diagnosis named, exact or not.

The data are made by the independent truth (tests/truth: no casadical code), the diagnosis runs with its
full search (DiagnosisSettings defaults). A claim is exact when the named causes (cause, joint, harmonic,
scope) are the hidden ones, no more and no less (tests/helpers/hidden.py). The slow test
tests/diagnosis/test_hidden_effects.py asserts the cases this prints as exact.

Usage::

    python benchmarks/studies/study_hidden_effects.py                       # the whole matrix (about 30 min on 2 cores)
    python benchmarks/studies/study_hidden_effects.py --robots arm4 arm7 --effects compliance drift --seeds 0
    python benchmarks/studies/study_hidden_effects.py --jobs 2 --json out/hidden.json
    python benchmarks/studies/study_hidden_effects.py --n-val 1000       # intervals' coverage on more held-out poses

Each row also gives the share of its validation poses inside the final model's 95 % intervals of a measured point
(``interval_coverage``; target 90-98 %), and the end a count of the cases within that band: with the default 200
validation poses one pose is half a per cent, and a coverage of 95 % scatters by 1.5 % from one draw to the next.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.append(str(ROOT))  # the tests' helpers as ``tests.helpers``, after any casadical on PYTHONPATH

import numpy as np  # noqa: E402

from tests.helpers import hidden  # noqa: E402


def fmt(claims) -> str:
    def one(c):
        cause, joint, harmonic, scope = c
        text = cause + (f" j{joint}" if joint is not None else "") + (f" h{harmonic}" if harmonic is not None else "")
        return text + (f" ({scope})" if scope != "robot" else "")
    return ", ".join(one(c) for c in sorted(claims, key=str)) or "-"


def run(robot: str, effect: str, seed: int, n_val: int = 200) -> dict:
    os.environ.setdefault("CASADICAL_JIT", "0")
    from casadical.diagnosis import DiagnosisSettings, diagnose
    c = hidden.case(robot, effect, seed)
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rob, cal, val, _ = hidden.make_data(c, n_val=n_val)
        rep = diagnose(rob, cal, val, DiagnosisSettings(seed=seed, session_tools=c.sessions))
        v = hidden.judge(rep, c.expected, c.allowed)
        true_mm = None
        if not v.exact:     # what the true model, fitted to the same poses, gives: is it the search or the model?
            from casadical import calibrate
            true_mm = calibrate(rob, cal, hidden.true_spec(c), "lm", warn=False,
                                session_tools=c.sessions).stats(val).mean_mm
    unexplained = [f.where for f in rep.findings if f.cause == "unexplained"]
    return {"robot": robot, "effect": effect, "seed": seed, "hidden": fmt(c.expected), "named": fmt(v.named),
            "missed": fmt(v.missing), "false": fmt(v.false), "exact": v.exact, "verdict": v.text(),
            "unexplained": unexplained, "final_model": rep.final_model, "validation_mm": rep.final_validation.mean_mm,
            "true_model_mm": true_mm, "interval_coverage": rep.interval_coverage, "cpu_s": time.process_time() - t0}


def tables(rows: list[dict]) -> str:
    """Markdown: exact claims per effect, and every claim that is not exact (docs/diagnosis.md quotes both)."""
    effects = list(dict.fromkeys(r["effect"] for r in rows))
    out = ["### Exact claims per effect", "", "| effect | exact |", "|---|---|"]
    for e in effects:
        mine = [r for r in rows if r["effect"] == e]
        out.append(f"| {e} | {sum(r['exact'] for r in mine)} of {len(mine)} |")
    bad = [r for r in rows if not r["exact"]]
    out += ["", "### Claims that are not exact", "",
            "| arm | hidden | seed | missed | false | validation mean (mm) | true model fitted (mm) |",
            "|---|---|---|---|---|---|---|"]
    out += [f"| {r['robot']} | {r['effect']} | {r['seed']} | {r['missed']} | {r['false']} | "
            f"{r['validation_mm']:.4f} | {r['true_model_mm']:.4f} |" for r in bad] \
        or ["| none | - | - | - | - | - | - |"]
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", nargs="+", default=list(hidden.ROBOTS), choices=list(hidden.ROBOTS) + ["ys100"])
    ap.add_argument("--effects", nargs="+", default=list(hidden.EFFECTS), choices=hidden.EFFECTS)
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--json", help="write every row here")
    ap.add_argument("--n-val", type=int, default=200, help="validation poses per case (default 200, as the tests)")
    args = ap.parse_args(argv)
    cases = [(r, e, s) for r in args.robots for e in args.effects for s in args.seeds]
    rows = []
    print(f"{'robot':13s} {'effect':28s} {'seed':>4s}  {'hidden':28s} {'named':40s} exact  val mm  cpu s", flush=True)
    with ProcessPoolExecutor(args.jobs) as pool:
        for row in pool.map(run, *zip(*cases), [args.n_val] * len(cases)):
            rows.append(row)
            print(f"{row['robot']:13s} {row['effect']:28s} {row['seed']:4d}  {row['hidden']:28s} {row['named']:40s} "
                  f"{'yes' if row['exact'] else 'NO':5s} {row['validation_mm']:7.4f} {row['cpu_s']:6.1f}"
                  + (f"  95 % interval {row['interval_coverage']:.1%}" if row["interval_coverage"] is not None else "")
                  + ("" if row["exact"] else f"   {row['verdict']}")
                  + (f"   unexplained: {'; '.join(row['unexplained'])}" if row["unexplained"] else ""), flush=True)
    bad = [r for r in rows if not r["exact"]]
    print(f"\n{len(rows) - len(bad)} of {len(rows)} claims exact")
    cov = [r["interval_coverage"] for r in rows if r["interval_coverage"] is not None]
    if cov:
        print(f"95 % intervals ({args.n_val} validation poses each): {sum(0.90 <= c <= 0.98 for c in cov)} of "
              f"{len(cov)} cases hold 90-98 % (range {min(cov):.1%} - {max(cov):.1%}; median {np.median(cov):.1%})")
    print()
    print(tables(rows))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
