"""Where a diagnosis spends its CPU: each stage of ``diagnose()`` (diagnosis/_pipeline.py ``STAGES``), the HTML
report, and what is left of the process (start-up, imports, reading and writing files), for the three real jobs,
side by side with another tree in the same run.

Each job runs in a fresh process per tree, in turn (``--repeats`` times, the median of each figure), after an
untimed run that fills the tree's own cache of compiled functions. The stages are timed by wrapping each one
(``time.process_time``: this process's CPU, every thread); the HTML report's figures drawn in child processes
are counted with them (``RUSAGE_CHILDREN``). Jobs:

- ``readme``: the README's ``diagnose`` of 300 poses of UR10 series B (JSON, HTML and the final model);
- ``real2000``: 2,000 poses of UR10 series A (the rest judges), JSON;
- ``sessions``: two sessions of 300 poses (series A and B, each split like the README's), JSON;
- ``readme-no-goal``: the README's job on the same poses without the commanded goal pose (the six ``goal_*``
  columns of series B, which the structure screen and the stand-in check try as the data's own columns since
  issue 49: what the job costs on a file that does not carry them).

    python benchmarks/speed/bench_stages.py --base /work/base          # against aebf0e6's checkout (no stages:
                                                                       # its HTML report and whole process)
    python benchmarks/speed/bench_stages.py --jobs readme --repeats 5
    python benchmarks/speed/bench_stages.py --base /work/base --jobs readme readme-no-goal --repeats 5
    python benchmarks/speed/bench_stages.py --base /work/base --without bearing_compliance --jobs readme

``--without CAUSE`` runs this tree a second time with one cause of the catalogue left out (its candidates and its
terms in the superset: what screening it costs; the report may differ where the cause is named).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "problems" / "datasets" / "ur10-ipa"

#: run in the child, from the tree on its PYTHONPATH: the command with its stages timed, the figures as JSON
CHILD = r"""
import json, resource, sys, time
t_start = time.process_time()
times = {}
def timed(name, f):
    def g(*a, **k):
        t, c = time.process_time(), resource.getrusage(resource.RUSAGE_CHILDREN)
        try:
            return f(*a, **k)
        finally:
            c2 = resource.getrusage(resource.RUSAGE_CHILDREN)
            times[name] = times.get(name, 0.0) + time.process_time() - t + (c2.ru_utime + c2.ru_stime
                                                                            - c.ru_utime - c.ru_stime)
    g.__name__ = getattr(f, "__name__", name)
    return g
import importlib
def module(*names):     # a tree before its modules were private (22830a8) names them without the underscore
    for name in names:
        try:
            return importlib.import_module(name)
        except ImportError:
            pass
P = module("casadical.diagnosis._pipeline", "casadical.diagnosis.pipeline")
if hasattr(P, "STAGES"):     # a tree before the diagnosis had stages (aebf0e6): its whole process only
    P.STAGES = tuple(timed(s.__name__, s) for s in P.STAGES)
import casadical.html as H
H.diagnosis_html = timed("html report", H.diagnosis_html)
HD = module("casadical.html._diagnosis", "casadical.html.diagnosis")
if HD is not None:
    HD.diagnosis_html = H.diagnosis_html
import os
if os.environ.get("BENCH_WITHOUT"):     # --without: the cause left out of the catalogue and the superset
    from casadical.terms import CAUSES, REGISTRY
    name = os.environ["BENCH_WITHOUT"]
    type(CAUSES[name]).candidates = lambda self, data: []
    REGISTRY[name].superset = classmethod(lambda cls, robot: [])
