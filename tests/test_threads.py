"""casadical.threads: the BLAS/OpenMP limit is in force inside, restored after, and can be overridden."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (a second OpenBLAS: the limit must reach every loaded library)
from threadpoolctl import threadpool_limits

from casadical import cli
from casadical.errors import SettingError
from casadical.threads import ENV, blas_threads, get_threads, limited_threads, set_threads


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


def test_cli_bad_environment_is_one_line(monkeypatch, capsys, tmp_path):
    monkeypatch.setenv(ENV, "many")
    rc = cli.main(["candidates", "ys100", "-n", "3", "--out", str(tmp_path / "c.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and ENV in err
    assert not (tmp_path / "c.csv").exists()
    assert threads() == {2}


def test_cli_commands_run_limited(monkeypatch, tmp_path):
    seen = []
    import casadical.cli.planning as planning

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
