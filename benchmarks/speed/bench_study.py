"""Wall time of a Monte Carlo study against the number of Dask workers, with the serial run as baseline.

Runs one study (default: the worked example of docs/studies.md,
``problems/studies/poses-ys100.toml``) serially in this process, then on a
fresh local Dask cluster of each number of workers (cluster start-up
included), each into its own results folder, and checks that every Dask
table equals the serial one row by row (floats bit for bit). Prints a
markdown table with the load average of the machine around each run.

Usage::

    python benchmarks/speed/bench_study.py                          # poses-ys100, 40 repetitions, 1 and 2 workers
    python benchmarks/speed/bench_study.py ca-ys100 --repetitions 20 --workers 1 2 4 --keep out/bench
    python benchmarks/speed/bench_study.py --repetitions 10 --rounds 3  # medians of 3 rotated rounds
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as the Dask workers have it

from casadical.study import (  # noqa: E402
    ResultStore,
    differing_columns,  # noqa: E402
    load_study,
    run_study,
)


def load() -> str:
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


def cpu() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("study", nargs="?", default="poses-ys100", help="study protocol (file or bundled name)")
    ap.add_argument("--repetitions", type=int, default=None, help="override the protocol's repetitions")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="Dask worker counts (default 1 2)")
    ap.add_argument("--rounds", type=int, default=1,
                    help="repeat every configuration, in rotated order, and report medians (a shared "
                         "machine's load changes from minute to minute)")
    ap.add_argument("--keep", help="keep the results folders here (default: a temporary folder)")
    ap.add_argument("--plot", metavar="OUT.png", help="wall time against workers: every run and the medians")
    args = ap.parse_args(argv)
    study = load_study(args.study)
    if args.repetitions:
        study.repetitions = args.repetitions
    folder = args.keep or tempfile.mkdtemp(prefix="casadical-bench-study-")
    os.makedirs(folder, exist_ok=True)
    print(f"# study {study.name}: {study.repetitions} repetitions x {study.rows_per_repetition} rows; "
          f"{cpu()}, {len(os.sched_getaffinity(0))} cores, python {platform.python_version()}\n")
    print("| round | backend | workers | wall time (s) | rows | rows with errors | equal to serial "
          "| load average before (1/5/15 min) | after |")
    print("|---|---|---|---|---|---|---|---|---|")
    configs = [("serial", None)] + [("dask", n) for n in args.workers]
    walls: dict = {c: [] for c in configs}
    serial = None
    for k in range(args.rounds):
        order = configs[k % len(configs):] + configs[:k % len(configs)]
        for backend, n in order:
            out = os.path.join(folder, backend if n is None else f"dask-{n}")
            before = load()
            t0 = time.perf_counter()
            report = run_study(study, out, backend=backend, workers=n, force=True)
            wall = time.perf_counter() - t0
            walls[(backend, n)].append(wall)
            table = ResultStore.open(out).read()
            if serial is None:          # round 1 starts with the serial run: the reference
                serial, same = table, "(reference)"
            else:
                diff = differing_columns(table, serial)
                same = "yes, bit for bit" if not diff else "NO: " + ", ".join(diff)
            print(f"| {k + 1} | {backend} | {n or 1} | {wall:.1f} | {table.num_rows} | {report.error_rows} "
                  f"| {same} | {before} | {load()} |", flush=True)
    base = statistics.median(walls[("serial", None)])
    print(f"\n| backend | workers | median wall time (s) over {args.rounds} round(s) | speed-up vs serial |")
    print("|---|---|---|---|")
    for (backend, n), w in walls.items():
        print(f"| {backend} | {n or 1} | {statistics.median(w):.1f} | {base / statistics.median(w):.2f} |")
    if args.plot:
        plot(walls, study, args.plot)
    if not args.keep:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


def plot(walls: dict, study, path: str) -> None:
    """Wall time of every run and the medians against the configuration, with the serial time / workers."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [("serial" if n is None else f"Dask, {n} worker{'s' if n > 1 else ''}") for _, n in walls]
    base = statistics.median(walls[("serial", None)])
    fig, ax = plt.subplots(figsize=(6, 3.4), layout="constrained")
    for i, ((_, n), w) in enumerate(walls.items()):
        ax.bar(i, statistics.median(w), color="#9ecae1", label="median" if i == 0 else None)
        ax.plot([i] * len(w), w, "o", color="#08519c", ms=4, label="each run" if i == 0 else None)
        if n:
            ax.plot([i - 0.4, i + 0.4], [base / n] * 2, "--", color="#d94801",
                    label="serial time / workers" if n == min(k for _, k in walls if k) else None)
    ax.set_xticks(range(len(walls)), labels)
    ax.set_ylabel("wall time (s)")
    ax.set_title(f"study {study.name}, {study.repetitions} repetitions, load {os.getloadavg()[0]:.1f}",
                 fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    ax.margins(y=0.15)
    fig.savefig(path, dpi=110)
    print(f"plot -> {path}")


if __name__ == "__main__":
    sys.exit(main())
