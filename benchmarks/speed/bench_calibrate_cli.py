"""``casadical calibrate`` end to end (process start to JSON) against scipy baselines, same run.

Data: 200 and 1,000 poses drawn (seed 0) from the bundled real UR10 series
``problems/datasets/ur10-ipa/series_b.csv``; models ``kinematic`` and
``kinematic+compliance``; the poses not drawn are the validation set.

Each row is the wall time of a fresh process, from its start to its JSON
file, and its CPU time (user + system, with its children such as the C
compiler: on a loaded machine the better guide to the time on an idle
one), median of ``--repeats`` runs (cold: one run):

- casadical, cold cache: ``casadical calibrate`` with an empty cache of
  compiled functions (``CASADICAL_CACHE`` = a new folder), default solver
  (IPOPT) and loss (pseudo-Huber, noise scale re-estimated);
- casadical, warm cache: the same command again (IPOPT, and ``--solver lm``);
- (a) scipy: the same model (casadical's CasADi model, virtual machine)
  solved by ``scipy.optimize.least_squares`` with its defaults (``trf``,
  2-point finite differences), the same robust loss written as least
  squares (each pose's residual times ``sqrt(2 rho(u2) / u2)``) and the same
  noise-scale loop; (a') the same with the exact Jacobian (CasADi AD);
- (b) FIGAROH-style: a numpy forward model (``numpy_model.py``), its
  Jacobian by scipy's forward differences, ``least_squares(method="lm")``,
  as FIGAROH's calibration does, same loss and loop.

The baselines get casadical's free parameter set and start (nominal
parameters, base by the same closed-form alignment) for free: their time
has no identifiability analysis and no uncertainty. Accuracy: RMS (mm) of
the position error on the calibration poses and on the validation poses,
and the largest parameter difference to casadical's IPOPT result in units of
the parameter's typical size.

The whole table is measured twice: as the machine is, and with one other
CPU-bound process running (a busy loop this script starts and stops). The
load average is printed with each.

Usage::

    python benchmarks/speed/bench_calibrate_cli.py                  # ~5-10 min on 2 cores
    python benchmarks/speed/bench_calibrate_cli.py --sizes 200 --models kinematic --repeats 3
    python benchmarks/speed/bench_calibrate_cli.py --json out.json

BLAS runs single-threaded in every process (``OPENBLAS_NUM_THREADS=1``
unless set). Targets (issue 12): 200 poses <= 1 s with a warm cache, >= 10x
the scipy calibration, each figure with a busy core at most 2x its value
without.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from bench_plan_poses import passes  # noqa: E402  (this folder is on sys.path when run as a script)

HERE = Path(__file__).resolve().parent
SERIES = HERE.parents[1] / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"
TARGET_S, SPEEDUP, BUSY_RATIO = 1.0, 10.0, 2.0


# --- the baselines (run in their own process: python bench_calibrate_cli.py --baseline ...) ----------


def _kabsch(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """4x4 pose T minimising |T P - Q| (rows are points)."""
    cp, cq = P.mean(0), Q.mean(0)
    U, _, Vt = np.linalg.svd((P - cp).T @ (Q - cq))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, cq - R @ cp
    return T


def baseline(kind: str, data_csv: str, spec: str, free_json: str, out: str) -> None:
    """Calibrate like casadical (robust loss, noise-scale loop) with scipy; write values and base0."""
    from scipy.optimize import least_squares

    from casadical.data import Measurements
    from casadical.loading import load_robot
    from casadical.model import Model

    robot = load_robot("ur10")
    data = Measurements.read_csv(data_csv, n_joints=6, require_positions=True)
    model = Model(robot, spec, jit=False)
    names = model.parameters.names
    p0 = model.parameters.values.copy()
    scale = model.parameters.scales
    free = np.array([names.index(n) for n in json.loads(Path(free_json).read_text())])
    q, xyz = data.q, data.xyz
    cov = model.covariates(data)
    eye = np.concatenate([np.eye(3).ravel(), np.zeros(3)])
    if kind == "figaroh":
        sys.path.insert(0, str(HERE))
        from numpy_model import NumpyModel

        npm = NumpyModel(robot, names, scale)
        payload = cov[:, model.covariate_names.index("payload_kg")]
        T = _kabsch(npm.predict(q, p0, payload, eye), xyz)
    else:
        T = _kabsch(model.predict(q, p0, cov, eye), xyz)
    base0 = np.concatenate([T[:3, :3].ravel(), T[:3, 3]])

    def values(x):
        v = p0.copy()
        v[free] = p0[free] + scale[free] * x
        return v

    def weights(r, delta):   # residual of a pose times sqrt(2 rho(u2) / u2): the pseudo-Huber loss
        u2 = np.einsum("ij,ij->i", r, r)
        return np.sqrt(2.0 / (np.sqrt(1.0 + delta * u2) + 1.0)), u2

    if kind == "figaroh":
        def fun(x, delta):
            r = npm.predict(q, values(x), payload, base0) - xyz
            return (r * weights(r, delta)[0][:, None]).ravel()
        jac = "2-point"
        method = "lm"
    elif kind == "scipy":
        def fun(x, delta):
            r = model.predict(q, values(x), cov, base0) - xyz
            return (r * weights(r, delta)[0][:, None]).ravel()
        jac = "2-point"
        method = "trf"
    else:
        def fun(x, delta):
            r = model.predict(q, values(x), cov, base0) - xyz
            return (r * weights(r, delta)[0][:, None]).ravel()

        def jac(x, delta):   # exact: d(w r)/dx with w = w(u2(x))
            v = values(x)
            y, J = model.predict_jacobian(q, v, cov, base0)
            r = y - xyz
            w, u2 = weights(r, delta)
            Jx = J[:, :, free] * scale[free]
            dw = -w ** 3 * delta / (8.0 * np.sqrt(1.0 + delta * u2))    # dw/du2
            g = 2 * np.einsum("nk,nkp->np", r, Jx)                     # du2/dx
            return (w[:, None, None] * Jx + (dw[:, None] * g)[:, None, :] * r[:, :, None]).reshape(-1, len(free))
        method = "trf"
    x = np.zeros(len(free))
    sigma, c = math.nan, 3.0
    for _ in range(6):   # casadical.calibration._solve.ROBUST_LOOPS: re-estimate the noise scale until it settles
        r = (model.predict(q, values(x), cov, base0) if kind != "figaroh"
             else npm.predict(q, values(x), payload, base0)) - xyz
        new = max(float(np.median(np.linalg.norm(r, axis=1))) / 1.5381722544550522, 1e-12)
        if math.isfinite(sigma) and abs(new / sigma - 1) < 0.05:
            break
        sigma = new
        delta = 1.0 / (c * sigma) ** 2
        x = least_squares(fun, x, jac=jac, method=method, args=(delta,)).x
    Path(out).write_text(json.dumps({"names": names, "values": values(x).tolist(), "base0": base0.tolist()}))


# --- the benchmark --------------------------------------------------------------------------------------


def wall(cmd: list[str], env: dict) -> tuple[float, float]:
    """Wall time and CPU time (user + system, the process and its children such as the compiler)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{r.stderr}")
    return dt, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def accuracy(spec, cal, val, values, base0):
    from casadical.loading import load_robot
    from casadical.model import Model

    m = Model(load_robot("ur10"), spec, jit=False)

    def rms(d):
        e = m.predict(d.q, values, m.covariates(d), base0) - d.xyz
        return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))) * 1e3)
    return rms(cal), rms(val)


