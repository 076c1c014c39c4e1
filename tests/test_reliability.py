"""Issue 21: interrupts stop the work, a fit that does not fit is an error, every bad case is one clear line.

Signals are sent to real ``casadical`` processes at a moment where the work
runs (IPOPT iterating, figure workers drawing); robots that matter are arms
that are not built in (tests/arms.py).
"""

import functools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from arms import ARM4, ARM5, to_toml

from casadical.cli import main
from casadical.files import atomic_write, outputs_together
from casadical.robot import robot_from_dict
from casadical.simulate import Effects, simulate

ROOT = Path(__file__).resolve().parent.parent


def cli(capsys, *args):
    """The command line in-process: exit code, stdout, stderr lines."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.strip().splitlines() if line]


def one_error(err, *parts):
    assert len(err) == 1, err
    assert err[0].startswith("casadical: error: "), err
    for part in parts:
        assert part in err[0], err


@functools.cache
def _arm_files(folder: str, name: str, n: int, seed: int) -> tuple[str, str]:
    arm = {"arm5": ARM5, "arm4": ARM4}[name]
    robot_file = Path(folder) / f"{name}.toml"
    robot_file.write_text(to_toml(arm))
    data, _ = simulate(robot_from_dict(arm, name), n, Effects(), seed=seed)
    data_file = Path(folder) / f"{name}-{n}-{seed}.csv"
    data.write_csv(data_file, overwrite=True)
    return str(robot_file), str(data_file)


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    """``arms(name, n, seed)``: (robot TOML, simulated poses CSV) of a test arm, made once per module."""
    folder = str(tmp_path_factory.mktemp("arms"))
    return lambda name, n, seed=0: _arm_files(folder, name, n, seed)


# --- 1. interrupts ---------------------------------------------------------------------------------------


def _start(args, tmp_path, **env):
    return subprocess.Popen([sys.executable, "-m", "casadical", *map(str, args)], cwd=tmp_path,
                            env={**os.environ, "PYTHONPATH": str(ROOT), "CASADICAL_JIT": "0", **env},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _children(pid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                stat = Path(f"/proc/{d}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(d))
    return out


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _finish(p, pids=()):
    """Wait for ``p`` (60 s at most; then it and ``pids`` are killed and the test fails)."""
    try:
        return p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        for pid in [p.pid, *pids]:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        p.communicate()
        pytest.fail("the command did not end within 60 s of the signal")


def _nothing_left(tmp_path, *names):
    for name in names:
        assert not (tmp_path / name).exists(), name
    assert not list(tmp_path.glob(".*.part")), list(tmp_path.glob(".*.part"))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_stops_an_ipopt_solve(arms, tmp_path, sig, code):
    """CasADi catches the interrupt inside IPOPT and returns its last iterate: that must not become a
    calibration with exit 0. The signal is sent once the process has used 2 s of CPU: IPOPT iterates on
    3,000 poses then (the whole run takes about 5 s)."""
    robot, data = arms("arm5", 3000)
    p = _start(["calibrate", robot, data, "--solver", "ipopt", "--out", "cal.json", "--html", "cal.html"],
               tmp_path)
    while p.poll() is None and _cpu_s(p.pid) < 2.0:
        time.sleep(0.02)
    assert p.poll() is None, "finished before the signal"
    if sig == signal.SIGINT:
        os.killpg(p.pid, sig)   # a terminal's Ctrl-C: the whole process group
    else:
        os.kill(p.pid, sig)
    t = time.monotonic()
    _, err = _finish(p)
    assert time.monotonic() - t < 10
    assert p.returncode == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("casadical: ") and "no output was written" in lines[0], err
    _nothing_left(tmp_path, "cal.json", "cal.html")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked figure workers: Linux only")
@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_while_the_report_is_drawn_ends_its_workers(arms, tmp_path, sig, code):
    """SIGTERM to ``diagnose`` while forked workers draw the HTML report's figures: the command exits 143
    with one line, no worker outlives it, and none of its outputs (the JSON was written before the HTML)
    is left."""
    robot, data = arms("arm5", 300, 1)
    _, val = arms("arm5", 1500, 2)
    p = _start(["diagnose", robot, data, "--validate", val, "--json", "r.json", "--html", "r.html", "--out",
                "f.json", "--quiet", "--no-blackbox"], tmp_path, CASADICAL_EVAL_THREADS="2")
    kids: list[int] = []
    while p.poll() is None and not kids:
        kids = _children(p.pid)
        time.sleep(0.01)
    assert kids, "no figure worker was forked"
    if sig == signal.SIGINT:
        os.killpg(p.pid, sig)
    else:
        os.kill(p.pid, sig)
    _, err = _finish(p, kids)
    time.sleep(0.2)
    assert not [k for k in kids if _alive(k)], "a figure worker outlived the command"
    assert p.returncode == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "no output was written" in lines[0], err
    _nothing_left(tmp_path, "r.json", "r.html", "f.json")


def test_outputs_appear_together_or_not_at_all(tmp_path):
    """Inside an outputs_together block nothing is in place before the end; an interrupt removes it all."""
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    with pytest.raises(KeyboardInterrupt), outputs_together():
        atomic_write(a, "a")
        assert not a.exists()
        atomic_write(b, "b")
        raise KeyboardInterrupt
    assert not a.exists() and not b.exists() and not list(tmp_path.iterdir())
    b.write_text("theirs")
    with pytest.raises(Exception, match="exists already"), outputs_together():
        atomic_write(a, "a")
        atomic_write(b, "b")      # refused at once: b exists
    assert not a.exists() and b.read_text() == "theirs" and len(list(tmp_path.iterdir())) == 1
    with outputs_together():
        atomic_write(a, "a")
        atomic_write(b, "b", overwrite=True)
    assert a.read_text() == "a" and b.read_text() == "b" and len(list(tmp_path.iterdir())) == 2


def test_an_output_that_cannot_be_written_fails_before_the_work(arms, tmp_path, capsys):
    """``--html`` in a folder where no file can be made: one line before any work, and no calibration JSON
    without its report."""
    robot, data = arms("arm5", 300)
    code, _, err = cli(capsys, "calibrate", robot, data, "--out", tmp_path / "cal.json", "--html", "/proc/cal.html")
    assert code == 2
    one_error(err, "/proc/cal.html", "cannot write in folder '/proc'")
    assert not (tmp_path / "cal.json").exists()


# --- 2. a fit that does not fit ---------------------------------------------------------------------------


def _palletiser_poses(tmp_path, n=60, seed=3):
    """Poses of the four-axis test arm (ARM4_BETA) within the limits of the four-axis palletiser (ARM4):
    another robot's data that passes every check of joints and units."""
    from arms import ARM4_BETA

    other = {**ARM4_BETA, "joint": [dict(j, min_deg=max(j["min_deg"], k["min_deg"]),
                                         max_deg=min(j["max_deg"], k["max_deg"]))
                                    for j, k in zip(ARM4_BETA["joint"], ARM4["joint"])]}
    data, _ = simulate(robot_from_dict(other, "other"), n, Effects(), seed=seed)
    path = tmp_path / "other-robot.csv"
    data.write_csv(path, overwrite=True)
    return str(path)


