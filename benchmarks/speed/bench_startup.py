"""Start-up of each command: the CPU its imports cost, beside an older tree's in the same run.

For each command a user runs (``calibrate``, ``diagnose`` without ``--html``, ``predict``, ``compensate``,
``export``, ``split``, ``inspect``), on the bundled real UR10 data (full pose; ``calibrate`` and
``predict`` of a kinematic calibration on the positions alone too):

1. the command runs once in a fresh process under each tree (this one; the older one on ``PYTHONPATH``,
   ``--base``), and the modules it imported are recorded (``sys.modules`` at its exit, in import order);
2. fresh processes import exactly those modules, the two trees in turn (new, old, new, old, ...), and the
   CPU time of the imports (``time.process_time``, the interpreter's own start-up left out) is taken,
   ``--repeats`` times; the table gives the medians and their ratio.

So a figure is the start-up a command pays before its work, on the machine as it is (CPU time, not wall,
is the figure that holds on a loaded machine). The table also names the heavy packages each command
imports: scikit-learn and matplotlib only where used, cvxpy only for planning, dask only for studies.

Usage::

    python benchmarks/speed/bench_startup.py --base fe55b8a          # ~3 min on 2 cores; the code before issue 26
    python benchmarks/speed/bench_startup.py --base /path/to/old/tree --repeats 9 --commands predict export

``--base`` is a git revision of this repository (its ``casadical/`` is extracted to a temporary folder) or
a folder that holds an older ``casadical/``; without it the table has this tree alone. Both run on this
interpreter and its packages.
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
SERIES = ROOT / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"
#: packages worth naming when a command imports them
HEAVY = ("scipy", "sklearn", "matplotlib", "cvxpy", "dask", "distributed", "pandas", "pyarrow", "yourdfpy",
         "tqdm", "casadi")
#: the columns of a measured orientation
ORIENTATION = {"rx_deg", "ry_deg", "rz_deg", "std_rx_deg", "std_ry_deg", "std_rz_deg"}
#: never imported again: the entry point
SKIP = {"__main__", "casadical.__main__"}


def commands(d: Path) -> dict[str, list[str]]:
    """Each command with its arguments, on the inputs in ``d`` (made by :func:`inputs`)."""
    return {
        "calibrate": ["calibrate", "ur10", str(d / "val.csv"), "--model", "kinematic", "--out", str(d / "o.json"),
                      "--force"],
        "calibrate, positions only": ["calibrate", "ur10", str(d / "val_xyz.csv"), "--model", "kinematic", "--out",
                                      str(d / "o.json"), "--force"],
        "diagnose": ["diagnose", "ur10", str(d / "cal.csv"), "--validate", str(d / "val.csv"), "--json",
                     str(d / "r.json"), "--force"],
        "predict": ["predict", str(d / "gp.json"), str(d / "val.csv"), "--out", str(d / "p.csv"), "--force"],
        "predict, no GP, positions only": ["predict", str(d / "k.json"), str(d / "val_xyz.csv"), "--out",
                                           str(d / "p.csv"), "--force"],
        "compensate": ["compensate", str(d / "gp.json"), str(d / "val.csv"), "--out", str(d / "j.csv"), "--force"],
        "export": ["export", str(d / "gp.json"), "--urdf", str(d / "o.urdf"), "--force"],
        "split": ["split", str(SERIES), "-n", "300", "--seed", "0", "--out-cal", str(d / "c.csv"), "--out-val",
                  str(d / "v.csv"), "--force"],
        "inspect": ["inspect", "ur10", "--poses", "60"],
    }


def _env(tree: Path | None) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    env.pop("PYTHONPATH", None)
    if tree is not None:
        env["PYTHONPATH"] = str(tree)
    return env


def _run(argv: list[str], tree: Path | None, cwd: Path) -> subprocess.CompletedProcess:
    """``argv`` in a fresh process on ``tree``'s code, in ``cwd`` (not this tree's root: ``python -c`` would
    find this tree's casadical/ there before ``PYTHONPATH``'s)."""
    return subprocess.run([sys.executable, *argv], env=_env(tree), cwd=cwd, capture_output=True, text=True)


def _casadical(args: list[str], d: Path, tree: Path | None = None) -> None:
    r = _run(["-m", "casadical", *args], tree, d)
    if r.returncode:
        raise SystemExit(f"casadical {' '.join(args)} failed:\n{r.stderr}")


def inputs(d: Path, tree: Path | None) -> None:
    """The data: the README's split of series B (300 calibration poses), 40 of the other poses as validation
    (full pose, and their positions alone), a calibration with the GP compensator
    (``kinematic+gp_compensator``) for predict, compensate, export, and a kinematic one of the positions.
    The calibrations are made by ``tree`` (the older code, whose files the newer reads)."""
    _casadical(["split", str(SERIES), "-n", "300", "--seed", "0", "--out-cal", str(d / "cal.csv"), "--out-val",
                str(d / "rest.csv")], d)
    lines = (d / "rest.csv").read_text().splitlines(keepends=True)
    (d / "val.csv").write_text("".join(lines[:41]))
    for name, rows in (("cal", None), ("val", 41)):      # the orientation columns left out
        table = list(csv.reader((d / f"{name}.csv").read_text().splitlines()[:rows]))
        keep = [k for k, c in enumerate(table[0]) if c not in ORIENTATION]
        with open(d / f"{name}_xyz.csv", "w", newline="") as f:
            csv.writer(f).writerows([[r[k] for k in keep] for r in table])
    _casadical(["calibrate", "ur10", str(d / "cal.csv"), "--model", "kinematic+gp_compensator", "--out",
                str(d / "gp.json")], d, tree)
    _casadical(["calibrate", "ur10", str(d / "cal_xyz.csv"), "--model", "kinematic", "--out", str(d / "k.json")], d,
               tree)


_RECORD = """
import json, sys
from casadical.cli import main
try:
    code = main({args!r})
