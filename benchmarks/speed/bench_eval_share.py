"""What the model's evaluation costs in each job of issue 26's targets, and what the job would cost without it.

Issue 26 set its targets for a diagnosis whose largest cost was evaluating models on CasADi's virtual
machine. This script measures, for the jobs of ``bench_speed.py`` (same files, same commands), the CPU time
spent inside CasADi's evaluations (every :meth:`casadical.model._batch.Batch.evaluate`, in whichever thread it runs:
the compiled superset's functions and the models' own) against the whole process's CPU (its children
included: the HTML report's figure processes). "Without evaluation" is the whole less the evaluation: what
the job would cost if every model evaluation were free, the floor a faster model cannot go below.

Each case runs once untimed (it fills the cache of compiled functions), then ``--repeats`` times in a fresh
process of this script that wraps ``Batch.evaluate`` and runs the command's ``main`` in-process; the medians
are printed. Python's bytecode is kept as in ``bench_speed.py``.

Usage::

    python benchmarks/speed/bench_eval_share.py                        # readme, readme_nohtml, real2000, sessions
    python benchmarks/speed/bench_eval_share.py --cases readme --repeats 3
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

from bench_speed import TARGETS, prepare, run_env  # noqa: E402


def child(out: str, argv: list[str]) -> None:
    """Run ``casadical argv`` in this process with ``Batch.evaluate`` timed (thread CPU, every thread)."""
    from casadical.cli import main
    from casadical.model import _batch as batch

    spent, lock = [0.0], threading.Lock()
    evaluate = batch.Batch.evaluate

    def timed(self, *inputs):
        t = time.thread_time()
        try:
            return evaluate(self, *inputs)
        finally:
            dt = time.thread_time() - t
            with lock:
                spent[0] += dt

    batch.Batch.evaluate = timed
    code = main(argv)
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    total = me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime
    Path(out).write_text(json.dumps({"code": code, "cpu_s": total, "eval_s": spent[0]}))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--child", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child[0], args.child[1:])
        return 0
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; this tree {ROOT}; median of "
          f"{args.repeats} runs\n")
    print("| case | CPU of the job | of which CasADi evaluation | share | CPU without evaluation | target |")
    print("|---|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        env = run_env(str(ROOT), Path(tmp) / "cache", Path(tmp) / "pycache")
        for case in args.cases:
            folder = Path(tmp) / case
            folder.mkdir()
            cmds = prepare(case, folder)
            for cmd in cmds:            # untimed: the files, and the cache of compiled functions
                subprocess.run(cmd, env=env, check=True, capture_output=True, cwd=folder)
            runs = []
            for _ in range(args.repeats):
                out = folder / "share.json"
                argv = cmds[-1][cmds[-1].index("casadical") + 1:]
                subprocess.run([sys.executable, __file__, "--child", str(out), *argv], env=env, check=True,
                               capture_output=True, cwd=folder)
                runs.append(json.loads(out.read_text()))
                if runs[-1]["code"]:
                    raise SystemExit(f"{case}: casadical {' '.join(argv)} exited with {runs[-1]['code']}")
            cpu = statistics.median(r["cpu_s"] for r in runs)
            ev = statistics.median(r["eval_s"] for r in runs)
            share = statistics.median(r["eval_s"] / r["cpu_s"] for r in runs)
            rest = statistics.median(r["cpu_s"] - r["eval_s"] for r in runs)
            print(f"| {case} | {cpu:.2f} s | {ev:.2f} s | {share:.1%} | {rest:.2f} s | {TARGETS[case]} |",
                  flush=True)
    print(f"\nload average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
