"""casadical.runtime._threads: the BLAS/OpenMP limit is in force inside, restored after, and can be overridden; large
batches of poses are evaluated in blocks, side by side, to the same bits."""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (a second OpenBLAS: the limit must reach every loaded library)
from threadpoolctl import threadpool_limits

from casadical import cli
from casadical.errors import SettingError
from casadical.loading import load_robot
from casadical.runtime import (
    ENV,
    EVAL_ENV,
    EVAL_MAX,
    blas_threads,
    evaluation_pool,
    evaluation_threads,
    get_threads,
    limited_threads,
    set_threads,
)

#: libraries that can run 2 threads: a BLAS built single-threaded (SCS's, loaded with cvxpy by other
#: tests) stays at 1 whatever it is told, and says nothing about the limit
_watched: set[str] = set()


def threads() -> set[int]:
    """Thread counts of the watched libraries."""
    return {n for name, n in blas_threads().items() if name in _watched}


@pytest.fixture(autouse=True)
def two_threads(monkeypatch):
    """Start each test with every BLAS at 2 threads and no casadical setting (restored after)."""
    monkeypatch.delenv(ENV, raising=False)
    set_threads(None)
    with threadpool_limits(limits=2):
        _watched.clear()
        _watched.update(name for name, n in blas_threads().items() if n == 2)
        if not _watched:
            pytest.skip("no BLAS here can run 2 threads")
        yield
    set_threads(None)


def test_limit_inside_restored_after():
    assert len(_watched) >= 2  # numpy's and scipy's OpenBLAS
    with limited_threads():
        assert threads() == {1}
        with limited_threads():
            assert threads() == {1}
        assert threads() == {1}  # the inner exit keeps the outer limit
    assert threads() == {2}


def test_restored_after_an_exception():
    with pytest.raises(ZeroDivisionError):
        with limited_threads():
            1 / 0
    assert threads() == {2}


def test_decorator_reads_the_setting_at_call_time():
    @limited_threads()
    def inside():
        return threads()

    assert inside() == {1}
    set_threads(3)
    assert inside() == {3}
    assert threads() == {2}


@pytest.mark.parametrize("value,expect", [("3", {3}), ("1", {1}), ("all", {2}), ("0", {2}), (" 2 ", {2})])
def test_environment_override(monkeypatch, value, expect):
    monkeypatch.setenv(ENV, value)
    with limited_threads():
        assert threads() == expect
    assert threads() == {2}


def test_python_setting_beats_environment(monkeypatch):
    monkeypatch.setenv(ENV, "3")
    set_threads(1)
    assert get_threads() == 1
    set_threads(0)
    assert get_threads() is None
    set_threads(None)
    assert get_threads() == 3
    with limited_threads(2):
        assert threads() == {2}


@pytest.mark.parametrize("value", ["two", "-1", "1.5"])
def test_bad_environment_value(monkeypatch, value):
    monkeypatch.setenv(ENV, value)
    with pytest.raises(SettingError, match=ENV):
        get_threads()


@pytest.mark.parametrize("bad", [-1, 1.5, "2", True])
def test_bad_python_values(bad):
    with pytest.raises(SettingError):
        set_threads(bad)
    with pytest.raises(SettingError):
        limited_threads(bad)


