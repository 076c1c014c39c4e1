"""Planning rows that touch: the rows the Ds criterion keeps against random ones, and its certificate (docs/planning.md,
"Planning touches").

On candidates the independent truth of the tests puts in the two sockets of a block (tests/truth/touch.py; a 6-axis
MDH arm that is not built in, two placements, 30 candidates per socket, the ball 20 um off the socket per axis):
the 18 rows plan-poses keeps by the Ds criterion and 7 random selections of 18 (each socket none or 4+ rows) are
each calibrated (kinematic, Levenberg-Marquardt) and judged on three fresh placements (their sockets fitted to
their own rows). Then, on a pool small enough to enumerate (a 4-axis arm, one placement, 6 candidates per socket),
the certificate's bound against the best of every subset a calibration takes. Prints Markdown tables
(regenerate_docs.py quotes them)::

    python benchmarks/studies/study_touch_plan.py [--seeds 6]
"""

from __future__ import annotations

import argparse
import itertools
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[2]))  # the tests' helpers as ``tests.helpers``

from casadical.model import Model  # noqa: E402
from casadical.planning import schur_log_det, select_touches, short_sets, touch_problem  # noqa: E402
from tests.helpers.touch_plan import compare, sockets  # noqa: E402


def selected_vs_random(seeds: int) -> None:
    print("### Selected against random rows (arm6-mdh, 2 placements x 2 sockets x 30 candidates, 18 kept)\n")
    print("| seed | parameters | Ds-efficiency at least | consistency, selected (mm) | consistency, 7 random: "
          "median (min - max) | rank of the selected among the 8 | log det per parameter, selected / random "
          "median |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for seed in range(seeds):
        with tempfile.TemporaryDirectory() as tmp:
            c = compare("arm6-mdh", seed, Path(tmp))
        r = np.array(c.randoms)
        rank = 1 + int(np.sum(r < c.selected))
        ratios.append(c.selected / np.median(r))
        print(f"| {seed} | {c.n_parameters} | {c.efficiency:.3f} | {c.selected:.4f} | {np.median(r):.4f} "
              f"({r.min():.4f} - {r.max():.4f}) | {rank} | {c.selected_ds:.2f} / {np.median(c.random_ds):.2f} |")
    print(f"\nselected / random median consistency: {np.median(ratios):.2f} (median over {seeds} seeds), "
          f"{min(ratios):.2f} - {max(ratios):.2f}")


def certificate() -> None:
    print("\n### The certificate against every subset (arm4, 1 placement x 2 sockets x 6 candidates, 8 kept)\n")
    print("| sockets | parameters | subsets a calibration takes | best log det | selected | bound "
          "| Ds-efficiency at least | selected against the best |")
    print("|---|---|---|---|---|---|---|---|")
    for fixture in (True, False):
        with tempfile.TemporaryDirectory() as tmp:
            robot, data, _, _ = sockets("arm4", 3, 6, 1, Path(tmp), fixture)
        problem = touch_problem(Model(robot, "kinematic", jit=False), data)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = select_touches(problem, 8)
        values = [schur_log_det(problem, S) for S in itertools.combinations(range(len(data)), 8)
                  if not short_sets(problem, S)]
        p = problem.n_parameters
        best = max(values)
        print(f"| {'the fixture' if fixture else 'free points'} | {p} | {len(values)} | {best:.3f} "
              f"| {res.log_det:.3f} | {res.upper_bound:.3f} | {res.d_efficiency:.3f} "
              f"| {np.exp((res.log_det - best) / p):.3f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    selected_vs_random(args.seeds)
    certificate()


if __name__ == "__main__":
    main()
