"""The peer's calibration from touches (MUKCa) as a whole process, beside a casadical command, in one run.

MUKCa (github platonics-delft/kinematics_calibration, MIT: CasADi + IPOPT
on a URDF) calibrates a URDF from the ball-in-socket rows of one placement:
``python3 run_optimizer.py --model panda --data panda_2/front_center``, run
in its ``scripts/`` folder (its README). This times that whole process
(Python's start, the imports, the symbolic model and Hessian, IPOPT, the
URDF and the per-iteration files it writes) and, alternating with it in the
same run, the casadical command given with ``--casadical`` (a command line;
the lead plugs in ``casadical calibrate panda.urdf --urdf-tip ball_link
front_center.csv --fixture two_sockets.toml ...`` once it exists). Each is
the median of ``--runs`` runs of a fresh process (wall time, and CPU time of
the process and its children: on a loaded machine the better guide), its
first run also printed on its own (casadical's first run may compile its
model); then the ratio peer / casadical.

``--phases`` runs the peer once more inside a timing driver (the same
script, in one process) and prints where its time goes: Python's start,
the imports (CasADi, yourdfpy, forwardkinematics, tkinter), reading the URDF
and the data, the symbolic objective, ``nlpsol`` (CasADi builds the Hessian
of the Lagrangian here), IPOPT, and the per-iteration URDFs and KPIs.

``--calibrate-all DIR`` runs the peer once on every robot folder of its
data that has no calibrated URDF in the repository (on its first ``front*``
placement, as a user would start) and keeps each result in ``DIR/ROBOT/``
(the URDF, config.yaml, kpis.yaml) for ``study_touch_peer.py --peer-runs``.

The peer runs in a temporary copy of its ``scripts/``, ``urdf/``,
``config_optimizer/`` and the robot's data (its optimizer deletes and
rewrites ``calibrated_urdf/ROBOT``, which would replace the URDFs it ships),
under an X display (it creates a tkinter root window at import): the
``DISPLAY`` given, else an ``Xvfb`` this script starts and stops.

Setting the peer up (outside this repository; what was done here):

1. a checkout of the repository at commit 45ca7a1 (the one its README's
   figures come from; ``git sparse-checkout`` without ``imgs/*.gif`` where
   large files are absent);
2. a venv with its locked versions (``poetry.lock``): casadi 3.6.7, numpy
   1.23.5, yourdfpy 0.0.56, urdf-parser-py 0.0.4, matplotlib 3.7.5,
   pyyaml 6.0.2, trimesh 4.5.2, lxml 5.3.0, pyglet 1.5.29, scipy 1.10.1;
   ``pip install --no-deps -e`` of the checkout;
3. forwardkinematics at the locked commit 662b776 of its unpublished branch
   ``ft-symbolic-fk`` (PyPI's 1.2.3 has no ``symbolic_parameters``): the
   release 1.2.3 with that commit's ``urdfFks/urdfFk.py`` and
   ``urdfFks/casadiConversion/urdfparser.py``, plus one patch: its
   ``numpy_rpy`` writes the CasADi symbols of a fixed joint's origin (the
   ball joint's offset, a parameter) into a float numpy array, which numpy
   turns into NaN (IPOPT stops at once: "NaN detected for output
   grad_f_x"); the patch builds the same matrix in CasADi when an entry is
   symbolic. With it the run reproduces the README's figures (8.278 ->
   0.168 mm, distance error 0.001 mm, 8 iterations);
4. ``apt-get install xvfb`` (Debian's Python has tkinter in python3-tk).

Usage::

    python benchmarks/speed/bench_touch_peer.py --peer /work/peer/kinematics_calibration \\
        --peer-python /work/peer/venv/bin/python --runs 5 --phases \\
        --casadical "casadical calibrate ... --json /tmp/cal.json --force"
    MUKCA_PEER=... MUKCA_PEER_PYTHON=... python benchmarks/speed/bench_touch_peer.py

``--warm N`` (default 7) also times, in this process, a warm
``calibrate()`` of the same rows (the bundled ``placements/front_center.csv``
with ``two_sockets.toml``, ``--model``, IPOPT and Levenberg-Marquardt; the
first call, which may compile the model, apart) beside its baseline in the
same run: the tracker calibration of the same 60 readings, their points
measured (the touch calibration's prediction plus 0.1 mm of noise per
axis), the same model and solver. Issue 45 asks for at most 0.5 s.

Without the peer (no ``--peer``, no ``MUKCA_PEER``, or not a checkout) it
prints one line saying so and only the warm figures. Timings need an idle
machine: the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "datasets"))
from mukca import front_placement, model_of  # noqa: E402

#: run inside the peer's Python: its script's main() with timers around its stages (printed as one JSON line)
PHASES_DRIVER = r"""
import json, sys, time
t = {"start": time.perf_counter()}
sys.argv = ["run_optimizer.py"] + sys.argv[1:]
sys.path.insert(0, ".")
import run_optimizer                                  # casadi, yourdfpy, forwardkinematics, tkinter's root
t["imported"] = time.perf_counter()
import casadi as ca
from calibrate_fk.parameter_optimizer import ParameterOptimizer
spans = {}
def timed(name, f):
    def g(*a, **k):
        t0 = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            spans[name] = spans.get(name, 0.0) + time.perf_counter() - t0
    return g