from casadical.cli import main
main(sys.argv[1:])
me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
total = me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime
print(json.dumps({"stages": times, "total": total}), file=sys.stderr)
"""


def prepare(job: str, tmp: Path, env: dict) -> list[str]:
    """The job's files in ``tmp`` and its diagnose arguments."""
    py = [sys.executable, "-m", "casadical"]
    if job in ("readme", "readme-no-goal", "sessions"):
        for s in ("a", "b"):
            subprocess.run([*py, "split", str(DATA / f"series_{s}.csv"), "-n", "300", "--seed", "0", "--out-cal",
                            f"{s}_cal.csv", "--out-val", f"{s}_val.csv", "--force"], check=True, cwd=tmp, env=env,
                           capture_output=True)
    if job == "readme-no-goal":
        for name in ("b_cal.csv", "b_val.csv"):
            rows = list(csv.reader((tmp / name).open(newline="")))
            keep = [i for i, h in enumerate(rows[0]) if not h.startswith("goal_")]
            with (tmp / name).open("w", newline="") as f:
                csv.writer(f).writerows([r[i] for i in keep] for r in rows)
    if job in ("readme", "readme-no-goal"):
        return ["diagnose", "ur10", "b_cal.csv", "--validate", "b_val.csv", "--json", "report.json", "--html",
                "report.html", "--out", "final.json", "--force"]
    if job == "sessions":
        return ["diagnose", "ur10", "a_cal.csv", "b_cal.csv", "--validate", "a_val.csv", "b_val.csv", "--json",
                "report.json", "--force"]
    code = ("import numpy as np\nfrom casadical.data import Measurements\n"
            f"d = Measurements.read_csv({str(DATA / 'series_a.csv')!r}, n_joints=6, require_positions=True)\n"
            "i = np.sort(np.random.default_rng(0).permutation(len(d))[:2000])\n"
            "d.subset(i).write_csv('a_cal.csv', overwrite=True)\n"
            "d.subset(np.setdiff1d(np.arange(len(d)), i)).write_csv('a_val.csv', overwrite=True)\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=tmp, env=env)
    return ["diagnose", "ur10", "a_cal.csv", "--validate", "a_val.csv", "--json", "report.json", "--force"]


def run(args: list[str], env: dict, cwd: Path) -> dict:
    r = subprocess.run([sys.executable, "-c", CHILD, *args], env=env, cwd=cwd, capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(args)}\n{r.stderr[-3000:]}")
    return json.loads(r.stderr.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", nargs="+", default=["readme", "real2000", "sessions"],
                    choices=["readme", "readme-no-goal", "real2000", "sessions"])
    ap.add_argument("--base", help="another tree to run beside this one (aebf0e6's checkout)")
    ap.add_argument("--without", metavar="CAUSE", help="also this tree with CAUSE left out (bearing_compliance)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    trees = {"this tree": str(ROOT)}
    if args.base:
        trees["base"] = str(Path(args.base).resolve())
    if args.without:
        trees[f"without {args.without}"] = str(ROOT)
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; CPU seconds, median of {args.repeats} "
          f"runs in turn\n")
    with tempfile.TemporaryDirectory(prefix="stages-") as tmp:
        envs = {k: dict(os.environ, PYTHONPATH=v, CASADICAL_CACHE=str(Path(tmp) / f"cache-{i}"),
                        PYTHONPYCACHEPREFIX=str(Path(tmp) / f"pycache-{i}"))
                for i, (k, v) in enumerate(trees.items())}
        for env in envs.values():
            env.pop("PYTHONDONTWRITEBYTECODE", None)
        if args.without:
            envs[f"without {args.without}"]["BENCH_WITHOUT"] = args.without
        for job in args.jobs:
            folder = Path(tmp) / job
            folder.mkdir()
            cmd = prepare(job, folder, envs["this tree"])
            for env in envs.values():
                run(cmd, env, folder)                   # fills the cache
            got: dict = {k: [] for k in trees}
            for _ in range(args.repeats):
                for k, env in envs.items():
                    got[k].append(run(cmd, env, folder))
            names = list(dict.fromkeys(n for runs in got.values() for r in runs for n in r["stages"]))
            med = {k: {n: statistics.median(r["stages"].get(n, 0.0) for r in runs) for n in names}
                   for k, runs in got.items()}
            tot = {k: statistics.median(r["total"] for r in runs) for k, runs in got.items()}
            print(f"**{job}**\n")
            others = [k for k in trees if k != "this tree"]
            print("| step | " + " | ".join(trees) + "".join(f" | this / {k}" for k in others) + " |")
            print("|---|" + "---:|" * (len(trees) + len(others)))
            rows = [(n, {k: med[k][n] for k in trees}) for n in names]
            rows.append(("the rest of the process (start-up, imports, files)",
                         {k: tot[k] - sum(med[k].values()) for k in trees}))
            rows.append(("**the whole process**", tot))
            for n, v in rows:
                cells = " | ".join(f"{v[k]:.2f}" for k in trees)
                ratios = "".join(f" | {v['this tree'] / v[k]:.2f}" if v[k] > 0.005 else " | -" for k in others)
                print(f"| {n} | {cells}{ratios} |")
            print(flush=True)
    print(f"load average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
