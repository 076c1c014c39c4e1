"""plan-poses REPORT.json on simulated arms: planned poses against random ones, side by side (docs/planning.md).

For each scenario of tests/helpers/planning_loop.py (a cause the first poses cannot
resolve, on an arm that is not built in, measured by the independent truth
of the tests) and each seed: diagnose the first poses, plan M of 500
candidates (485 repeat the measured region, 15 reach beyond it: other poses,
or another payload), "measure" the planned poses and M random candidates,
diagnose each with the first poses, and say whether the diagnosis names the
cause (of the right scope) and no longer finds it ambiguous with its rivals.
Prints Markdown tables (regenerate_docs.py quotes them)::

    python benchmarks/studies/study_next_poses.py [--seeds 3] [--scenarios "narrow range" ...]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parents[2]))  # the tests' helpers as ``tests.helpers``

from tests.helpers.planning_loop import SCENARIOS, loop  # noqa: E402

#: the worked examples the docs quote: scenario -> seed
EXAMPLES = {"narrow range": 0, "compliance or scale": 1}


def _text(q: dict) -> str:
    return q["text"].split(" (finding")[0]


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


def example(name: str, seed: int, plan: dict, m: int) -> None:
    """The first question's table: standard errors and chance to tell, for each set of poses."""
    q = plan["questions"][0]
    print(f"\n### Worked example: {name}, seed {seed} ({_text(q)})\n")
    names = q["parameters"]
    print("| poses | " + " | ".join(f"std {n} ({q['units'][n]})" for n in names) + " | chance to tell |")
    print("|" + "---|" * (len(names) + 2))
    for key, label in (("before", "measured alone"), ("planned", f"+ {m} planned"),
                       ("random", f"+ {m} random (median)"), ("d_optimal", f"+ {m} D-optimal, whole model")):
        e = q[key]
        cells = ["not determined" if e["std"][n] is None or e["std"][n] == float("inf") else f"{e['std'][n]:.3g}"
                 for n in names]
        print(f"| {label} | " + " | ".join(cells) + f" | {_pct(e['power'])} |")
    print(f"\ncertified Ds-efficiency of the planned set: >= {plan['criterion']['ds_efficiency']:.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    args = ap.parse_args()
    rows, plans, wins = [], {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenarios:
            for seed in range(args.seeds):
                folder = Path(tmp) / f"{name.replace(' ', '-').replace(',', '')}-{seed}"
                folder.mkdir()
                with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                    out = loop(SCENARIOS[name], seed, folder)
                qs = out["plan"]["questions"]
                rows.append([name, str(seed), "; ".join(_text(q) for q in qs),
                             f"{out['far_picked']} / {out['far_random']}",
                             " / ".join(_pct(q["planned"]["power"]) for q in qs),
                             " / ".join(_pct(q["random"]["power"]) for q in qs),
                             "yes" if out["first"] else "no", "yes" if out["planned"] else "no",
                             "yes" if out["random"] else "no"])
                plans[name, seed] = out["plan"]
                wins[name] = wins.get(name, 0) + (out["planned"] and not out["random"])
                print(f"{name} seed {seed}: done", file=sys.stderr)
    m = SCENARIOS[args.scenarios[0]].m
    print(f"### The loop: {m} planned against {m} random candidates\n")
    head = ["scenario", "seed", "open questions", "far candidates picked (planned / random)",
            "chance to tell, planned", "chance to tell, random (mean)", "named: first poses",
            f"named: + {m} planned", f"named: + {m} random"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(r) + " |")
    print("\nseeds where the planned poses resolve what the random ones do not: "
          + ", ".join(f"{name} {k} of {args.seeds}" for name, k in wins.items()))
    for name, seed in EXAMPLES.items():
        if (name, seed) in plans:
            example(name, seed, plans[name, seed], SCENARIOS[name].m)


if __name__ == "__main__":
    main()