@pytest.mark.parametrize("variable", [ENV, EVAL_ENV])
def test_cli_bad_environment_is_one_line(monkeypatch, capsys, tmp_path, variable):
    """Said before any work, even by a command that would evaluate only compiled code or nothing at all."""
    monkeypatch.setenv(variable, "many")
    rc = cli.main(["candidates", "ys100", "-n", "3", "--out", str(tmp_path / "c.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and variable in err
    assert not (tmp_path / "c.csv").exists()
    assert threads() == {2}


def test_cli_commands_run_limited(monkeypatch, tmp_path):
    seen = []
    import casadical.cli._planning as planning

    real = planning.cmd_candidates

    def spy(args):
        seen.append(threads())
        return real(args)

    monkeypatch.setattr(planning, "cmd_candidates", spy)
    assert cli.main(["candidates", "ys100", "-n", "3", "--out", str(tmp_path / "c.csv")]) == 0
    assert seen == [{1}]
    assert threads() == {2}


def test_same_numbers_with_and_without_the_limit():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(3000, 40))
    with limited_threads():
        a = np.linalg.cholesky(X.T @ X)
    with limited_threads(0):
        b = np.linalg.cholesky(X.T @ X)
    np.testing.assert_allclose(a, b, rtol=1e-12)


# --- evaluation threads: a large batch of poses in blocks, side by side ----------------------------


@pytest.mark.parametrize("name", ["arm4", "arm5", "arm7"])
def test_blocks_give_the_same_bits_as_one_batch(monkeypatch, name):
    """Every per-pose output (positions, Jacobians, rotations, torques, offsets) is the same in 1, 2 or 3
    blocks, with per-pose covariates (temperature, time, motion direction) sliced with their poses."""
    from casadical.model import Model
    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARMS

    robot = robot_from_dict(ARMS[name])
    model = Model(robot, "kinematic+compliance+backlash+thermal_expansion+drift+periodic[2:1,3:2]", jit=False)
    rng = np.random.default_rng(3)
    N = 731  # blocks of unequal size
    q = rng.uniform(-1.5, 1.5, (N, robot.n))
    p = model.parameters.values + model.parameters.scales * rng.normal(0, 1, len(model.parameters))
    cov = model.default_covariates(N) + rng.normal(0, 1, (N, len(model.covariate_names)))
    methods = ("predict", "predict_jacobian", "predict_angle_jacobian", "predict_q_jacobian", "flange_rotation",
               "flange_rotation_jacobian", "torques", "joint_offsets")
    results = {}
    for n in ("1", "2", "3"):
        monkeypatch.setenv(EVAL_ENV, n)
        for m in methods:
            out = getattr(model, m)(q, p, cov)
            results.setdefault(m, []).append(out if isinstance(out, tuple) else (out,))
        blocks = model._batch("fk_jac", N)
        assert len(getattr(blocks, "blocks", [blocks])) == int(n)
    for m, (one, *more) in results.items():
        for other in more:
            for a, b in zip(one, other):
                assert a.shape == b.shape and np.array_equal(a, b), m
    assert not np.array_equal(results["predict"][0][0][:N // 2], results["predict"][0][0][N // 2:])


def test_small_batches_and_compiled_code_stay_in_one_block(monkeypatch):
    from casadical.model import BLOCK_MIN, Model
    from casadical.model import _jitcache as jitcache
    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARM3

    monkeypatch.setenv(EVAL_ENV, "4")
    model = Model(load_robot("ur10"), "kinematic", jit=False)
    assert not hasattr(model._batch("fk", 2 * BLOCK_MIN - 1), "blocks")
    assert len(model._batch("fk", 4 * BLOCK_MIN).blocks) == 4
    if jitcache.compiler() is not None:   # compiled: one block whatever the size
        compiled = Model(robot_from_dict(ARM3), "kinematic", jit=True)
        assert not hasattr(compiled._batch("fk", 4 * BLOCK_MIN), "blocks")


def test_a_new_setting_while_another_thread_evaluates(monkeypatch):
    """A thread that raises the thread count makes a larger pool while another thread evaluates: the
    evaluating thread never finds its pool shut down, and its numbers stay the same."""
    import threading
    import time

    from casadical.model import Model

    monkeypatch.setenv(EVAL_ENV, "2")
    model = Model(load_robot("ur10"), "kinematic+compliance", jit=False)
    q = np.random.default_rng(1).uniform(-1, 1, (600, 6))
    expect = model.predict(q)
    stop, errors = threading.Event(), []

    def flip():
        for k in range(60):
            os.environ[EVAL_ENV] = str(2 + k % 5)
            evaluation_pool()
            time.sleep(0.002)
        stop.set()

    flipper = threading.Thread(target=flip)
    flipper.start()
    try:
        while not stop.is_set():
            if not np.array_equal(model.predict(q), expect):
                errors.append("different numbers")
    finally:
        flipper.join()
    assert not errors


def test_a_block_that_fails_is_waited_for(monkeypatch):
    """When one block fails, the call still waits for the others before it raises: none of them may go on
    writing into the model's buffers after the call is over. The second block goes on only once the first
    has failed, and then waits for the call to be over (``returned``): a call that waits for it never sets
    that, and the block ends by itself (``returned`` still unset); a call that did not wait sets it first."""
    import threading

    from casadical.model import Model
    from casadical.model._symbolic import _Batch

    monkeypatch.setenv(EVAL_ENV, "2")
    model = Model(load_robot("ur10"), "kinematic", jit=False)
    q = np.random.default_rng(2).uniform(-1, 1, (400, 6))
    blocks = model._batch("fk", 400).blocks
    real, finished = _Batch.evaluate, []
    failed, returned = threading.Event(), threading.Event()

    def evaluate(self, *inputs):
        if self is blocks[0][1]:   # the first block fails, the second is still at work
            failed.set()
            raise RuntimeError("this block fails")
        assert failed.wait(60)
        returned.wait(0.5)
        real(self, *inputs)
        finished.append((self, returned.is_set()))

    monkeypatch.setattr(_Batch, "evaluate", evaluate)
    with pytest.raises(RuntimeError, match="this block fails"):
        model.predict(q)
    returned.set()
    assert finished == [(blocks[1][1], False)]


@pytest.mark.parametrize("value", ["two", "0", "-1", "1.5"])
def test_bad_evaluation_threads_value(monkeypatch, value):
    monkeypatch.setenv(EVAL_ENV, value)
    with pytest.raises(SettingError, match=EVAL_ENV):
        evaluation_threads()


def test_default_evaluation_threads(monkeypatch):
    monkeypatch.delenv(EVAL_ENV, raising=False)
    assert 1 <= evaluation_threads() <= EVAL_MAX
    monkeypatch.setenv(EVAL_ENV, " 3 ")
    assert evaluation_threads() == 3


def test_blocks_after_a_fork(monkeypatch):
    """A child process made by fork has none of its parent's pool threads: it makes its own pool."""
    import multiprocessing

    from casadical.model import Model

    monkeypatch.setenv(EVAL_ENV, "2")
    model = Model(load_robot("ur10"), "kinematic", jit=False)
    q = np.random.default_rng(0).uniform(-1, 1, (400, 6))
    expect = model.predict(q)   # the parent's pool exists now
    ctx = multiprocessing.get_context("fork")
    out = ctx.Queue()
    child = ctx.Process(target=lambda: out.put(model.predict(q)))  # fork: nothing is pickled but the result
    child.start()
    try:
        got = out.get(timeout=60)
        child.join(timeout=60)
    finally:
        if child.is_alive():
            child.kill()
    assert child.exitcode == 0 and np.array_equal(got, expect)


def test_stacked_eigendecompositions_in_threads_give_the_same_bits(monkeypatch):
    """The cross-validation's stacked solve (every fold of every scheme) is shared among the threads."""
    from casadical.diagnosis import solve_identified

    rng = np.random.default_rng(5)
    X = rng.normal(size=(37, 90, 12)) * np.logspace(0, -4, 12)   # some directions poorly determined
    A, b = np.einsum("kni,knj->kij", X, X), rng.normal(size=(37, 12))
    out = {}
    for n in ("1", "2", "3"):
        monkeypatch.setenv(EVAL_ENV, n)
        out[n] = solve_identified(A, b)
    assert np.array_equal(out["1"], out["2"]) and np.array_equal(out["1"], out["3"])
    np.testing.assert_allclose(out["1"][4], solve_identified(A[4], b[4]), rtol=1e-12)