def test_another_robots_poses_are_refused_by_calibrate(arms, tmp_path, capsys):
    robot, _ = arms("arm4", 60)
    other = _palletiser_poses(tmp_path)
    code, _, err = cli(capsys, "calibrate", robot, other, "--model", "kinematic", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, other, "the nominal model of robot four-axis palletiser", "do not belong together",
              "--allow-mismatch")
    assert not (tmp_path / "c.json").exists()
    code, _, err = cli(capsys, "calibrate", robot, other, "--model", "kinematic", "--out", tmp_path / "c.json",
                       "--allow-mismatch")
    assert code == 0 and any("allowed by --allow-mismatch" in line for line in err)


def test_another_robots_poses_are_refused_by_a_calibration_taken_further(arms, tmp_path, capsys):
    """``calibrate CAL.json OTHER.csv --model base``: the base pose alone cannot bring them near."""
    robot, data = arms("arm4", 60)
    assert cli(capsys, "calibrate", robot, data, "--model", "kinematic", "--out", tmp_path / "cal.json")[0] == 0
    _, own_data = arms("arm4", 40, 7)
    code, _, _ = cli(capsys, "calibrate", tmp_path / "cal.json", own_data, "--model", "base",
                     "--out", tmp_path / "b.json")
    assert code == 0                     # its own robot's poses: taken further as before
    other = _palletiser_poses(tmp_path)
    code, _, err = cli(capsys, "calibrate", tmp_path / "cal.json", other, "--model", "base",
                       "--out", tmp_path / "x.json")
    assert code == 2
    one_error(err, other, f"the calibration {tmp_path / 'cal.json'}", "with its base pose fitted",
              "do not belong together", "--allow-mismatch")


