"""What a diagnosis does, counted: the units of work of its procedure in the three real jobs, how many of each and
what they cost (CPU, inclusive: a full fit's linearisations are counted in both rows).

The issue that asked for speed by procedure (37) reasoned from units: a screening round needs one linearisation
to score every candidate, so the README job's arithmetic would be about a second. This script counts what the
answers need at today's procedure: every full fit (a robust Levenberg-Marquardt solve of every calibration pose),
its linearisations, every candidate a round fits by one step (each recorded in the report as a step, with its
held-out means on the folds and its validation mean), the folds, the nameability checks, the structure screen's
pairs, the GP compensator's fits and its held-out folds, the predictions at the validation poses. Each job runs once
in a fresh process from this tree (and from ``--base``, in turn, each tree with its own cache), after an untimed
run that fills its cache of compiled functions (jobs of ``bench_stages.py``).

    python benchmarks/speed/bench_procedure.py --base /work/base      # beside aebf0e6's checkout
    python benchmarks/speed/bench_procedure.py --jobs readme
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_stages import prepare  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

#: the units: (row, module, owner (class or None), function); a call of an inner unit inside an outer call of the
#: same row is not counted again
UNITS = [
    ("full fits (calibrate, robust)", "casadical.diagnosis._state", "DiagnosisRun", "fit"),
    ("Levenberg-Marquardt solves", "casadical.solvers._lm", "LevenbergMarquardt", "solve"),
    ("linearisations of every calibration pose", "casadical.problem", "CalibrationProblem", "linearize"),
    ("screens (a round's linearisation, every candidate scored)", "casadical.diagnosis._screening", "Screen",
     "scores"),
    ("candidates fitted by one step (report steps)", "casadical.diagnosis._screening", "Screen", "fit"),
    ("held-out folds of a fit (35 folds each, linearised)", "casadical.diagnosis._validation", "Linearized", "cv"),
    ("nameability checks (harmonics, halves, drift)", "casadical.diagnosis._nameable", None, "cause_checks"),
    ("one-step fits at the validation poses", "casadical.diagnosis._screening", "Screen", "validation_errors"),
    ("full fits at the validation poses", "casadical.result", "CalibrationResult", "errors"),
    ("structure searches (140 pairs of covariate and effect each)", "casadical.diagnosis._structure",
     "StructureScreen", "strongest"),
    ("GP compensator fits (hyperparameters)", "casadical.compensators._gp", "ResidualGP", "fit"),
    ("GP compensator held-out folds", "casadical.calibration._per_session", None, "gp_compensator_held_out"),
]

CHILD = r"""
import functools, importlib, json, resource, sys, time
UNITS = json.loads(sys.argv[1])
count, cpu, depth = {}, {}, {}
extra = {"lm_iterations": 0}
def wrap(row, f):
    @functools.wraps(f)
    def g(*a, **k):
        if depth.get(row):
            return f(*a, **k)
        depth[row] = 1
        t = time.process_time()
        try:
            out = f(*a, **k)
        finally:
            depth[row] = 0
            cpu[row] = cpu.get(row, 0.0) + time.process_time() - t
            count[row] = count.get(row, 0) + 1
        if row.startswith("Levenberg"):
            extra["lm_iterations"] += out.iterations
        return out
    return g
for row, mod, owner, name in UNITS:
    try:            # an older tree may not have the unit (aebf0e6: no structure screen)
        m = importlib.import_module(mod)
        obj = getattr(m, owner) if owner else m
        f = getattr(obj, name)
    except (ImportError, AttributeError):
        continue
    if isinstance(f, classmethod) or (owner and isinstance(obj.__dict__.get(name), classmethod)):
        setattr(obj, name, classmethod(wrap(row, obj.__dict__[name].__func__)))
    else:
        setattr(obj, name, wrap(row, f))
    if not owner:   # imported by name elsewhere: rebind where the diagnosis calls it
        for other in list(sys.modules.values()):
            if getattr(other, "__name__", "").startswith("casadical") and getattr(other, name, None) is f:
                setattr(other, name, getattr(m, name))
from casadical.cli import main
try:
    main(sys.argv[2:])
except SystemExit:
    pass
me = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"count": count, "cpu": cpu, "extra": extra, "total": me.ru_utime + me.ru_stime}), file=sys.stderr)
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", nargs="+", default=["readme", "real2000", "sessions"],
                    choices=["readme", "real2000", "sessions"])
    ap.add_argument("--base", help="another tree to count beside this one (aebf0e6's checkout)")
    args = ap.parse_args()
    trees = {"this tree": str(ROOT), **({"base": str(Path(args.base).resolve())} if args.base else {})}
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; one run per job and tree; count / CPU "
          "seconds (inclusive)\n")
    got = {}
    with tempfile.TemporaryDirectory(prefix="procedure-") as tmp:
        envs = {k: dict(os.environ, PYTHONPATH=v, CASADICAL_CACHE=str(Path(tmp) / f"cache-{i}"))
                for i, (k, v) in enumerate(trees.items())}
        for job in args.jobs:
            folder = Path(tmp) / job
            folder.mkdir()
            cmd = prepare(job, folder, envs["this tree"])
            for tree, env in envs.items():
                subprocess.run([sys.executable, "-m", "casadical", *cmd], env=env, cwd=folder, capture_output=True,
                               check=True)                                  # fills the cache
                r = subprocess.run([sys.executable, "-c", CHILD, json.dumps(UNITS), *cmd], env=env, cwd=folder,
                                   capture_output=True, text=True)
                if r.returncode:
                    raise SystemExit(f"{job} ({tree}) failed:\n{r.stderr[-3000:]}")
                got[job, tree] = json.loads(r.stderr.strip().splitlines()[-1])
    cols = list(got)
    print("| unit of work | " + " | ".join(f"{j}{', ' + t if len(trees) > 1 else ''}" for j, t in cols) + " |")
    print("|---|" + "---:|" * len(cols))
    for row, *_ in UNITS:
        cells = []
        for c in cols:
            n, t = got[c]["count"].get(row, 0), got[c]["cpu"].get(row, 0.0)
            cells.append(f"{n} / {t:.2f} s" if n else "-")
        print(f"| {row} | " + " | ".join(cells) + " |")
    print("| Levenberg-Marquardt iterations | " + " | ".join(str(got[c]["extra"]["lm_iterations"]) for c in cols)
          + " |")
    print("| **the whole process** | " + " | ".join(f"{got[c]['total']:.2f} s" for c in cols) + " |")
    print(f"\nload average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
