"""plan-poses REPORT.json on simulated arms: planned poses against random ones, side by side (docs/planning.md).

For each scenario of tests/planning_loop.py (a cause the first poses cannot
resolve, on an arm that is not built in) and each seed: diagnose the first
poses, plan M of 500 candidates (485 repeat the measured region, 15 reach
beyond it), "measure" the planned poses and M random candidates with the
simulator, diagnose each with the first poses, and say whether the
diagnosis names the cause. Prints Markdown tables (regenerate_docs.py
quotes them)::

    python benchmarks/study_next_poses.py [--seeds 3]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from planning_loop import SCENARIOS, loop  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    rows, example = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("narrow range", "harmonic band"):
            for seed in range(args.seeds):
                folder = Path(tmp) / f"{name.replace(' ', '-')}-{seed}"
                folder.mkdir()
                with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                    out = loop(SCENARIOS[name], seed, folder)
                q = out["plan"]["questions"][0]
                rows.append([name, str(seed), q["text"].split(" (finding")[0],
                             f"{out['far_picked']} / {out['far_random']}",
                             f"{100 * q['planned']['power']:.0f} %", f"{100 * q['random']['power']:.0f} %",
                             "yes" if out["first"] else "no", "yes" if out["planned"] else "no",
                             "yes" if out["random"] else "no"])
                if example is None:
                    example = out["plan"]
                print(f"{name} seed {seed}: done", file=sys.stderr)
    m = SCENARIOS["narrow range"].m
    print(f"### The loop: {m} planned against {m} random candidates\n")
    head = ["scenario", "seed", "open question", "far candidates picked (planned / random)",
            "chance to tell, planned", "chance to tell, random (mean)", "named: first poses",
            f"named: + {m} planned", f"named: + {m} random"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(r) + " |")
    q = example["questions"][0]
    print(f"\n### Worked example: narrow range, seed 0 ({q['text'].split(' (finding')[0]})\n")
    names = q["parameters"]
    print("| poses | " + " | ".join(f"std {n} ({q['units'][n]})" for n in names) + " | chance to tell |")
    print("|" + "---|" * (len(names) + 2))
    for key, label in (("before", "measured alone"), ("planned", f"+ {m} planned"),
                       ("random", f"+ {m} random (median)"), ("d_optimal", f"+ {m} D-optimal, whole model")):
        e = q[key]
        cells = ["not determined" if e["std"][n] is None or e["std"][n] == float("inf") else f"{e['std'][n]:.3g}"
                 for n in names]
        print(f"| {label} | " + " | ".join(cells) + f" | {100 * e['power']:.0f} % |")
    c = example["criterion"]
    print(f"\ncertified Ds-efficiency of the planned set: >= {c['ds_efficiency']:.4f}")


if __name__ == "__main__":
    main()