_nlpsol = ca.nlpsol
def nlpsol(*a, **k):
    t0 = time.perf_counter()
    solver = _nlpsol(*a, **k)
    spans["nlpsol (Hessian built)"] = time.perf_counter() - t0
    class Timed:
        def __call__(self, *b, **c):
            out = timed("IPOPT", solver)(*b, **c)
            spans["IPOPT iterations"] = solver.stats()["iter_count"]
            return out
        def stats(self):
            return solver.stats()
    return Timed()
ca.nlpsol = nlpsol
for name in ("load_model", "read_data", "create_symbolic_fk", "evaluate_fks", "optimize",
             "save_intermediate_solution"):
    setattr(ParameterOptimizer, name, timed(name, getattr(ParameterOptimizer, name)))
run_optimizer.main()
t["end"] = time.perf_counter()
print("PHASES " + json.dumps({"import": t["imported"] - t["start"], "main": t["end"] - t["imported"],
                              "spans": spans}))
"""


def load_average() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def timed_run(cmd: list[str], cwd: Path | None = None, env: dict | None = None) -> tuple[float, float, str]:
    """Wall time, CPU time (user + system of the process and its children), stdout; exits on failure."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        tail = "\n".join((r.stdout + r.stderr).strip().splitlines()[-15:])
        raise SystemExit(f"bench_touch_peer.py: failed ({r.returncode}): {shlex.join(cmd)}\n{tail}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), r.stdout


@contextmanager
def x_display():
    """An X display for tkinter: the DISPLAY given, or an Xvfb started here for the duration."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        raise SystemExit("bench_touch_peer.py: the peer needs an X display (it opens a tkinter root): "
                         "set DISPLAY or install Xvfb (apt-get install xvfb)")
    for n in range(90, 140):
        if not Path(f"/tmp/.X{n}-lock").exists():
            break
    proc = subprocess.Popen([xvfb, f":{n}", "-nolisten", "tcp", "-screen", "0", "640x480x24"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(100):
            if Path(f"/tmp/.X11-unix/X{n}").exists():
                break
            time.sleep(0.05)
        yield f":{n}"
    finally:
        proc.terminate()
        proc.wait()


def work_copy(peer: Path, robot: str, into: Path) -> Path:
    """A copy of what the peer's run_optimizer.py reads and writes, with ``robot``'s data only."""
    for folder in ("scripts", "urdf", "config_optimizer"):
        shutil.copytree(peer / folder, into / folder)
    shutil.copytree(peer / "data" / robot, into / "data" / robot)
    (into / "calibrated_urdf").mkdir()
    return into


def peer_command(python: str, robot: str, placement: str) -> list[str]:
    return [python, "run_optimizer.py", "--model", model_of(robot), "--data", f"{robot}/{placement}"]


def peer_result(stdout: str) -> tuple[float, float, float]:
    """(consistency before, after, distance error after), mm, from the peer's printout (its evaluate_fks before
    and after the fit)."""
    mae = [float(x) for x in re.findall(r"Mean absolute error: (\S+)", stdout)]
    dist = [float(x) for x in re.findall(r"Distance error: (\S+)", stdout)]
    if len(mae) < 2 or len(dist) < 2:
        raise SystemExit("bench_touch_peer.py: the peer printed no result:\n" + stdout[-2000:])
    return mae[0] * 1000, mae[-1] * 1000, dist[-1] * 1000


def bench(args, peer: Path, python: str) -> dict:
    env = dict(os.environ)
    casadical_cmd = shlex.split(args.casadical) if args.casadical else None
    out = {"load_before": load_average(), "peer": [], "casadical": []}
    with tempfile.TemporaryDirectory(prefix="mukca-") as tmp, x_display() as display:
        env["DISPLAY"] = display
        scripts = work_copy(peer, args.robot, Path(tmp)) / "scripts"
        cmd = peer_command(python, args.robot, args.placement)
        rows = sum(len((peer / "data" / args.robot / args.placement / f"hole_{k}.csv").read_text().splitlines())
                   for k in (0, 1))
        print(f"peer: {shlex.join(cmd)}  (in a copy of {peer}; {rows} rows of {args.robot}/{args.placement}; "
              f"DISPLAY {display})")
        if casadical_cmd:
            print(f"casadical: {shlex.join(casadical_cmd)}")
        for i in range(args.runs):
            wall, cpu, stdout = timed_run(cmd, cwd=scripts, env=env)
            out["peer"].append((wall, cpu))
            if i == 0:
                before, after, dist = peer_result(stdout)
                out["peer_fit"] = {"consistency_before_mm": before, "consistency_after_mm": after,
                                   "distance_error_after_mm": dist}
                print(f"peer's fit on its training rows: consistency {before:.3f} -> {after:.3f} mm, distance "
                      f"error {dist:.4f} mm")
            if casadical_cmd:
                out["casadical"].append(timed_run(casadical_cmd, env=env)[:2])
        if args.phases:
            wall, _, stdout = timed_run([python, "-c", PHASES_DRIVER] + cmd[2:], cwd=scripts, env=env)
            line = next(ln for ln in stdout.splitlines() if ln.startswith("PHASES "))
            out["phases"] = json.loads(line[len("PHASES "):]) | {"process": wall}
    out["load_after"] = load_average()
    return out


def report(out: dict, runs: int) -> None:
    print(f"\nload average before {out['load_before']}, after {out['load_after']}; median of {runs} run(s), "
          f"first run apart")
    medians = {}
    for who in ("peer", "casadical"):
        t = out[who]
        if not t:
            continue
        medians[who] = (statistics.median(w for w, _ in t), statistics.median(c for _, c in t))
        print(f"{who:<10} wall {medians[who][0]:7.2f} s  CPU {medians[who][1]:7.2f} s   (first run: wall "
              f"{t[0][0]:.2f} s, CPU {t[0][1]:.2f} s)")
    if len(medians) == 2:
        (pw, pc), (cw, cc) = medians["peer"], medians["casadical"]
        print(f"ratio peer / casadical: wall {pw / cw:.1f}x, CPU {pc / cc:.1f}x")
    if "phases" in out:
        p = out["phases"]
        s = p["spans"]
        known = ("load_model", "read_data", "create_symbolic_fk", "evaluate_fks", "optimize")
        print("\nthe peer's time, one run in a timing driver (s):")
        print(f"  {'the whole process':<62}{p['process']:6.2f}")
        print(f"  {'Python start and exit, the driver':<62}{p['process'] - p['import'] - p['main']:6.2f}")
        print(f"  imports (casadi, yourdfpy, forwardkinematics, tkinter root)   {p['import']:6.2f}")
        for name in known[:4]:
            label = name + (" (before and after the fit)" if name == "evaluate_fks" else "")
            print(f"  {label:<62}{s.get(name, 0.0):6.2f}")
        saving = s.get("save_intermediate_solution", 0.0)
        rest = s["optimize"] - s["nlpsol (Hessian built)"] - s["IPOPT"] - saving
        print(f"  {'optimize: symbolic objective (a substitute per row), URDF out':<62}{rest:6.2f}")
        print(f"  {'optimize: nlpsol (CasADi builds the Hessian of the Lagrangian)':<62}"
              f"{s['nlpsol (Hessian built)']:6.2f}")
        print(f"  {'optimize: IPOPT, ' + str(s['IPOPT iterations']) + ' iterations':<62}{s['IPOPT']:6.2f}")
        print(f"  {'optimize: per-iteration URDFs and KPIs (saving_steps)':<62}{saving:6.2f}")
        print(f"  {'everything inside main()':<62}{p['main']:6.2f}")


DATASET = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "panda-mukca"


def warm_calibrations(runs: int, model: str) -> dict:
    """Median wall time (s) of a warm in-process ``calibrate()`` of panda_2's front_center rows (touches) and of a
    tracker calibration of the same readings, per solver; the first (compiling) call apart."""
    import warnings

    import numpy as np

    from casadical import Measurements, calibrate, load_robot
    from casadical.rows import read_fixture_file

    warnings.simplefilter("ignore")     # the calibrations' notes are theirs; the times are ours
    arm = load_robot(DATASET / "raw" / "urdf" / "panda.urdf", tip="ball_link")
    touch = Measurements.read_csv(DATASET / "placements" / "front_center.csv", robot=arm).with_fixtures(
        read_fixture_file(DATASET / "two_sockets.toml"))
    t0 = time.perf_counter()
    fitted = calibrate(arm, touch, model)
    first = time.perf_counter() - t0
    xyz = fitted.predict(touch) + np.random.default_rng(0).normal(scale=1e-4, size=(len(touch), 3))
    tracker = Measurements.from_arrays(touch.q, xyz)
    out = {"rows": len(touch), "model": model, "first_s": first, "load": load_average()}
    for solver in ("ipopt", "lm"):
        for name, data in (("touch", touch), ("tracker", tracker)):
            calibrate(arm, data, model, solver=solver)       # this solver's first call (IPOPT builds its solver)
            times = []
            for _ in range(runs):
                t0 = time.perf_counter()
                calibrate(arm, data, model, solver=solver)
                times.append(time.perf_counter() - t0)
            out[f"{name}_{solver}_s"] = statistics.median(times)
    out["load_after"] = load_average()
    return out


def report_warm(w: dict, runs: int) -> None:
    print(f"\nwarm in-process calibrate() of {w['rows']} rows, model {w['model']}, median of {runs} (load average "
          f"{w['load']} before, {w['load_after']} after; the first call of the process {w['first_s']:.2f} s):")
    print(f"  {'solver':<28}{'touches, 2 sockets (s)':>24}{'tracker, same readings (s)':>28}{'ratio':>8}")
    for solver, label in (("ipopt", "IPOPT (the default)"), ("lm", "Levenberg-Marquardt")):
        t, k = w[f"touch_{solver}_s"], w[f"tracker_{solver}_s"]
        print(f"  {label:<28}{t:>24.3f}{k:>28.3f}{t / k:>8.2f}")
    print("  issue 45: at most 0.5 s")


def calibrate_all(peer: Path, python: str, into: Path) -> None:
    """Run the peer on every robot without a calibrated URDF in its repository; keep the results in ``into``."""
    env = dict(os.environ)
    with x_display() as display:
        env["DISPLAY"] = display
        for folder in sorted(p for p in (peer / "data").iterdir() if p.is_dir()):
            robot = folder.name
            model = model_of(robot)
            placements = [p.name for p in folder.iterdir() if (p / "hole_0.csv").exists()]
            if (peer / "calibrated_urdf" / robot / f"{model}.urdf").exists() or len(placements) < 2:
                continue
            place = front_placement(placements)
            with tempfile.TemporaryDirectory(prefix="mukca-") as tmp:
                scripts = work_copy(peer, robot, Path(tmp)) / "scripts"
                wall, _, stdout = timed_run(peer_command(python, robot, place), cwd=scripts, env=env)
                before, after, dist = peer_result(stdout)
                made = Path(tmp) / "calibrated_urdf" / robot
                (into / robot).mkdir(parents=True, exist_ok=True)
                for name in (f"{model}.urdf", "config.yaml", "kpis.yaml"):
                    shutil.copy2(made / name, into / robot / name)
            print(f"{robot}: trained on {place}: consistency {before:.3f} -> {after:.3f} mm, distance error "
                  f"{dist:.4f} mm ({wall:.1f} s) -> {into / robot}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--peer", type=Path, default=os.environ.get("MUKCA_PEER"),
                    help="checkout of the peer at 45ca7a1 (default: $MUKCA_PEER)")
    ap.add_argument("--peer-python", default=os.environ.get("MUKCA_PEER_PYTHON"),
                    help="the Python of the peer's venv (default: $MUKCA_PEER_PYTHON, else venv/bin/python beside "
                         "or inside the checkout)")
    ap.add_argument("--robot", default="panda_2")
    ap.add_argument("--placement", default="front_center")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--casadical", help="a casadical command line to time beside the peer (quoted)")
    ap.add_argument("--phases", action="store_true", help="also time the peer's stages in one run")
    ap.add_argument("--calibrate-all", type=Path, metavar="DIR",
                    help="run the peer on every robot without a shipped calibrated URDF; results to DIR")
    ap.add_argument("--warm", type=int, default=7, metavar="N",
                    help="runs of the warm in-process calibrate() and its tracker baseline (0: none)")
    ap.add_argument("--model", default="kinematic", help="the model of the warm calibrations")
    ap.add_argument("--json", type=Path, help="write the timings here")
    args = ap.parse_args(argv)
    warm = None
    if args.warm > 0:
        warm = warm_calibrations(args.warm, args.model)
        report_warm(warm, args.warm)
    peer = Path(args.peer) if args.peer else None
    if peer is None or not (peer / "scripts" / "run_optimizer.py").exists():
        print(f"bench_touch_peer.py: the peer skipped: no checkout of the peer (MUKCa) at "
              f"{peer or '(none: give --peer or MUKCA_PEER)'}")
        if args.json and warm:
            args.json.write_text(json.dumps({"warm": warm}, indent=1))
        return 0
    python = args.peer_python or next(
        (str(p) for p in (peer.parent / "venv" / "bin" / "python", peer / ".venv" / "bin" / "python",
                          peer / "venv" / "bin" / "python") if p.exists()), None)
    if python is None:
        print("bench_touch_peer.py: skipped: no Python for the peer (give --peer-python or MUKCA_PEER_PYTHON)")
        return 0
    if args.calibrate_all:
        calibrate_all(peer, python, args.calibrate_all)
        return 0
    out = bench(args, peer, python)
    out["warm"] = warm
    report(out, args.runs)
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
