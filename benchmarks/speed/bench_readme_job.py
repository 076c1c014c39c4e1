"""The README's main job, step by step, against plain kinematic calibrations of the same data, same run.

The job (README): ``casadical split`` series B of the bundled real UR10 data
(300 calibration poses, seed 0), then ``casadical diagnose`` with ``--json``,
``--html`` and ``--out``. Each row is a fresh process from its start to its
files: wall time and CPU time (user + system, with its children), median of
``--repeats`` runs. Side by side:

- the yardstick of issue 12: ``casadical calibrate ur10 CAL --model
  kinematic`` of the same 300 poses (the job must take no more than 4 of
  these);
- ``diagnose`` without ``--html``; with ``--transfer`` series A (11,911
  poses; ``--no-transfer`` skips it);
- ``diagnose`` with one evaluation thread (``CASADICAL_EVAL_THREADS=1``:
  the serial code) and with an empty cache of compiled functions (cold);
- the whole table again with one other CPU-bound process running (a busy
  loop this script starts and stops; ``--no-busy`` skips it).

Every diagnosis of the same data must give the same report: the script
compares each run's JSON with the first one's (every number but the run
time and the options it records), each HTML page with the first one's (but the run time), and the
``--transfer`` runs with each other, and stops if one differs.

It ends with the README's figures as the README says them, with the machine
they were measured on (CPU model, cores, numpy's BLAS kernel): the job
(``split`` then ``diagnose``) on an empty cache of compiled functions (the
first run on a machine) and on a filled one (later runs), wall and CPU,
medians of ``--repeats`` whole-process runs with their range, and what of
the CPU the HTML report takes. ``--readme`` runs only the rows these need;
on an idle machine::

    python benchmarks/speed/bench_readme_job.py --readme --repeats 5

Usage::

    python benchmarks/speed/bench_readme_job.py                # ~3 min on 2 cores
    python benchmarks/speed/bench_readme_job.py --repeats 5 --no-transfer --json out.json

Targets (issue 12): the job <= 10 s wall and no more than 4 plain kinematic
``calibrate`` runs; with a busy core every figure at most 2x its value
without.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from bench_calibrate_cli import wall  # noqa: E402
from bench_plan_poses import passes  # noqa: E402

HERE = Path(__file__).resolve().parent
DATA = HERE.parents[1] / "problems" / "datasets" / "ur10-ipa"
TARGET_S, TARGET_RUNS, BUSY_RATIO = 10.0, 4.0, 2.0
#: the rows the targets are computed from
SPLIT, JOB, NO_HTML, YARDSTICK = ("split (300 of 1,495 poses)", "diagnose --json --html --out",
                                  "diagnose --json --out (no HTML)", "calibrate --model kinematic (the yardstick)")
#: the first run: the job on an empty cache of compiled functions
COLD = "diagnose, empty cache of compiled functions"
#: the rows the README's figures are computed from (--readme runs only these)
README_ROWS = (SPLIT, JOB, NO_HTML, COLD)


def machine() -> str:
    """The machine the figures are of: CPU model (/proc/cpuinfo), cores, numpy's BLAS and its kernel."""
    import platform

    from threadpoolctl import threadpool_info

    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            model = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), model)
    except OSError:
        pass
    import numpy as np

    np.ones(2) @ np.ones(2)       # numpy's BLAS is loaded
    blas = ", ".join(f"{i.get('internal_api')} {i.get('version')} ({i.get('architecture', '?')} kernel)"
                     for i in threadpool_info() if i.get("user_api") == "blas")
    return f"{model}, {os.cpu_count()} cores; {blas or 'BLAS unknown'}"


def steps(tmp: Path, transfer: bool) -> list[tuple[str, list[str], dict]]:
    """(label, command, extra environment) of every row."""
    exe = [sys.executable, "-m", "casadical"]
    cal, val = str(tmp / "cal.csv"), str(tmp / "val.csv")
    diag = [*exe, "diagnose", "ur10", cal, "--validate", val, "--json", str(tmp / "report.json"), "--out",
            str(tmp / "final.json"), "--force", "--quiet"]
    html = ["--html", str(tmp / "report.html")]
    rows = [(SPLIT, [*exe, "split", str(DATA / "series_b.csv"), "-n", "300", "--seed", "0", "--out-cal", cal,
                     "--out-val", val, "--force"], {}),
            (JOB, diag + html, {}),
            (NO_HTML, diag, {}),
            ("diagnose, one evaluation thread", diag + html, {"CASADICAL_EVAL_THREADS": "1"}),
            (COLD, diag + html, {"CASADICAL_CACHE": "(new)"}),
            (YARDSTICK, [*exe, "calibrate", "ur10", cal, "--model", "kinematic", "--out", str(tmp / "kin.json"),
                         "--force"], {})]
    if transfer:
        rows.insert(3, ("diagnose --html --transfer series A", diag + html + ["--transfer",
                                                                              str(DATA / "series_a.csv")], {}))
    return rows


def outputs(tmp: Path, html: bool) -> dict:
    """A diagnosis' report (every value but the run time and the options it records as given) and its HTML page
    (but the run time)."""
    out = {"report": {k: v for k, v in json.loads((tmp / "report.json").read_text()).items()
                      if k not in ("time_s", "inputs")}}
    if html:
        page = (tmp / "report.html").read_text(encoding="utf-8")
        out["HTML page"] = re.sub(r"(Run time|models tried in) [0-9.]+ s", r"\1", page)
    return out