def run_table(args, tmp: Path, label: str) -> list[dict]:
    from casadical.data import Measurements
    from casadical.result import load_calibration

    full = Measurements.read_csv(SERIES, n_joints=6)
    rows = []
    py = sys.executable
    for N in args.sizes:
        idx = np.sort(np.random.default_rng(0).choice(len(full), N, replace=False))
        cal, val = full.subset(idx), full.subset(np.setdiff1d(np.arange(len(full)), idx))
        csv = tmp / f"ur10_{N}.csv"
        cal.write_csv(csv, overwrite=True)
        for spec in args.models:
            env = dict(os.environ, CASADICAL_CACHE=str(tmp / f"cache_{label}_{N}_{spec}"))
            out = tmp / "cal.json"
            cmd = [py, "-m", "casadical", "calibrate", "ur10", str(csv), "--model", spec, "--out", str(out),
                   "--force"]
            times = {"casadical IPOPT, cold cache": [wall(cmd, env)]}
            times["casadical IPOPT, warm cache"] = [wall(cmd, env) for _ in range(args.repeats)]
            res = load_calibration(out)
            ref = {"values": res.parameters.values, "base0": res.base0}
            scale = res.parameters.scales
            free = [p.name for p in res.parameters if not p.fixed]
            (tmp / "free.json").write_text(json.dumps(free))
            lm_out = tmp / "lm.json"
            times["casadical LM, warm cache"] = [wall(cmd[:-3] + ["--solver", "lm", "--out", str(lm_out),
                                                                  "--force"], env) for _ in range(args.repeats)]
            lm = load_calibration(lm_out)
            outs = {"casadical IPOPT, cold cache": ref, "casadical IPOPT, warm cache": ref,
                    "casadical LM, warm cache": {"values": lm.parameters.values, "base0": lm.base0}}
            for kind, name in (("scipy", "(a) scipy least_squares (trf, 2-point), same CasADi model"),
                               ("scipy-exact", "(a') scipy least_squares (trf), same model, exact Jacobian"),
                               ("figaroh", "(b) FIGAROH-style: numpy model, finite differences, scipy lm")):
                b_out = tmp / f"{kind}.json"
                bcmd = [py, __file__, "--baseline", kind, str(csv), spec, str(tmp / "free.json"), str(b_out)]
                times[name] = [wall(bcmd, env) for _ in range(args.baseline_repeats)]
                doc = json.loads(b_out.read_text())
                outs[name] = {"values": np.array(doc["values"]), "base0": np.array(doc["base0"])}
            for name, ts in times.items():
                o = outs[name]
                rc, rv = accuracy(spec, cal, val, o["values"], o["base0"])
                dp = float(np.max(np.abs(o["values"] - ref["values"]) / scale))
                row = {"pass": label, "poses": N, "model": spec, "method": name,
                       "time_s": statistics.median(t[0] for t in ts), "cpu_s": statistics.median(t[1] for t in ts),
                       "runs": ts, "rms_cal_mm": rc, "rms_val_mm": rv, "dp_max": dp, "load": os.getloadavg()[0]}
                rows.append(row)
                print(f"| {N:,} | {spec} | {name} | {row['time_s']:.2f} s | {row['cpu_s']:.2f} s | {rc:.4f} | "
                      f"{rv:.4f} | {dp:.1e} | {row['load']:.1f} |", flush=True)
    return rows


