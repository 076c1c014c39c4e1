"""Interrupts stop the work: a signal at any moment of a command is one line, and its outputs appear all or none
(casadical/runtime/_interrupts.py, casadical/runtime/_files.py; issues 21 and 10).

Signals are sent to real ``casadical`` processes at a moment where the work
runs (IPOPT iterating, the report's figures drawn, gcc compiling); robots that matter are arms
that are not built in (tests/helpers/arms.py).
"""

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from casadical import load_robot
from casadical.data import Measurements
from casadical.runtime import atomic_write, handle_signals, outputs_together
from tests.helpers.cli import arm_files, cli, one_error

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    """``arms(name, n, seed)``: (robot TOML, simulated poses CSV) of a test arm, made once per module."""
    folder = str(tmp_path_factory.mktemp("arms"))
    return lambda name, n, seed=0: arm_files(folder, name, n, seed)


# --- signals ----------------------------------------------------------------------------------------------


def _start(args, tmp_path, **env):
    """A ``casadical`` process in ``tmp_path``; its own child processes (a Dask cluster) carry a tag in
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


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc: Linux only")
@pytest.mark.parametrize("point, sig", [
    ("start", "SIGTERM"), ("start", "SIGINT"),     # while Python imports the commands
    ("work", "SIGINT"),                            # the command begins
    ("solver", "SIGTERM"),                         # a Levenberg-Marquardt iteration of the first fit
    ("output", "SIGINT"),                          # the first output is complete, the others not yet
    ("figures", "SIGTERM"), ("figures", "SIGINT:group"),  # the report's figures are drawn
    ("commit", "SIGTERM"),                         # the first output is in place, the others not yet
    ("exit", "SIGINT"), ("exit", "SIGTERM"),       # every output in place, the interpreter ends
])
def test_a_signal_at_any_moment_is_one_line_and_all_outputs_or_none(arms, tmp_path, point, sig):
    """Issue 28: ``diagnose --json --html --out`` signalled at each moment of its run (the process signals
    itself there: CASADICAL_SIGNAL_AT): exit 130/143 with one line, never a traceback, never swallowed; the
    three outputs appear together or not at all (SIGINT:group: a terminal's Ctrl-C, to the whole process group),
    the report an earlier run wrote (--force) stays as it was
    until the new one is complete, and no child process outlives the command. A signal after the outputs
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
    from tests.study.test_study import write_study

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
    from tests.study.test_study import raw_repetitions, write_study

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


# --- Ctrl-C while the model compiles ----------------------------------------------------------------


@pytest.mark.skipif(not (shutil.which("gcc") or shutil.which("cc")), reason="no C compiler")
def test_ctrl_c_during_the_jit_stops_cleanly(tmp_path):
    """A terminal's Ctrl-C (SIGINT to the whole process group) while gcc runs: exit 130, no output, no JIT folder,
    nothing in the compiled-function cache."""
    robot = load_robot("ys100")
    q = np.random.default_rng(0).uniform(robot.limits[:, 0] + 0.1, robot.limits[:, 1] - 0.1, (400, 6))
    Measurements.from_arrays(q).write_csv(tmp_path / "poses.csv")
    env = dict(os.environ, CASADICAL_JIT="1", TMPDIR=str(tmp_path), CASADICAL_CACHE=str(tmp_path / "cache"),
               CASADICAL_SIGNAL_AT="compile:SIGINT:group")    # the process group's Ctrl-C once gcc started
    p = subprocess.Popen([sys.executable, "-m", "casadical", "predict", "ys100", str(tmp_path / "poses.csv"),
                          "--out", str(tmp_path / "out.csv")], env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err and "virtual machine" not in err
    assert not (tmp_path / "out.csv").exists()
    assert not list(tmp_path.glob("casadical-jit-*"))
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


def _compilers(folder) -> list[str]:
    """Live processes whose command line names a file in ``folder`` (the compiler driver, cc1, the assembler)."""
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit() and int(d) != os.getpid():
            try:
                cmd = Path(f"/proc/{d}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if str(folder) in cmd and "casadical" not in cmd.split()[0] and _alive(int(d)) and not _killed(int(d)):
                out.append(f"{d}: {cmd[:160]}")
    return out


def _killed(pid: int) -> bool:
    """A SIGKILL is pending for ``pid``: it dies the next time it is scheduled."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True
    pending = 0
    for line in status.splitlines():
        if line.startswith(("SigPnd:", "ShdPnd:")):
            pending |= int(line.split()[1], 16)
    return bool(pending & (1 << (signal.SIGKILL - 1)))


@pytest.mark.skipif(not shutil.which("gcc"), reason="needs gcc (its compiler proper, cc1, is its child)")
@pytest.mark.parametrize("point, quick", [("compile", False), ("compile", True), ("solver", True)],
                         ids=["optimised", "quick", "background"])
def test_ctrl_c_while_the_model_compiles_leaves_no_compiler_behind(tmp_path, point, quick):
    """SIGINT to the command alone (``kill -INT PID``; issue 47: ``calibrate ... --model kinematic+compliance``
    into an empty cache, interrupted while gcc ran) once the compiler proper (cc1, the driver's child) runs:
    exit 130 and no compiler process left, whether the run waited for the optimised compile, for the quick one,
    or had the optimised one in the background while IPOPT iterated (jitcache.spare_core decides which; forced
    here)."""
    robot_file, data_file = arm_files(str(tmp_path), "arm5", 300, 0)
    fifo = tmp_path / "hold"
    os.mkfifo(fifo)
    run = (f"from casadical.model import _jitcache as jitcache; jitcache.spare_core = lambda: {quick}; "
           "from casadical.__main__ import run; run()")     # the ``casadical`` command
    p = subprocess.Popen([sys.executable, "-c", run, "calibrate", robot_file, data_file, "--model",
                          "kinematic+compliance", "--out", str(tmp_path / "cal.json")], cwd=tmp_path,
                         env={**os.environ, "PYTHONPATH": str(ROOT), "CASADICAL_JIT": "1", "TMPDIR": str(tmp_path),
                              "CASADICAL_CACHE": str(tmp_path / "cache"), "CASADICAL_PAUSE_AT": f"{point}:{fifo}"},
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        with open(fifo, "wb"):         # returns once the command waits at ``point``: its compilers started
            t0 = time.monotonic()
            while not any("cc1" in c for c in _compilers(tmp_path)) and time.monotonic() - t0 < 30:
                time.sleep(0.01)
            running = _compilers(tmp_path)
            assert any("cc1" in c for c in running), running
            os.kill(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130 and "interrupted; no output was written" in err and "Traceback" not in err, err
    assert _compilers(tmp_path) == [], "a compiler outlived the command"     # (one killed but not yet gone aside)
    assert not (tmp_path / "cal.json").exists()
