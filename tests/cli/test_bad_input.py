"""Issue 21: interrupts stop the work, a fit that does not fit is an error, every bad case is one clear line.

Signals are sent to real ``casadical`` processes at a moment where the work
runs (IPOPT iterating, figure workers drawing); robots that matter are arms
that are not built in (tests/arms.py).
"""

import errno
import functools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from arms import ARM4, ARM5, to_toml
from test_robust import cli, one_error  # the command line in-process, and its one-line errors

from casadical import load_robot
from casadical.cli import main
from casadical.errors import DataFileError
from casadical.files import atomic_write, outputs_together
from casadical.interrupts import handle_signals
from casadical.robot import robot_from_dict
from casadical.simulate import Effects, simulate

ROOT = Path(__file__).resolve().parent.parent


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
    """A ``casadical`` process in ``tmp_path``; its own processes (figure workers, a Dask cluster) carry a tag in
    their environment (:func:`_tagged`)."""
    return subprocess.Popen([sys.executable, "-m", "casadical", *map(str, args)], cwd=tmp_path,
                            env={**os.environ, "PYTHONPATH": str(ROOT), "CASADICAL_JIT": "0",
                                 "CASADICAL_TEST_TAG": str(tmp_path), **env},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _tagged(tmp_path) -> list[int]:
    """Live processes started by a command of :func:`_start` in ``tmp_path`` (their environment says so)."""
    tag = f"CASADICAL_TEST_TAG={tmp_path}".encode()
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                if tag in Path(f"/proc/{d}/environ").read_bytes().split(b"\0") and _alive(int(d)):
                    out.append(int(d))
            except OSError:
                continue
    return out


def _finish(p, tmp_path):
    """Wait for ``p`` (a failure after 120 s: it and its processes are killed)."""
    try:
        return p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        for pid in [p.pid, *_tagged(tmp_path)]:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        p.communicate()
        pytest.fail("the command did not end within 120 s")


def _none_outlives(tmp_path):
    """No process of the command is left: they end with it (a failure if one is still there after 30 s)."""
    deadline = time.monotonic() + 30
    while _tagged(tmp_path):
        assert time.monotonic() < deadline, f"processes outlived the command: {_tagged(tmp_path)}"
        time.sleep(0.05)


def _said(err: str) -> list[str]:
    """The lines of standard error of a command run in a subprocess, but the warning that loading the arm4,
    arm5 and arm4-dh files gives (parallel axes without beta_deg: casadical.errors.ParallelAxesWarning,
    ignored in-process by pyproject.toml), which is not what these tests look at."""
    return [x for x in err.strip().splitlines() if "has no beta_deg" not in x]


def _nothing_left(tmp_path, *names):
    for name in names:
        assert not (tmp_path / name).exists(), name
    assert not list(tmp_path.glob(".*.part")), list(tmp_path.glob(".*.part"))


def _one_line(err: str, code: int, *parts: str) -> None:
    lines = _said(err)
    assert len(lines) == 1 and "Traceback" not in err, err
    what = "interrupted" if code == 130 else "stopped by SIGTERM"
    assert lines[0].startswith(f"casadical: {what}"), err
    for part in parts:
        assert part in lines[0], err


CODES = {"SIGINT": 130, "SIGTERM": 143}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked figure workers and /proc: Linux only")
@pytest.mark.parametrize("point, sig", [
    ("start", "SIGTERM"), ("start", "SIGINT"),     # while Python imports the commands
    ("work", "SIGINT"),                            # the command begins
    ("solver", "SIGTERM"),                         # a Levenberg-Marquardt iteration of the first fit
    ("output", "SIGINT"),                          # the first output is complete, the others not yet
    ("figures", "SIGTERM"), ("figures", "SIGINT:group"),  # forked workers draw the report's figures
    ("commit", "SIGTERM"),                         # the first output is in place, the others not yet
    ("exit", "SIGINT"), ("exit", "SIGTERM"),       # every output in place, the interpreter ends
])
def test_a_signal_at_any_moment_is_one_line_and_all_outputs_or_none(arms, tmp_path, point, sig):
    """Issue 28: ``diagnose --json --html --out`` signalled at each moment of its run (the process signals
    itself there: CASADICAL_SIGNAL_AT): exit 130/143 with one line, never a traceback, never swallowed; the
    three outputs appear together or not at all (SIGINT:group: a terminal's Ctrl-C, to the figure workers too),
    the report an earlier run wrote (--force) stays as it was
    until the new one is complete, and no figure worker outlives the command. A signal after the outputs
    are in place says so. (Before: SIGTERM the moment r.json appeared exited -15 with every output; SIGINT
    then exited 0 with a traceback from threading._shutdown, or -2 without a word.)"""
    robot, data = arms("arm5", 300, 1)
    _, val = arms("arm5", 1500, 2)
    (tmp_path / "r.json").write_text("the report of an earlier run")
    p = _start(["diagnose", robot, data, "--validate", val, "--json", "r.json", "--html", "r.html", "--out",
                "f.json", "--quiet", "--no-blackbox", "--force"], tmp_path,
               CASADICAL_EVAL_THREADS="2", CASADICAL_SIGNAL_AT=f"{point}:{sig}")
    _, err = _finish(p, tmp_path)
    code = CODES[sig.split(":")[0]]
    assert p.returncode == code, err
    _none_outlives(tmp_path)
    if point == "exit":
        _one_line(err, code, "after the command had finished; its 3 outputs are complete")
        assert isinstance(json.loads((tmp_path / "r.json").read_text()), dict)      # the new report
        assert isinstance(json.loads((tmp_path / "f.json").read_text()), dict)
        assert (tmp_path / "r.html").read_text().rstrip().endswith("</html>")
    else:
        _one_line(err, code, "no output was written")
        assert (tmp_path / "r.json").read_text() == "the report of an earlier run"
        _nothing_left(tmp_path, "r.html", "f.json")


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_stops_an_ipopt_solve(arms, tmp_path, sig):
    """CasADi catches the interrupt inside IPOPT and returns its last iterate (status User_Requested_Stop):
    that must not become a calibration with exit 0. The process signals itself from IPOPT's iteration
    callback, inside the solve."""
    robot, data = arms("arm5", 300)
    p = _start(["calibrate", robot, data, "--solver", "ipopt", "--out", "cal.json", "--html", "cal.html"],
               tmp_path, CASADICAL_SIGNAL_AT=f"solver:{sig}")
    _, err = _finish(p, tmp_path)
    assert p.returncode == CODES[sig], err
    lines = _said(err)
    # one line says it; before it, at most the progress line of the fit (said once it took a second)
    assert all(x.startswith("calibrate: fitting model") for x in lines[:-1]), err
    _one_line(lines[-1], CODES[sig], "no output was written")
    _nothing_left(tmp_path, "cal.json", "cal.html")


def test_a_signal_a_library_swallowed_still_stops_the_command(tmp_path):
    """A Ctrl-C that some code on the way caught (or turned into its own error, as CasADi's callbacks and
    Python's ``__set_name__`` do) still stops the command before its outputs are put in place."""
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    b.write_text("theirs")
    with pytest.raises(KeyboardInterrupt), handle_signals(), outputs_together():
        atomic_write(a, "a")
        atomic_write(b, "b", overwrite=True)
        try:
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(3):      # the handler runs between two bytecodes of this loop
                pass
        except KeyboardInterrupt:   # swallowed
            pass
    assert not a.exists() and b.read_text() == "theirs" and sorted(tmp_path.iterdir()) == [b]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("point", ["cluster", "repetition"], ids=["while-the-cluster-starts", "while-it-runs"])
def test_sigterm_stops_a_dask_study_and_its_cluster(tmp_path, point):
    """SIGTERM while a local Dask cluster starts or runs a study: exit 143 with the one resume line (a
    cluster cut short in its start printed tracebacks at exit), and the cluster's processes end with the
    command."""
    pytest.importorskip("distributed")
    from test_study import write_study

    protocol = write_study(tmp_path, reps=400)
    p = _start(["study", protocol, "--out", "r", "--workers", "2", "--quiet"], tmp_path,
               CASADICAL_SIGNAL_AT=f"{point}:SIGTERM")
    _, err = _finish(p, tmp_path)
    assert p.returncode == 143, err
    lines = _said(err)
    assert len(lines) == 1 and lines[0].startswith("casadical: stopped by SIGTERM: ") and "to resume" in lines[0], err
    _none_outlives(tmp_path)


def _waiting(fifo, p) -> int:
    """Once process ``p`` waits at its checkpoint (CASADICAL_PAUSE_AT: it opened ``fifo`` to read), the pipe opened
    to write; closing it lets the process go on."""
    deadline = time.monotonic() + 120
    while True:
        try:
            return os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as e:          # ENXIO: no reader yet
            if e.errno != errno.ENXIO:
                raise
        assert p.poll() is None, p.communicate()
        assert time.monotonic() < deadline, "the process did not reach its checkpoint"
        time.sleep(0.01)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes")
def test_two_studies_started_together_on_one_folder(tmp_path):
    """Issue 28: two ``study --out res`` started together: B finds no folder and, before it makes one, A makes
    it and takes its lock. B is refused by the lock with one line and touches nothing; A runs; the table holds
    each repetition once. (Before: B failed with "res: File exists" and, having seen no folder, removed A's;
    A then failed with "res/_study.json: cannot write".)"""
    pytest.importorskip("pyarrow")
    from test_study import raw_repetitions, write_study

    protocol = write_study(tmp_path, reps=5)
    fa, fb = tmp_path / "a.fifo", tmp_path / "b.fifo"
    os.mkfifo(fa)
    os.mkfifo(fb)
    args = ["study", protocol, "--out", "res", "--serial", "--quiet"]
    b = _start(args, tmp_path, CASADICAL_PAUSE_AT=f"study-folder:{fb}")
    hold_b = _waiting(fb, b)                  # B: no folder yet
    a = _start(args, tmp_path, CASADICAL_PAUSE_AT=f"study-locked:{fa}")
    hold_a = _waiting(fa, a)                  # A: made the folder, holds the lock
    os.close(hold_b)
    _, err_b = _finish(b, tmp_path)
    assert b.returncode == 2
    one_error(_said(err_b), "res", "another casadical study is writing to this folder")
    os.close(hold_a)
    _, err_a = _finish(a, tmp_path)
    assert a.returncode == 0, err_a
    from collections import Counter

    from casadical.study import load_study
    per = load_study(protocol).rows_per_repetition
    assert Counter(raw_repetitions(tmp_path / "res")) == {r: per for r in range(5)}


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


def test_a_commit_that_fails_halfway_restores_what_it_replaced(tmp_path):
    """All or none, also with --force: when a later output cannot be moved into place, an earlier one that
    replaced a user's file is put back (before: the user's file was left replaced by the new one)."""
    a, sub = tmp_path / "a.txt", tmp_path / "sub"
    sub.mkdir()
    a.write_text("theirs")
    with pytest.raises(Exception, match="cannot write"), outputs_together():
        atomic_write(a, "new", overwrite=True)
        atomic_write(sub / "b.txt", "b")
        for f in sub.iterdir():      # the folder of the second output goes away before the end
            f.unlink()
        sub.rmdir()
    assert a.read_text() == "theirs" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


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


def test_another_robots_poses_are_refused_by_predict_with_the_robot(arms, tmp_path, capsys):
    """``predict ROBOT OTHER.csv``: the nominal model judges the poses as calibrate's does."""
    robot, data = arms("arm4", 60)
    assert cli(capsys, "predict", robot, data, "--out", tmp_path / "own.csv")[0] == 0
    other = _palletiser_poses(tmp_path)
    code, _, err = cli(capsys, "predict", robot, other, "--out", tmp_path / "p.csv")
    assert code == 2
    one_error(err, other, "the nominal model of robot four-axis palletiser", "do not belong together",
              "--allow-mismatch")
    assert not (tmp_path / "p.csv").exists()
    code, _, err = cli(capsys, "predict", robot, other, "--out", tmp_path / "p.csv", "--allow-mismatch")
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
    pass (with a margin of 10 to the rule), as does a calibration of series B taken to series A."""
    from arms import ARM3, ARM4_BETA, ARM7_DH, ARMS

    from casadical import calibrate, load_robot
    from casadical.checks import REACH_SHARE, base_fitted_errors, check_poses
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
        median = np.median(base_fitted_errors(p, data.xyz))
        assert median < REACH_SHARE / 10 * reach(robot), (robot.name, data.path)   # measured: 0.22 % at most
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


# --- 3. every case one clear line, right rows, bounded work --------------------------------------------------


@pytest.fixture(scope="module")
def study_results(tmp_path_factory):
    """A finished 2-repetition study of a four-axis arm (serial) and its protocol."""
    from test_study import write_study

    folder = tmp_path_factory.mktemp("study")
    protocol = write_study(folder, reps=2)
    assert main(["study", protocol, "--out", str(folder / "r"), "--serial", "--quiet"]) == 0
    return Path(protocol), folder / "r"


@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage"])
def test_resuming_a_study_with_a_damaged_part(study_results, tmp_path, capsys, damage):
    import shutil

    protocol, results = study_results
    out = tmp_path / "r"
    shutil.copytree(results, out)
    part = next(out.glob("part-*.parquet"))
    part.write_bytes({"truncated": part.read_bytes()[:100], "empty": b"", "garbage": b"garbage\n"}[damage])
    bigger = tmp_path / protocol.name
    bigger.write_text(protocol.read_text().replace("repetitions = 2", "repetitions = 3"))
    shutil.copy(protocol.parent / "arm4-dh.toml", tmp_path)
    code, _, err = cli(capsys, "study", bigger, "--out", out, "--serial", "--quiet")
    assert code == 2
    one_error(err, str(part), "is damaged", "delete it")
    code, _, err = cli(capsys, "study", "--summary", out)
    assert code == 2
    one_error(err, str(part), "is damaged")


def test_absurd_repetitions_are_refused_at_once(study_results, tmp_path, capsys):
    protocol, _ = study_results
    big = tmp_path / protocol.name
    big.write_text(protocol.read_text().replace("repetitions = 2", "repetitions = 1000000000"))
    (tmp_path / "arm4-dh.toml").write_text((protocol.parent / "arm4-dh.toml").read_text())
    code, _, err = cli(capsys, "study", big, "--out", tmp_path / "r", "--serial")
    assert code == 2
    one_error(err, str(big), "'repetitions'", "at most 1,000,000")
    assert not (tmp_path / "r").exists()


def test_a_scheduler_that_cannot_be_reached_leaves_nothing(study_results, tmp_path, capsys):
    pytest.importorskip("distributed")
    protocol, _ = study_results
    code, _, err = cli(capsys, "study", protocol, "--out", tmp_path / "r", "--scheduler", "nosuch://host:1", "--quiet")
    assert code == 2
    one_error(err, "nosuch://host:1", "cannot reach the Dask scheduler")
    assert not (tmp_path / "r").exists()


def test_a_refused_scheduler_says_it_is_trying_and_leaves_nothing(study_results, tmp_path, capsys, monkeypatch):
    """A TCP address nothing listens at: Dask retries until the timeout, and the user is told so at once."""
    pytest.importorskip("distributed")
    from casadical.study import runner

    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 1)
    protocol, _ = study_results
    code, _, err = cli(capsys, "study", protocol, "--out", tmp_path / "r", "--scheduler", "tcp://127.0.0.1:1")
    assert code == 2
    assert any("connecting to the Dask scheduler at tcp://127.0.0.1:1 (trying for up to 1 s)" in line for line in err)
    assert "cannot reach the Dask scheduler" in err[-1] and "tcp://127.0.0.1:1" in err[-1]
    assert not (tmp_path / "r").exists()


URDF_LINK = '<link name="{}"/>'
URDF_JOINT = ('<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/><origin xyz="{o}" rpy="0 0 0"/>'
              '<axis xyz="{ax}"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>')


def _urdf(origin2="0 0 0.3") -> str:
    body = "".join(URDF_LINK.format(x) for x in "abcde")
    body += URDF_JOINT.format(n="j1", p="a", c="b", o="0 0 0.4", ax="0 0 1")
    body += "\n" + URDF_JOINT.format(n="j2", p="b", c="c", o=origin2, ax="0 1 0")
    body += "\n" + URDF_JOINT.format(n="j3", p="c", c="d", o="0 0 0.7", ax="0 1 0")
    body += '\n<joint name="t" type="fixed"><parent link="d"/><child link="e"/><origin xyz="0.5 0 0"/></joint>'
    return '<?xml version="1.0"?>\n<robot name="hand-written arm">\n' + body + "\n</robot>\n"


def test_urdf_joint_origin_of_1e300(tmp_path, capsys):
    (tmp_path / "r.urdf").write_text(_urdf("1e300 0 0.3"))
    code, _, err = cli(capsys, "inspect", tmp_path / "r.urdf")
    assert code == 2
    one_error(err, "r.urdf, row 4", "joint 'j2'", "1e+300 m", "metres")


def test_compliance_of_a_urdf_without_inertial(tmp_path, capsys):
    from casadical import load_robot

    (tmp_path / "r.urdf").write_text(_urdf())
    data, _ = simulate(load_robot(tmp_path / "r.urdf"), 40, Effects(), seed=0, floor_z=None)
    data.write_csv(tmp_path / "d.csv")
    code, _, err = cli(capsys, "calibrate", tmp_path / "r.urdf", tmp_path / "d.csv", "--model",
                       "kinematic+compliance", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "r.urdf", "no link masses", "<inertial>", "--model kinematic")
    assert cli(capsys, "calibrate", tmp_path / "r.urdf", tmp_path / "d.csv", "--model", "kinematic",
               "--out", tmp_path / "c.json")[0] == 0


def test_negative_payload_in_a_data_file(arms, tmp_path, capsys):
    from casadical.data import Measurements

    robot, data = arms("arm5", 40)
    d = Measurements.read_csv(data)
    Measurements({**d.columns, "payload_kg": np.full(len(d), 5.0)}).write_csv(tmp_path / "p.csv")
    lines = (tmp_path / "p.csv").read_text().splitlines()
    col = lines[0].split(",").index("payload_kg")
    cells = lines[4].split(",")
    cells[col] = "-20"                                              # row 5 of the file
    lines[4] = ",".join(cells)
    (tmp_path / "p.csv").write_text("\n".join(lines) + "\n")
    code, _, err = cli(capsys, "calibrate", robot, tmp_path / "p.csv", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "p.csv, row 5, column 'payload_kg'", "-20 kg")
    with pytest.raises(DataFileError, match="row 5, column 'payload_kg'.*-20 kg"):     # made in memory, too
        Measurements({**d.columns, "payload_kg": np.where(np.arange(len(d)) == 3, -20.0, 5.0)})
    with pytest.raises(DataFileError, match="-3 kg"):
        simulate(load_robot(robot), 10, Effects(), seed=0, payload_kg=-3.0)


def test_simulate_leaves_no_folder_behind_when_the_protocol_fails(tmp_path, capsys):
    """A protocol whose workspace keeps too few poses fails in the work: --out-dir is not made."""
    text = (Path(__file__).parents[1] / "problems" / "protocols" / "ca-ys100.toml").read_text()
    (tmp_path / "p.toml").write_text(text.replace("floor_z_m = 0.0", "floor_z_m = 50.0"))
    code, _, err = cli(capsys, "simulate", tmp_path / "p.toml", "--out-dir", tmp_path / "new" / "sim")
    assert code == 2
    one_error(err, "too few poses")
    assert not (tmp_path / "new").exists()
    (tmp_path / "file").write_text("x")
    code, _, err = cli(capsys, "simulate", "ca-ys100", "--out-dir", tmp_path / "file")
    assert code == 2
    one_error(err, "file", "names a file, not a folder")


@pytest.fixture(scope="module")
def arm_calibration(arms, tmp_path_factory):
    robot, data = arms("arm4", 60)
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    assert main(["calibrate", robot, data, "--model", "kinematic", "--solver", "lm", "--out", str(path)]) == 0
    return path


def test_calibration_from_a_future_version(arm_calibration, tmp_path, capsys):
    import json

    doc = json.loads(arm_calibration.read_text())
    doc["casadical_version"] = "99.0"
    (tmp_path / "future.json").write_text(json.dumps(doc))
    code, _, err = cli(capsys, "export", tmp_path / "future.json", "--urdf", tmp_path / "r.urdf")
    assert code == 2
    one_error(err, "future.json, column 'casadical_version'", "written by casadical 99.0", "update casadical")
    assert not (tmp_path / "r.urdf").exists()


def test_hand_edited_huge_link_length_is_not_exported(arm_calibration, tmp_path, capsys):
    import json

    doc = json.loads(arm_calibration.read_text())
    k = next(i for i, p in enumerate(doc["parameters"]) if p["name"] == "a3")
    doc["parameters"][k]["value"] = 1e308
    (tmp_path / "huge.json").write_text(json.dumps(doc))
    code, _, err = cli(capsys, "export", tmp_path / "huge.json", "--urdf", tmp_path / "r.urdf", "--table",
                       tmp_path / "t.csv")
    assert code == 2
    one_error(err, f"huge.json, column 'parameters[{k}].value'", "a3", "length in mm")
    assert not (tmp_path / "r.urdf").exists() and not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize("variable, value", [("CASADICAL_CACHE_MAX_MB", "lots"), ("CASADICAL_CACHE_MAX_MB", "-1"),
                                             ("CASADICAL_JIT", "maybe")])
def test_bad_cache_variables_are_errors(monkeypatch, capsys, variable, value):
    monkeypatch.setenv(variable, value)
    code, _, err = cli(capsys, "cache", "--info")
    assert code == 2
    one_error(err, variable, repr(value))


def _oversized(path: Path, sep: str) -> None:
    """A measurement file whose row 5 has a field too large for Python's csv reader (131,072 characters)."""
    rows = ["q1_deg,q2_deg,q3_deg,q4_deg,x_mm,y_mm,z_mm"] + [",".join(["1"] * 7)] * 6
    rows[4] = ",".join(["1", "2" * 200_000] + ["1"] * 5)
    path.write_text("\n".join(r.replace(",", sep) for r in rows) + "\n")


def test_an_oversized_cell_is_reported_in_its_row(tmp_path, capsys):
    _oversized(tmp_path / "d.csv", ",")
    code, _, err = cli(capsys, "split", tmp_path / "d.csv", "-n", "2", "--out-cal", tmp_path / "a.csv",
                       "--out-val", tmp_path / "b.csv")
    assert code == 2
    one_error(err, "d.csv, row 5", "field larger than field limit")
    _oversized(tmp_path / "t.txt", ";")
    code, _, err = cli(capsys, "import", tmp_path / "t.txt", "--map", "separator=;", "--map",
                       "joints=q1_deg,q2_deg,q3_deg,q4_deg", "--map", "joint_unit=deg", "--map",
                       "position=x_mm,y_mm,z_mm", "--map", "position_unit=mm", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "t.txt, row 5", "field larger than field limit")


def test_too_few_poses_name_the_file(arms, tmp_path, capsys):
    robot, data = arms("arm5", 40)
    lines = Path(data).read_text().splitlines()
    for n, what in ((6, "poses give"), (3, "at least 3 measured poses")):
        (tmp_path / f"few{n}.csv").write_text("\n".join(lines[:n]) + "\n")
        code, _, err = cli(capsys, "calibrate", robot, tmp_path / f"few{n}.csv", "--out", tmp_path / "c.json")
        assert code == 2
        one_error(err, f"few{n}.csv: ", what)


def test_a_huge_skip_lines_is_bounded_work_and_names_the_key(tmp_path, capsys):
    _oversized(tmp_path / "t.txt", ";")
    code, _, err = cli(capsys, "import", tmp_path / "t.txt", "--map", "separator=;", "--map",
                       "joints=q1_deg,q2_deg,q3_deg,q4_deg", "--map", "joint_unit=deg", "--map",
                       "position=x_mm,y_mm,z_mm", "--map", "position_unit=mm", "--map", "skip_lines=2147483648",
                       "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "--map, column 'skip_lines'", "2,147,483,648", "has 7")


# --- the same measurements twice ----------------------------------------------------------------------------


def test_validation_poses_that_are_calibration_poses(arms, tmp_path, capsys):
    """``--validate`` with the calibration file (or a copy) is an error: nothing would be held out; some shared
    rows are a warning with their count and the first one's row. calibrate, diagnose and compare alike."""
    import shutil

    robot, data = arms("arm5", 60)
    _, val = arms("arm5", 40, 1)
    shutil.copy(data, tmp_path / "copy.csv")
    for cmd in (["calibrate", robot, data, "--out", tmp_path / "c.json"],
                ["diagnose", robot, data, "--json", tmp_path / "r.json", "--quiet"],
                ["compare", robot, data, "--methods", "KM"]):
        code, _, err = cli(capsys, *cmd, "--validate", tmp_path / "copy.csv")
        assert code == 2, cmd
        one_error(err, "copy.csv", "every one of its 60 poses is a calibration pose of", "not held out",
                  "casadical split")
        assert not (tmp_path / "c.json").exists() and not (tmp_path / "r.json").exists()
    _, other = arms("arm5", 50, 2)
    code, _, err = cli(capsys, "diagnose", robot, data, "--validate", other, "--transfer", tmp_path / "copy.csv",
                       "--json", tmp_path / "r.json", "--quiet")
    assert code == 2
    one_error(err, "copy.csv", "every one of its 60 poses is a calibration pose of", "no test of another series")
    assert not (tmp_path / "r.json").exists()
    # 5 calibration rows among the validation poses: a warning naming them, the rest is done
    lines = Path(val).read_text().splitlines()
    (tmp_path / "mixed.csv").write_text("\n".join(lines[:11] + Path(data).read_text().splitlines()[3:8]
                                                  + lines[11:]) + "\n")
    code, _, err = cli(capsys, "calibrate", robot, data, "--out", tmp_path / "c.json", "--validate",
                       tmp_path / "mixed.csv")
    assert code == 0
    assert any("mixed.csv: 5 of its 45 poses (the first in row 12) are calibration poses of" in e for e in err), err


def test_a_session_given_twice(arms, tmp_path, capsys):
    """The same file (or its copy) as two sessions would count every pose twice: an error. Two sessions that
    measured one joint program (the same readings, other points) are what sessions are for."""
    import shutil

    from casadical.data import Measurements

    robot, data = arms("arm5", 60)
    shutil.copy(data, tmp_path / "b.csv")
    code, _, err = cli(capsys, "calibrate", robot, data, data, "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "every one of its 60 poses is also in", "the same file given twice", "count twice")
    code, _, err = cli(capsys, "calibrate", robot, data, tmp_path / "b.csv", "--out", tmp_path / "c.json")
    assert code == 2
    one_error(err, "b.csv", "every one of its 60 poses is also in", "count twice")
    d = Measurements.read_csv(data)
    moved = dict(d.columns)
    for axis in ("x_mm", "y_mm", "z_mm"):       # the same joint program, measured again from elsewhere
        moved[axis] = d.columns[axis] + 250.0 + np.random.default_rng(0).normal(0, 0.01, len(d))
    Measurements(moved).write_csv(tmp_path / "again.csv")
    code, _, err = cli(capsys, "calibrate", robot, data, tmp_path / "again.csv", "--out", tmp_path / "c.json")
    assert code == 0 and not any("also in" in e for e in err)


def test_row_spacing_on_a_file_with_times_says_the_times_are_used(arms, tmp_path, capsys):
    from casadical.data import Measurements

    robot, data = arms("arm5", 40)
    d = Measurements.read_csv(data)
    Measurements({**d.columns, "time_s": np.arange(len(d)) * 7.0}).write_csv(tmp_path / "t.csv")
    code, _, err = cli(capsys, "calibrate", robot, tmp_path / "t.csv", "--model", "kinematic", "--row-spacing-s", "2",
                       "--out", tmp_path / "c.json")
    assert code == 0
    assert any("t.csv: has a time_s column, whose times are used; --row-spacing-s applies to files without one" in e
               for e in err), err


def test_keep_compensator_needs_a_calibration_with_one(arms, arm_calibration, tmp_path, capsys):
    robot, data = arms("arm4", 60)
    for source, words in ((robot, "give a calibration JSON in place of ROBOT"), (arm_calibration, "has none")):
        code, _, err = cli(capsys, "calibrate", source, data, "--model", "base", "--keep-compensator",
                           "--out", tmp_path / "c.json")
        assert code == 2
        one_error(err, "--keep-compensator", words)


def test_compare_refuses_poses_of_another_tracker_set_up(arms, tmp_path, capsys):
    """compare --validate / --extra in another measurement frame (the tracker moved) are judged by metres: one
    line before the work; --allow-mismatch lets them through with a warning."""
    robot, data = arms("arm5", 60)
    _, val = arms("arm5", 40, 1)
    moved, _ = simulate(robot_from_dict(ARM5, "arm5"), 40, Effects(base_xyz=(1.5, -0.5, 0.3),
                                                                   base_rpy=(0.0, 0.0, 1.0)), seed=9)
    moved.write_csv(tmp_path / "moved.csv")
    for option in ("--validate", "--extra"):
        args = ["--validate", val] if option == "--extra" else []
        code, _, err = cli(capsys, "compare", robot, data, *args, option, tmp_path / "moved.csv", "--methods", "KM")
        assert code == 2
        one_error(err, "moved.csv", f"the {'extra' if option == '--extra' else 'validation'} poses are missed by",
                  "not in that measurement frame", "--allow-mismatch")
    code, _, err = cli(capsys, "compare", robot, data, "--validate", tmp_path / "moved.csv", "--methods", "KM",
                       "--allow-mismatch")
    assert code == 0 and any("allowed by --allow-mismatch" in e for e in err)


def test_transfer_options_need_a_transfer(arms, tmp_path, capsys):
    robot, data = arms("arm5", 60)
    _, val = arms("arm5", 40, 1)
    code, _, err = cli(capsys, "diagnose", robot, data, "--validate", val, "--transfer-base-poses", "10",
                       "--json", tmp_path / "r.json")
    assert code == 2
    one_error(err, "--transfer-base-poses", "give --transfer OTHER.csv")
