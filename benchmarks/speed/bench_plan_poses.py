"""End-to-end benchmark of ``casadical plan-poses``, quiet and next to a busy process, against a baseline.

For pools of 2,000 / 10^4 / 10^5 candidates of a 6-axis robot that is not
built in (``benchmarks/speed/robots/bench6.toml``, model kinematic+compliance, 32
identifiable parameters) and M = 20, 30, 64, runs the command line as a user
does (a new process: start-up, reading the CSV, pool Jacobian, relaxation,
exchange, writing the selection) and measures its wall time

- on the machine as it is ("quiet"), and
- with one other CPU-bound process running (``python -c "while True: pass"``,
  started by this script and stopped after each measurement),

(and the CPU time of the process: user + system, all its threads; a
measure of the work that the load of other users changes little) for the
code of this checkout and for a baseline commit (default ``b70ddc3``,
the code before the speed work), checked out with ``git worktree`` into a
temporary folder and run with ``PYTHONPATH`` pointing at it. Both run with
the BLAS thread settings a user has by default: ``OPENBLAS_NUM_THREADS``,
``OMP_NUM_THREADS``, ``MKL_NUM_THREADS`` and ``CASADICAL_THREADS`` are
removed from their environment. Each run's certificate is read from its
``--json`` summary: the certified D-efficiency must not drop.

Also measures the cost of entering and leaving ``casadical.runtime._threads.limited_threads``.

Usage::

    python benchmarks/speed/bench_plan_poses.py                          # everything, ~15-25 min
    python benchmarks/speed/bench_plan_poses.py --sizes 2000 --ms 30     # one case
    python benchmarks/speed/bench_plan_poses.py --no-baseline --json out.json

Load averages (``os.getloadavg``) are printed with every measurement: on a
shared machine other users' jobs change the figures; rerun when they are high.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import timeit
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
ROBOT = HERE / "robots" / "bench6.toml"
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "CASADICAL_THREADS")


def _parse() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2000, 10_000, 100_000])
    ap.add_argument("--ms", type=int, nargs="+", default=[20, 30, 64])
    ap.add_argument("--baseline", default="b70ddc3", help="git commit of the baseline (default: %(default)s)")
    ap.add_argument("--git", default=str(REPO),
                    help="git repository holding the baseline commit (default: this checkout)")
    ap.add_argument("--no-baseline", action="store_true", help="only this checkout")
    ap.add_argument("--baseline-cases", default=None, metavar="N:M,M;N:M",
                    help="run the baseline only for these cases, e.g. '2000:20,30,64;100000:30' "
                         "(it takes minutes per run on a busy machine; default: every case)")
    ap.add_argument("--no-busy", action="store_true", help="skip the runs next to a busy process")
    ap.add_argument("--repeats", type=int, default=1, help="runs per figure (the median is shown)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the candidate pools")
    ap.add_argument("--json", default=None, help="write every measurement here")
    return ap.parse_args()


def _env(code: str | None) -> dict:
    """A user's environment (no thread settings) importing casadical from ``code`` (default: this checkout)."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env["PYTHONPATH"] = code or str(REPO)
    return env


def _plan(code: str | None, cands: Path, m: int, out: Path) -> dict:
    """One ``plan-poses`` run in a new process: wall time and the JSON summary."""
    summary = out.with_suffix(".json")
    cmd = [sys.executable, "-m", "casadical", "plan-poses", str(ROBOT), str(cands), "-m", str(m),
           "--out", str(out), "--json", str(summary), "--force"]
    load = os.getloadavg()[0]
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=_env(code), cwd=tempfile.gettempdir(), capture_output=True, text=True)
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    if proc.returncode != 0:
        raise RuntimeError(f"plan-poses failed ({code or 'this checkout'}): {proc.stderr.strip()}")
    doc = json.loads(summary.read_text())
    return {"wall_s": wall, "cpu_s": cpu, "load_before": load, "load_after": os.getloadavg()[0],
            "d_efficiency": doc["d_efficiency"], "log_det": doc["log_det"], "upper_bound": doc["upper_bound"],
            "selection_s": doc["time_s"], "jacobian_s": doc["jacobian_time_s"], "indices": doc["indices"]}


class Busy:
    """One CPU-bound Python process for the duration of a ``with`` block (stopped by its handle)."""

    def __enter__(self):
        self.proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        time.sleep(0.5)
        return self

    def __exit__(self, *exc):
        self.proc.terminate()
        self.proc.wait()


def passes(no_busy: bool) -> list[tuple[str, type]]:
    """The passes of a side-by-side table, each (label, context to run it in): as the machine is, then
    beside one busy core (unless ``no_busy``)."""
    return [("as is", contextlib.nullcontext)] + ([] if no_busy else [("one busy core", Busy)])