def test_another_robots_poses_are_refused_by_diagnose_transfer(arms, tmp_path, capsys):
    robot, data = arms("arm4", 60)
    _, val = arms("arm4", 40, 5)
    other = _palletiser_poses(tmp_path, 80)
    code, _, err = cli(capsys, "diagnose", robot, data, "--validate", val, "--transfer", other,
                       "--json", tmp_path / "r.json", "--quiet")
    assert code == 2
    one_error(err, other, "do not belong together", "--allow-mismatch")
    assert not (tmp_path / "r.json").exists()


def test_the_mismatch_rule_never_fires_on_real_data():
    """The bundled UR10 series, every seed-paper protocol's pose sets and the test arms' simulated poses
    pass (with a margin of 20 to the rule), as does a calibration of series B taken to series A."""
    from arms import ARM3, ARM4_BETA, ARM7_DH, ARMS

    from casadical import calibrate, load_robot
    from casadical.alignment import align
    from casadical.checks import REACH_SHARE, check_poses
    from casadical.data import Measurements
    from casadical.model import Model
    from casadical.robot import PROBLEMS
    from casadical.simulate import load_protocol
    from casadical.terms.base import reach

    cases = [(load_robot("ur10"), Measurements.read_csv(PROBLEMS / "datasets" / "ur10-ipa" / f"series_{s}.csv"))
             for s in "ab"]
    for f in sorted((PROBLEMS / "protocols").glob("*.toml")):
        proto = load_protocol(str(f))
        cases += [(proto.robot, d) for d in proto.generate(None)[0].values()]
    for name, arm in {**ARMS, "arm3": ARM3, "arm4b": ARM4_BETA, "arm7dh": ARM7_DH}.items():
        robot = robot_from_dict(arm, name)
        cases.append((robot, simulate(robot, 100, Effects(), seed=0)[0]))
    for robot, data in cases:
        check_poses(data, robot)
        p = Model(robot, "nominal", jit=False).predict(data.q)
        T = align(p, data.xyz)
        mean = np.linalg.norm(p @ T[:3, :3].T + T[:3, 3] - data.xyz, axis=1).mean()
        assert mean < REACH_SHARE / 20 * reach(robot), (robot.name, data.path)
    b, a = cases[1][1], cases[0][1]
    cal = calibrate(load_robot("ur10"), b.subset(np.arange(300)), "kinematic", "lm", warn=False)
    calibrate(cal, a, "base", "lm", warn=False)


def test_positions_in_mm_declared_as_metres_in_an_import_map(tmp_path, capsys):
    src = tmp_path / "tracker.txt"
    rng = np.random.default_rng(0)
    rows = ["j1;j2;j3;X;Y;Z"] + [";".join(f"{v:.4f}" for v in (*rng.uniform(-90, 90, 3),
                                                                 *rng.uniform(-900, 900, 3))) for _ in range(10)]
    src.write_text("\n".join(rows) + "\n")
    base = ["--map", "separator=;", "--map", "joints=j1,j2,j3", "--map", "joint_unit=deg",
            "--map", "position=X,Y,Z"]
    code, _, err = cli(capsys, "import", src, *base, "--map", "position_unit=m", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "--map, column 'position_unit'", "km around their centre", 'set position_unit = "mm"')
    assert not (tmp_path / "o.csv").exists()
    assert cli(capsys, "import", src, *base, "--map", "position_unit=mm", "--out", tmp_path / "o.csv")[0] == 0
