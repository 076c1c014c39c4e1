"""The first run on a machine: the README job's ``diagnose`` with an empty compiled-function cache against a
later run (the cache filled), this tree and a base tree in turn (issue 37, item "First run").

Each round runs, for each tree, in a fresh empty cache: the first run (cold), then a later run (warm), the
trees in turn, every process from a folder outside the checkouts (``PYTHONPATH`` names the tree) with
Python's bytecode kept as an installed package has it. Figures: wall and CPU (the process and its children:
the compilers too) of each, medians over the rounds, and the ratio cold / warm of each tree (the target:
at most 2 for the wall time). Then what the compile costs: each Function the job compiles (read from the
cache the first run filled: its name and size), its instructions, and gcc's CPU time for it at ``-O0`` (the
quick compile a first run waits for) and ``-O1`` (the optimised one, in the background), with their
evaluation time per pose (``--functions``).

Usage::

    python benchmarks/speed/bench_first_run.py --base /work/base --rounds 3
    python benchmarks/speed/bench_first_run.py --functions          # the compile table alone (~1 min)

The README job's files are made once with ``casadical split`` (300 poses of series B, seed 0).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))       # --functions imports this tree's casadical, whatever is installed
SERIES = ROOT / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"
TARGET = 2.0


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd: list[str], tree: Path, cache: Path, cwd: Path) -> tuple[float, float]:
    """Wall and CPU time (the process and its children) of one command, run with ``tree`` on PYTHONPATH."""
    env = dict(os.environ, PYTHONPATH=str(tree), CASADICAL_CACHE=str(cache), PYTHONPYCACHEPREFIX=str(cwd / "pyc"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    c0, t0 = _cpu_children(), time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    wall, cpu = time.perf_counter() - t0, _cpu_children() - c0
    if r.returncode:
        raise SystemExit(f"failed ({tree}): {' '.join(cmd)}\n{r.stderr[-2000:]}")
    return wall, cpu


def diagnose_cmd(work: Path, tag: str) -> list[str]:
    return [sys.executable, "-m", "casadical", "diagnose", "ur10", str(work / "cal.csv"), "--validate",
            str(work / "val.csv"), "--json", str(work / f"{tag}.json"), "--html", str(work / f"{tag}.html"),
            "--out", str(work / f"{tag}_final.json"), "--force", "--quiet"]


def functions_table(cache: Path) -> None:
    """The Functions a first run compiled (the entries of its cache), gcc's CPU at -O0 and -O1, and the
    evaluation per pose of each (2,000 random poses of the Function's inputs, best of 5)."""
    import casadi as ca
    import numpy as np

    from casadical.model import _jitcache as jitcache

    # the entries' Functions are not in the cache (only their libraries): build them as the job does,
    # by running it in this process with a hook that keeps every Function compiled
    kept: list = []
    orig = jitcache.load_all

    def keeping(funs, compile=True, before=None, quick=False):
        out = orig(funs, compile, before, quick)
        kept.extend(f for f, o in zip(funs, out) if o is not None)
        return out

    jitcache.load_all = keeping
    orig_load = jitcache.load

    def keeping_one(fun, compile=True):
        out = orig_load(fun, compile)
        if out is not None:
            kept.append(fun)
        return out

    jitcache.load = keeping_one
    from casadical.cli import main as cli

    work = cache.parent
    os.environ["CASADICAL_CACHE"] = str(cache)
    cli(diagnose_cmd(work, "fn")[3:])
    jitcache.finish()           # the background compiles: not beside the ones timed below
    cc = jitcache.compiler()
    print("\n| Function | instructions | gcc -O0 CPU | gcc -O1 CPU | eval -O0 (us/pose) | eval -O1 | VM |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    seen = set()
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        for fun in kept:
            if fun.name() + str(fun.n_instructions()) in seen:
                continue
            seen.add(fun.name() + str(fun.n_instructions()))
            c_file = jitcache._generate(fun, tmp)
            row = [fun.name(), f"{fun.n_instructions():,}"]
            libs = {}
            for level in ("-O0", "-O1"):
                lib = os.path.join(tmp, f"{fun.name()}{level}.so")
                c0 = _cpu_children()
                subprocess.run([cc, level, "-fPIC", "-shared", c_file, "-o", lib], check=True)
                row.append(f"{_cpu_children() - c0:.2f} s")
                libs[level] = ca.external(fun.name(), lib)
            N = 2000
            args = [rng.normal(size=(fun.sparsity_in(i).size1(), N)) * 0.1 for i in range(fun.n_in())]
            for f in (libs["-O0"], libs["-O1"], fun):
                F = f.map(N, "serial")
                F(*args)
                best = 1e9
                for _ in range(5):
                    t = time.process_time()
                    F(*args)
                    best = min(best, time.process_time() - t)
                row.append(f"{best / N * 1e6:.2f}")
            os.remove(c_file)
            print("| " + " | ".join(row) + " |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", metavar="TREE", help="a base tree (e.g. /work/base, aebf0e6), run in turn")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--functions", action="store_true", help="the compile table alone")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="first-run-") as tmp_:
        work = Path(tmp_)
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        subprocess.run([sys.executable, "-m", "casadical", "split", str(SERIES), "-n", "300", "--seed", "0",
                        "--out-cal", str(work / "cal.csv"), "--out-val", str(work / "val.csv"), "--force"],
                       cwd=work, env=env, check=True, capture_output=True)
        if args.functions:
            functions_table(work / "cache-fn")
            return 0
        trees = {"this": ROOT} | ({"base": Path(args.base).resolve()} if args.base else {})
        print(f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f} at start; README job's diagnose "
              f"(JSON, HTML, final model), {args.rounds} rounds, trees in turn\n")
        runs: dict[tuple[str, str], list[tuple[float, float]]] = {}
        for r in range(args.rounds):
            for name, tree in trees.items():
                cache = work / f"cache-{name}-{r}"
                for kind in ("cold", "warm"):
                    runs.setdefault((name, kind), []).append(timed(diagnose_cmd(work, f"{name}{kind}"), tree,
                                                                   cache, work))
        print("| tree | first run (empty cache): wall | CPU | later run: wall | CPU | first / later, wall "
              "(rounds) | first / later, CPU | target |")
        print("|---|---:|---:|---:|---:|---:|---:|---|")
        for name, tree in trees.items():
            cold, warm = runs[(name, "cold")], runs[(name, "warm")]
            med = [statistics.median(x[i] for x in xs) for xs in (cold, warm) for i in (0, 1)]
            ratios = sorted(c[0] / w[0] for c, w in zip(cold, warm))
            print(f"| {name} ({tree}) | {med[0]:.2f} s | {med[1]:.2f} s | {med[2]:.2f} s | {med[3]:.2f} s | "
                  f"{med[0] / med[2]:.2f} ({', '.join(f'{x:.2f}' for x in ratios)}) | {med[1] / med[3]:.2f} | "
                  f"<= {TARGET:g} wall |")
        print(f"\nload average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