def summary(rows: list[dict]) -> None:
    def t(pass_, N, spec, method, key):
        return next((r[key] for r in rows if r["pass"] == pass_ and r["poses"] == N and r["model"] == spec
                     and r["method"].startswith(method)), math.nan)
    print("\nTargets (issue 12), wall time (CPU time):")
    for N, spec in sorted({(r["poses"], r["model"]) for r in rows}):
        w = {k: t("as is", N, spec, m, "time_s") for k, m in (("c", "casadical IPOPT, warm"), ("a", "(a)"),
                                                              ("e", "(a')"), ("b", "(b)"))}
        c = {k: t("as is", N, spec, m, "cpu_s") for k, m in (("c", "casadical IPOPT, warm"), ("a", "(a)"),
                                                             ("e", "(a')"), ("b", "(b)"))}
        line = (f"  {N:,} poses, {spec}: warm {w['c']:.2f} s ({c['c']:.2f} s); against it (a) scipy "
                f"{w['a'] / w['c']:.1f}x ({c['a'] / c['c']:.1f}x), (a') {w['e'] / w['c']:.1f}x "
                f"({c['e'] / c['c']:.1f}x), (b) FIGAROH-style {w['b'] / w['c']:.1f}x ({c['b'] / c['c']:.1f}x)")
        if N == 200 and spec == "kinematic":
            line += (f" [<= 1 s: wall {'MET' if w['c'] <= TARGET_S else 'NOT MET'}, CPU "
                     f"{'MET' if c['c'] <= TARGET_S else 'NOT MET'}; >= 10x scipy: "
                     f"{'MET' if min(w['a'] / w['c'], c['a'] / c['c']) >= SPEEDUP else 'NOT MET'}]")
        print(line)
    busy = [(r, t("one busy core", r["poses"], r["model"], r["method"], "time_s")) for r in rows
            if r["pass"] == "as is"]
    ratios = [b / r["time_s"] for r, b in busy if math.isfinite(b)]
    if ratios:
        print(f"  with one busy core: {min(ratios):.2f}x - {max(ratios):.2f}x the wall time without "
              f"[<= 2x: {'MET' if max(ratios) <= BUSY_RATIO else 'NOT MET'}]")


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--baseline":
        baseline(*sys.argv[2:7])
        return 0
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 1000])
    ap.add_argument("--models", nargs="+", default=["kinematic", "kinematic+compliance"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline-repeats", type=int, default=1)
    ap.add_argument("--no-busy", action="store_true", help="skip the pass with a busy core")
    ap.add_argument("--json", help="save the rows")
    args = ap.parse_args()
    import casadi
    import scipy
    print(f"Python {sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"CasADi {casadi.__version__}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    rows = []
    head = ("| poses | model | method | wall (median) | CPU (median) | RMS cal (mm) | RMS val (mm) | "
            "max dp vs IPOPT | load |")
    with tempfile.TemporaryDirectory() as tmp:
        for label, context in passes(args.no_busy):
            print(f"\n{label}:\n\n{head}\n|---:|---|---|---:|---:|---:|---:|---:|---:|", flush=True)
            with context():
                rows += run_table(args, Path(tmp), label)
    summary(rows)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
