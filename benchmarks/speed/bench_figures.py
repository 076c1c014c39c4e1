"""The HTML report's figures: what they cost in the README job, this tree against a base tree, same run.

The README job (``split`` series B of the bundled UR10 data, 300 calibration
poses, seed 0; then ``diagnose ur10 CAL --validate VAL --json --html --out``)
runs in a fresh process per tree, the trees in turn, each with its own cache
of compiled functions (filled by one untimed run first). In the process:
the job's wall and CPU time (user + system, with its children: the base's
forked figure workers), and, timed inside it, importing ``casadical.html``
once the rest of what the job imports is loaded (matplotlib on a base that
draws with it) and ``Page.html``, which draws the figures and joins the page
(wall, and CPU of the process and its children). The JSON report and the
printed summary of both trees are compared (but the run time).

Usage::

    python benchmarks/speed/bench_figures.py --base /path/to/e23be15 --repeats 5
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SERIES_B = ROOT / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"

#: run in the tree's process: the job, with the import of casadical.html and Page.html timed
PROBE = r"""
import json, resource, sys, time
def cpu():
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime
t0, c0 = time.perf_counter(), cpu()
from casadical.cli import main
import casadical.calibration, casadical.diagnosis, casadical.prediction
t1, c1 = time.perf_counter(), cpu()
import casadical.html
from casadical.html import _page as page
t2, c2 = time.perf_counter(), cpu()
spent = []
draw = page.Page.html
def timed(self, *a, **k):
    t, c = time.perf_counter(), cpu()
    out = draw(self, *a, **k)
    spent.append((time.perf_counter() - t, cpu() - c))
    return out
page.Page.html = timed
code = main(sys.argv[1:])
t3, c3 = time.perf_counter(), cpu()
print(json.dumps({"code": code, "job_wall": t3 - t0, "job_cpu": c3 - c0, "import_wall": t2 - t1,
                  "import_cpu": c2 - c1, "html_wall": sum(s[0] for s in spent), "html_cpu": sum(s[1] for s in spent),
                  "has_matplotlib": "matplotlib" in sys.modules}), file=sys.stderr)
"""


def run(tree: str, cache: Path, folder: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=tree, CASADICAL_CACHE=str(cache))
    cmd = [sys.executable, "-c", PROBE, "diagnose", "ur10", "cal.csv", "--validate", "val.csv", "--json", "r.json",
           "--html", "r.html", "--out", "f.json", "--force"]
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=folder)
    if r.returncode:
        raise SystemExit(f"failed in {tree}:\n{r.stderr[-2000:]}")
    out = json.loads(r.stderr.strip().splitlines()[-1])
    out["stdout"] = re.sub(r"\(\d+\.\d s\)", "", r.stdout)
    out["json"] = {k: v for k, v in json.loads((folder / "r.json").read_text()).items() if k != "time_s"}
    out["html_bytes"] = (folder / "r.html").stat().st_size
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True, help="the tree to compare with (a checkout of the base commit)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    trees = {"this tree": str(ROOT), "base": str(Path(args.base).resolve())}
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; base {trees['base']}; median of "
          f"{args.repeats} runs each, the trees in turn\n")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run([sys.executable, "-m", "casadical", "split", str(SERIES_B), "-n", "300", "--seed", "0",
                        "--out-cal", "cal.csv", "--out-val", "val.csv"], check=True, capture_output=True, cwd=tmp,
                       env=dict(os.environ, PYTHONPATH=trees["this tree"]))
        caches = {k: tmp / f"cache-{i}" for i, k in enumerate(trees)}
        first = {k: run(v, caches[k], tmp) for k, v in trees.items()}          # untimed: fills each cache
        rows: dict = {k: [] for k in trees}
        for _ in range(args.repeats):
            for k, v in trees.items():
                rows[k].append(run(v, caches[k], tmp))
    print("| tree | job CPU | job wall | import casadical.html | figures (Page.html) CPU | wall | "
          "figures + import, share of the job's CPU | page size |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    med = {}
    for k, rs in rows.items():
        m = {f: statistics.median(r[f] for r in rs) for f in ("job_cpu", "job_wall", "import_cpu", "html_cpu",
                                                                "html_wall")}
        med[k] = m
        print(f"| {k}{' (matplotlib)' if rs[0]['has_matplotlib'] else ''} | {m['job_cpu']:.2f} s | "
              f"{m['job_wall']:.2f} s | {m['import_cpu']:.3f} s | {m['html_cpu']:.3f} s | {m['html_wall']:.3f} s | "
              f"{100 * (m['import_cpu'] + m['html_cpu']) / m['job_cpu']:.0f} % | {rs[0]['html_bytes'] / 1e6:.2f} MB |")
    pairs = list(zip(rows["this tree"], rows["base"]))

    def ratio(f) -> float:
        return statistics.median(f(a) / f(b) for a, b in pairs)

    print(f"\nthis tree / base, median of the pairs: job CPU {ratio(lambda r: r['job_cpu']):.2f}, wall "
          f"{ratio(lambda r: r['job_wall']):.2f}; figures and import CPU "
          f"{ratio(lambda r: r['html_cpu'] + r['import_cpu']):.3f}")
    a, b = first["this tree"], first["base"]
    same = a["json"] == b["json"] and a["stdout"] == b["stdout"]
    print("the JSON report and the printed summary: " + ("the same in both trees" if same else "DIFFER"))
    print(f"load average {os.getloadavg()[0]:.2f}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
