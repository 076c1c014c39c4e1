"""The speed targets (issue 37), each against aebf0e6 (or another tree) in the same run, alternating: whole processes.

Cases (each a fresh ``python -m casadical`` process from start to files; CPU = user + system of the process
and its children, such as the compiler):

- ``readme``: the README's main job, ``split`` series B (300 calibration poses, seed 0) then ``diagnose``
  with ``--json``, ``--html`` and ``--out``. Target: at most 0.4x the CPU of aebf0e6's, at most 2.5 s wall on
  2 idle cores;
- ``real2000``: ``diagnose`` of 2,000 poses of the real UR10 series A (full pose, temperatures and times;
  the other 9,911 judge), as ``bench_diagnosis.py --real`` draws them. Target: at most 0.35x;
- ``sessions``: ``diagnose`` of two sessions of 300 poses, series A and B of the real UR10 (each split like
  the README's, seed 0; the rest of each judges). Target: at most 0.4x;
- ``readme_nohtml``: the README job without ``--html`` (not a target: with ``readme`` it says what the HTML
  report's figures cost).

The trees run in turn (``--repeats`` pairs; the medians and the median of the pairwise ratios are printed),
after one untimed run of each that fills its own cache of compiled functions (one per tree: a tree never
reads what the other compiled) and of Python's bytecode (as an installed package has it). Each case also runs once on an
empty cache (``--cold``): the first run on a new machine. The printed summaries of the two trees are
compared line by line (but the run time and file names); a line that differs is printed.

Usage::

    python benchmarks/speed/bench_speed.py                                   # every case against /work/base
    python benchmarks/speed/bench_speed.py --cases readme --repeats 5 --base /path/to/aebf0e6 --cold

The 200,000-pose calibration is ``bench_scale.py --sizes 200000``, the 80-pose IPOPT solve
``bench_ipopt.py``: run them with ``PYTHONPATH`` at each tree.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
DATA = ROOT / "problems" / "datasets" / "ur10-ipa"


def wall(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """Wall time and CPU time (user + system, the process and its children such as the compiler). ``cwd``: out
    of the repository, whose folder ``python -m`` would put first on the import path (whatever PYTHONPATH)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=cwd)
    dt = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{r.stderr[-2000:]}")
    return dt, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)

TARGETS = {"readme": "<= 0.4x CPU, <= 2.5 s wall", "real2000": "<= 0.35x CPU", "sessions": "<= 0.4x CPU",
           "readme_nohtml": "- (the README job without --html: what the figures cost)"}


def run_env(tree: str, cache: Path, pycache: Path) -> dict:
    """The environment of a tree's runs: its sources first on the path, the cache of compiled functions, and
    Python's bytecode kept (in ``pycache``, out of the trees) as an installed package's is. Where
    ``PYTHONDONTWRITEBYTECODE`` is set (as on the machine of docs/speed.md) every run would otherwise compile
    the sources again: 0.2 s of the README job's CPU, and more for the tree with more code."""
    env = dict(os.environ, PYTHONPATH=tree, CASADICAL_CACHE=str(cache), PYTHONPYCACHEPREFIX=str(pycache))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def prepare(case: str, tmp: Path) -> list[list[str]]:
    """The case's files, and its commands (run in order; the last one's standard output is its summary)."""
    import numpy as np

    from casadical.data import Measurements

    exe = [sys.executable, "-m", "casadical"]
    if case in ("readme", "readme_nohtml"):
        cal, val = str(tmp / "ur10_cal.csv"), str(tmp / "ur10_val.csv")
        html = ["--html", str(tmp / "report.html")] if case == "readme" else []
        return [[*exe, "split", str(DATA / "series_b.csv"), "-n", "300", "--seed", "0", "--out-cal", cal,
                 "--out-val", val, "--force"],
                [*exe, "diagnose", "ur10", cal, "--validate", val, "--json", str(tmp / "report.json"), *html,
                 "--out", str(tmp / "final.json"), "--force"]]
    if case == "real2000":
        data = Measurements.read_csv(DATA / "series_a.csv", n_joints=6, require_positions=True)
        idx = np.sort(np.random.default_rng(0).permutation(len(data))[:2000])
        data.subset(idx).write_csv(tmp / "a_cal.csv", overwrite=True)
        data.subset(np.setdiff1d(np.arange(len(data)), idx)).write_csv(tmp / "a_val.csv", overwrite=True)
        return [[*exe, "diagnose", "ur10", str(tmp / "a_cal.csv"), "--validate", str(tmp / "a_val.csv"), "--json",
                 str(tmp / "report.json"), "--force"]]
    if case == "sessions":
        for s in ("a", "b"):
            subprocess.run([*exe, "split", str(DATA / f"series_{s}.csv"), "-n", "300", "--seed", "0", "--out-cal",
                            str(tmp / f"{s}_cal.csv"), "--out-val", str(tmp / f"{s}_val.csv"), "--force"],
                           check=True, capture_output=True, cwd=tmp)
        return [[*exe, "diagnose", "ur10", str(tmp / "a_cal.csv"), str(tmp / "b_cal.csv"), "--validate",
                 str(tmp / "a_val.csv"), str(tmp / "b_val.csv"), "--json", str(tmp / "report.json"), "--force"]]
    raise SystemExit(f"unknown case {case!r}")