def run_pass(args, tmp: Path, label: str, reference: dict) -> list[dict]:
    rows = []
    for name, cmd, extra in steps(tmp, not args.no_transfer):
        if args.readme and name not in README_ROWS:
            continue
        times = []
        for k in range(args.repeats):
            env = dict(os.environ, **extra)
            if extra.get("CASADICAL_CACHE") == "(new)":
                env["CASADICAL_CACHE"] = tempfile.mkdtemp(dir=tmp)
            times.append(wall(cmd, env))
            if "diagnose" in cmd:   # the same data must give the same outputs (--transfer: among themselves)
                for what, value in outputs(tmp, "--html" in cmd).items():
                    if reference.setdefault((what, "--transfer" in cmd), value) != value:
                        raise SystemExit(f"{name}: the {what} differs from the first one's")
        w, c = statistics.median(t[0] for t in times), statistics.median(t[1] for t in times)
        rows.append({"pass": label, "step": name, "wall_s": w, "cpu_s": c, "load": os.getloadavg()[0],
                     "runs": times})
        print(f"| {name} | {w:.2f} s ({_range(t[0] for t in times)}) | {c:.2f} s ({_range(t[1] for t in times)}) "
              f"| {rows[-1]['load']:.2f} |", flush=True)
    return rows


def _range(values) -> str:
    values = list(values)
    return f"{min(values):.2f}-{max(values):.2f}"


def readme(rows: list[dict], where: str) -> None:
    """The README's figures: the job (split, then diagnose) run by run, medians and ranges of its whole
    processes, on an empty cache (the first run) and a filled one (later runs); the HTML report's CPU."""
    runs = {r["step"]: r["runs"] for r in rows if r["pass"] == "as is"}
    if not set(README_ROWS) <= set(runs):
        return
    first = [(a[0] + b[0], a[1] + b[1]) for a, b in zip(runs[SPLIT], runs[COLD])]
    later = [(a[0] + b[0], a[1] + b[1]) for a, b in zip(runs[SPLIT], runs[JOB])]
    html = statistics.median(runs[JOB][k][1] - runs[NO_HTML][k][1] for k in range(len(runs[JOB])))

    def med(runs, k):
        return statistics.median(t[k] for t in runs)

    print(f"\nthe README's figures ({where}; the job: split, then diagnose --json --html --out; medians of "
          f"{len(later)} whole-process runs, their range in brackets):")
    print(f"  first run (empty cache): {med(first, 0):.1f} s wall ({_range(t[0] for t in first)}), "
          f"{med(first, 1):.1f} s of CPU ({_range(t[1] for t in first)})")
    print(f"  later runs: {med(later, 0):.1f} s wall ({_range(t[0] for t in later)}), {med(later, 1):.1f} s of CPU "
          f"({_range(t[1] for t in later)}), of which the HTML report {html:.1f} s")


def summary(rows: list[dict]) -> None:
    def t(label, step):
        return next((r["wall_s"] for r in rows if r["pass"] == label and r["step"] == step), math.nan)

    print("\ntargets (issue 12):")
    for label in dict.fromkeys(r["pass"] for r in rows):
        split, job, plain, kin = (t(label, step) for step in (SPLIT, JOB, NO_HTML, YARDSTICK))
        total = split + job
        print(f"  {label}: README job {total:.2f} s (target <= {TARGET_S:.0f} s: "
              f"{'met' if total <= TARGET_S else 'NOT met'}); {total / kin:.1f} kinematic calibrate runs of "
              f"{kin:.2f} s, {(split + plain) / kin:.1f} without the HTML (target <= {TARGET_RUNS:.0f}: "
              f"{'met' if total / kin <= TARGET_RUNS else 'NOT met'})")
    busy = [(r, t("one busy core", r["step"])) for r in rows if r["pass"] == "as is"]
    ratios = [b / r["wall_s"] for r, b in busy if math.isfinite(b)]
    if ratios:
        print(f"  with one busy core: {min(ratios):.2f}x - {max(ratios):.2f}x the wall time without (target <= "
              f"{BUSY_RATIO:.0f}x: {'met' if max(ratios) <= BUSY_RATIO else 'NOT met'})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-transfer", action="store_true", help="skip the row with --transfer series A")
    ap.add_argument("--no-busy", action="store_true", help="skip the pass with a busy core")
    ap.add_argument("--readme", action="store_true",
                    help="only the rows of the README's figures (no transfer, no busy pass)")
    ap.add_argument("--json", help="save the rows")
    args = ap.parse_args()
    if args.readme:
        args.no_transfer = args.no_busy = True
    import casadi
    import numpy as np

    where = machine()
    print(f"{where}\nPython {sys.version.split()[0]}, numpy {np.__version__}, CasADi {casadi.__version__}, "
          f"load average {os.getloadavg()[0]:.2f}")
    rows: list[dict] = []
    reference: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label, context in passes(args.no_busy):
            print(f"\n{label}:\n\n| step | wall: median (range) | CPU: median (range) | load |\n|---|---:|---:|---:|",
                  flush=True)
            with context():
                rows += run_pass(args, Path(tmp), label, reference)
    if not args.readme:
        summary(rows)
    readme(rows, where)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