except SystemExit as e:
    code = e.code
with open({out!r}, "w") as f:
    json.dump({{"code": code, "file": sys.modules["casadical"].__file__, "modules": list(sys.modules)}}, f)
"""

_TIME = """
import importlib, json, sys, time
names = json.load(open({path!r}))
t0 = time.process_time()
for n in names:
    if n not in sys.modules:
        try:
            importlib.import_module(n)
        except Exception:
            pass
print(time.process_time() - t0)
"""


def record(args: list[str], tree: Path | None, out: Path) -> list[str]:
    """The modules the command imports, in import order (and which code ran it: a check of ``PYTHONPATH``)."""
    r = _run(["-c", _RECORD.format(out=str(out), args=args)], tree, out.parent)
    doc = json.loads(out.read_text()) if out.exists() else {"code": r.returncode}
    if doc["code"]:
        raise SystemExit(f"casadical {' '.join(args)} failed:\n{r.stderr}")
    if not Path(doc["file"]).is_relative_to(tree or ROOT):
        raise SystemExit(f"the run meant for {tree or ROOT} ran {doc['file']}")
    names = [n for n in doc["modules"] if n not in SKIP]
    out.write_text(json.dumps(names))
    return names


def import_cpu(path: Path, tree: Path | None) -> float:
    """CPU seconds to import the modules listed in ``path``, in a fresh process."""
    r = _run(["-c", _TIME.format(path=str(path))], tree, path.parent)
    if r.returncode:
        raise SystemExit(r.stderr)
    return float(r.stdout.strip().splitlines()[-1])


def heavy(names: list[str]) -> str:
    tops = {n.split(".")[0] for n in names}
    return ", ".join(h for h in HEAVY if h in tops) or "-"


def old_tree(base: str, tmp: Path) -> Path:
    """The folder of the older code: ``base`` itself, or ``base``'s ``casadical/`` and built-in robots from git."""
    if (Path(base) / "casadical" / "__init__.py").exists():
        return Path(base).resolve()
    out = tmp / "base"
    out.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", base, "casadical", "problems/robots"],
                             capture_output=True)
    if archive.returncode:
        raise SystemExit(f"--base {base}: neither a folder with casadical/ nor a git revision "
                         f"({archive.stderr.decode().strip()})")
    subprocess.run(["tar", "-x", "-C", str(out)], input=archive.stdout, check=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", help="older code, side by side: a git revision, or a folder that holds casadical/")
    ap.add_argument("--repeats", type=int, default=7, help="timed imports per command and tree (default 7)")
    ap.add_argument("--commands", nargs="+", help="some commands only")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="casadical-startup-") as tmp:
        d = Path(tmp)
        trees = {"new": None} | ({"old": old_tree(a.base, d)} if a.base else {})
        inputs(d, trees.get("old"))
        cmds = commands(d)
        names = a.commands or list(cmds)
        rows = []
        for name in names:
            lists = {k: d / f"{name}.{k}.json" for k in trees}
            mods = {k: record(cmds[name], t, lists[k]) for k, t in trees.items()}
            cpu: dict[str, list[float]] = {k: [] for k in trees}
            for _ in range(a.repeats):          # the trees in turn: the machine's drift hits both
                for k, t in trees.items():
                    cpu[k].append(import_cpu(lists[k], t))
            rows.append((name, {k: (len([m for m in mods[k] if m.startswith("casadical")]), len(mods[k]),
                                    heavy(mods[k]), statistics.median(cpu[k])) for k in trees}))
            print(f"  {name}: done", file=sys.stderr)
    load = os.getloadavg()[0]
    print(f"Start-up CPU of each command: the imports it makes (median of {a.repeats}, trees in turn; "
          f"load {load:.1f}{f'; before: {a.base}' if a.base else ''})\n")
    if "old" in trees:
        print("| command | import CPU (s) | before (s) | ratio | modules (casadical's) | before | "
              "heavy packages imported | before |")
        print("|---|---:|---:|---:|---:|---:|---|---|")
        for name, r in rows:
            n, o = r["new"], r["old"]
            print(f"| {name} | {n[3]:.3f} | {o[3]:.3f} | {n[3] / o[3]:.2f} | {n[1]} ({n[0]}) | {o[1]} ({o[0]}) "
                  f"| {n[2]} | {o[2]} |")
    else:
        print("| command | import CPU (s) | modules (casadical's) | heavy packages imported |")
        print("|---|---:|---:|---|")
        for name, r in rows:
            n = r["new"]
            print(f"| {name} | {n[3]:.3f} | {n[1]} ({n[0]}) | {n[2]} |")


if __name__ == "__main__":
    main()