def summary(cmds: list[list[str]], env: dict, cwd: Path) -> list[str]:
    """The last command's printed summary, without run times and file names."""
    for cmd in cmds[:-1]:
        subprocess.run(cmd, env=env, check=True, capture_output=True, cwd=cwd)
    text = subprocess.run(cmds[-1], env=env, check=True, capture_output=True, text=True, cwd=cwd).stdout
    return [re.sub(r"[0-9.]+ s\b", "_ s", line) for line in text.splitlines() if "->" not in line]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    ap.add_argument("--base", default="/work/base", help="the tree to compare with (default /work/base: aebf0e6)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="also one run of each tree on an empty cache")
    args = ap.parse_args()
    trees = {"this tree": str(ROOT), "base": str(Path(args.base).resolve())}
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; base {trees['base']}; median of "
          f"{args.repeats} runs each, in turn\n")
    print("| case | this tree: CPU | wall | base: CPU | wall | CPU ratio (pairs) | wall ratio | target |")
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            folder = Path(tmp) / case
            folder.mkdir()
            cmds = prepare(case, folder)
            envs = {k: run_env(v, Path(tmp) / f"cache-{i}", Path(tmp) / f"pycache-{i}")
                    for i, (k, v) in enumerate(trees.items())}
            texts = {k: summary(cmds, env, folder) for k, env in envs.items()}      # untimed: fills the cache
            times: dict = {k: [] for k in trees}
            for _ in range(args.repeats):
                for k, env in envs.items():
                    w = c = 0.0
                    for cmd in cmds:
                        dw, dc = wall(cmd, env, folder)
                        w, c = w + dw, c + dc
                    times[k].append((w, c))
            (a, b) = (times["this tree"], times["base"])
            med = {k: (statistics.median(t[0] for t in v), statistics.median(t[1] for t in v))
                   for k, v in times.items()}
            cr = statistics.median(x[1] / y[1] for x, y in zip(a, b))
            wr = statistics.median(x[0] / y[0] for x, y in zip(a, b))
            print(f"| {case} | {med['this tree'][1]:.2f} s | {med['this tree'][0]:.2f} s | {med['base'][1]:.2f} s | "
                  f"{med['base'][0]:.2f} s | {cr:.2f} | {wr:.2f} | {TARGETS[case]} |", flush=True)
            ours, theirs = texts["this tree"], texts["base"]
            only = {k: [x for x in a if x not in set(b)] for k, a, b in (("this tree", ours, theirs),
                                                                          ("base", theirs, ours))}
            if any(only.values()):
                print(f"  {case}: the printed summaries differ: {len(only['this tree'])} line(s) only in this tree, "
                      f"{len(only['base'])} only in the base")
                for k, lines in only.items():
                    for x in lines[:6]:
                        print(f"    {k}: {x}")
            if args.cold:
                for k, env in envs.items():
                    cold = dict(env, CASADICAL_CACHE=tempfile.mkdtemp(dir=tmp))
                    w = c = 0.0
                    for cmd in cmds:
                        dw, dc = wall(cmd, cold, folder)
                        w, c = w + dw, c + dc
                    print(f"  {case}, {k}, empty cache: CPU {c:.2f} s, wall {w:.2f} s", flush=True)
    print(f"\nload average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