def _baseline_checkout(git: str, commit: str, where: Path) -> Path:
    path = where / "baseline"
    subprocess.run(["git", "-C", git, "worktree", "add", "--detach", str(path), commit],
                   check=True, capture_output=True)
    return path


def _entry_cost_us() -> dict:
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401

    from casadical.runtime import limited_threads

    with limited_threads():
        pass  # the first entry scans the process for BLAS libraries
    n = 20000
    changing = timeit.timeit(lambda: limited_threads().__enter__().__exit__(), number=n) / n
    with limited_threads():
        nested = timeit.timeit(lambda: limited_threads().__enter__().__exit__(), number=n) / n
    return {"enter_exit_changing_us": changing * 1e6, "enter_exit_nested_us": nested * 1e6}


def _cases(text: str | None) -> dict[int, set[int]] | None:
    if not text:
        return None
    out: dict[int, set[int]] = {}
    for part in text.split(";"):
        n, ms = part.split(":")
        out[int(n)] = {int(m) for m in ms.split(",")}
    return out


def main() -> int:
    args = _parse()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # stop the busy process and the worktree too
    only = _cases(args.baseline_cases)
    rows = []
    entry = _entry_cost_us()
    print(f"limited_threads enter + exit: {entry['enter_exit_changing_us']:.1f} us when it changes the "
          f"limits, {entry['enter_exit_nested_us']:.1f} us nested", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_plan_") as tmp:
        tmp = Path(tmp)
        codes: dict[str, str | None] = {"new": None}
        base = None
        if not args.no_baseline:
            base = _baseline_checkout(args.git, args.baseline, tmp)
            codes = {"baseline": str(base), "new": None}
        try:
            for N in args.sizes:
                cands = tmp / f"c{N}.csv"
                subprocess.run([sys.executable, "-m", "casadical", "candidates", str(ROBOT), "-n", str(N),
                                "--out", str(cands), "--seed", str(args.seed)], env=_env(None), check=True,
                               capture_output=True)
                for m in args.ms:
                    row = {"N": N, "M": m}
                    for name, code in codes.items():
                        if name == "baseline" and only is not None and m not in only.get(N, ()):
                            continue
                        for cond in ("quiet",) if args.no_busy else ("quiet", "busy"):
                            runs = []
                            for _ in range(args.repeats):
                                if cond == "busy":
                                    with Busy():
                                        runs.append(_plan(code, cands, m, tmp / f"sel_{name}.csv"))
                                else:
                                    runs.append(_plan(code, cands, m, tmp / f"sel_{name}.csv"))
                            best = sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2]
                            best["wall_runs_s"] = [r["wall_s"] for r in runs]
                            row[f"{name}_{cond}"] = best
                            print(f"N={N} M={m} {name} {cond}: {best['wall_s']:.2f} s (CPU {best['cpu_s']:.2f} s, "
                                  f"load {best['load_before']:.1f}), D-eff {best['d_efficiency']:.4f}", flush=True)
                    rows.append(row)
        finally:
            if base is not None:
                subprocess.run(["git", "-C", args.git, "worktree", "remove", "--force", str(base)],
                               capture_output=True)
                shutil.rmtree(base, ignore_errors=True)

    conds = ("quiet",) if args.no_busy else ("quiet", "busy")
    names = list(codes)

    def wall(r, key):
        return f"{r[key]['wall_s']:.2f} ({r[key].get('cpu_s', float('nan')):.2f})" if key in r else "-"

    print()
    head = ["candidates", "M"]
    for name in names:
        head += [f"{name} {c}: wall (CPU) s" for c in conds]
        if "busy" in conds:
            head.append(f"{name} busy / quiet")
    head += [f"{name} D-eff" for name in names] + ["load (1 min) at the runs"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        cells = [f"{r['N']:,}", str(r["M"])]
        for name in names:
            cells += [wall(r, f"{name}_{c}") for c in conds]
            if "busy" in conds:
                q, b = r.get(f"{name}_quiet"), r.get(f"{name}_busy")
                cells.append(f"{b['wall_s'] / q['wall_s']:.2f}" if q and b else "-")
        cells += [f"{r[f'{name}_quiet']['d_efficiency']:.4f}" if f"{name}_quiet" in r else "-" for name in names]
        loads = [r[f"{n}_{c}"]["load_before"] for n in names for c in conds if f"{n}_{c}" in r]
        cells.append(f"{min(loads):.1f}-{max(loads):.1f}")
        print("| " + " | ".join(cells) + " |")
    if len(names) == 2:
        worse = [(r["N"], r["M"]) for r in rows if "baseline_quiet" in r
                 and r["new_quiet"]["d_efficiency"] < r["baseline_quiet"]["d_efficiency"] - 1e-6]
        print(f"\ncertified D-efficiency lower than the baseline's in: {worse or 'no case'}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "threads": entry, "rows": rows,
                       "python": sys.version, "cpus": os.cpu_count()}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
