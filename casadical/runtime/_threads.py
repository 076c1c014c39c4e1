"""Thread limits for the library's small dense linear algebra, and threads for model evaluation.

casadical's matrices are small (tens of parameters, a few thousand rows per
block). Multi-threaded BLAS gains little on them and loses a lot on a busy
machine: with more BLAS threads than free cores the threads wait on each
other, and a calculation that takes 1 s alone can take 10-40 s next to one
other busy process. The library therefore runs its dense linear algebra
with **one BLAS/OpenMP thread** unless told otherwise:

- environment variable ``CASADICAL_THREADS``: a whole number ``n >= 1``
  (at most n threads), or ``0`` / ``all`` (no limit: BLAS's own default);
- from Python, :func:`set_threads` (overrides the environment variable for
  this process; ``set_threads(None)`` returns to it).

:func:`limited_threads` is a context manager and decorator that applies the
limit to every BLAS and OpenMP library loaded in the process (numpy's and
scipy's OpenBLAS, MKL, ...) through `threadpoolctl
<https://github.com/joblib/threadpoolctl>`_, and restores the previous
settings on exit. Thread counts of these libraries are process-wide, so the
limit holds for every Python thread while any is inside. Entering and
leaving costs 5-14 us when nested in another limit and 5-27 us when it
changes a library's limit (2-core VM at load 3-8, two OpenBLAS libraries
loaded; ``benchmarks/speed/bench_plan_poses.py``); the scan for loaded libraries
(~8 ms) is done once and repeated only after new modules have been imported.

Examples
--------
>>> from casadical.runtime import limited_threads, set_threads
>>> with limited_threads():
...     pass                                  # BLAS runs on one thread here
>>> set_threads(2)                            # this process: two threads
>>> @limited_threads()
... def solve(): ...
>>> set_threads(None)                         # back to CASADICAL_THREADS / 1

Evaluating a model on many poses (CasADi, which releases the GIL) is a
different matter: each thread takes its own block of poses and nothing
waits on anything until the blocks are done, so no thread spins on a busy
machine. The same threads share out the diagnosis' stacks of small
eigendecompositions (one per cross-validation fold).
:func:`evaluation_threads` says how many threads do it:
``CASADICAL_EVAL_THREADS`` (a whole number ``n >= 1``), else the cores this
process may use, at most :data:`EVAL_MAX`.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading

from ..errors import SettingError

#: environment variable read by :func:`get_threads`
ENV = "CASADICAL_THREADS"
#: the limit when neither :func:`set_threads` nor the environment says otherwise
DEFAULT = 1

#: environment variable read by :func:`evaluation_threads`
EVAL_ENV = "CASADICAL_EVAL_THREADS"
#: the most evaluation threads by default (blocks of a few hundred poses gain little from more)
EVAL_MAX = 4

_lock = threading.RLock()
_setting: int | None = None        # set_threads(); None = not set
_controller = None                 # threadpoolctl.ThreadpoolController, created on first use
_n_modules = -1                    # len(sys.modules) when the controller scanned the process


def set_threads(n: int | None) -> None:
    """Set the thread limit of :func:`limited_threads` for this process.

    Parameters
    ----------
    n : int or None
        ``n >= 1``: at most n BLAS/OpenMP threads; ``0``: no limit; ``None``:
        forget the setting (``CASADICAL_THREADS``, else 1, applies again).
    """
    global _setting
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 0):
        raise SettingError(f"set_threads takes a whole number >= 0 or None, got {n!r}")
    _setting = n


def get_threads() -> int | None:
    """The limit in force: a thread count, or None for no limit.

    :func:`set_threads` if called, else ``CASADICAL_THREADS``, else 1.
    """
    n = _setting
    if n is None:
        text = os.environ.get(ENV, "").strip()
        if not text:
            return DEFAULT
        if text.lower() == "all":
            return None
        try:
            n = int(text)
        except ValueError:
            n = -1
        if n < 0:
            raise SettingError(f"environment variable {ENV} must be a whole number >= 1, or 0 "
                                     f"or 'all' for no limit; got {text!r}")
    return n or None


def _libraries() -> list:
    """threadpoolctl's controllers of the BLAS/OpenMP libraries loaded now (rescanned after imports)."""
    global _controller, _n_modules
    n = len(sys.modules)
    if _controller is None or n != _n_modules:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
        _n_modules = n
    return _controller.lib_controllers


class limited_threads(contextlib.ContextDecorator):
    """Context manager and decorator: BLAS/OpenMP threads limited to :func:`get_threads`.

    Parameters
    ----------
    n : int, optional
        This limit instead of the configured one (``0``: no limit).

    Notes
    -----
    Only libraries whose thread count differs from the limit are changed, and
    exactly those are restored on exit, so nested use costs next to nothing.
    """

    def __init__(self, n: int | None = None):
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 0):
            raise SettingError(f"limited_threads takes a whole number >= 0, got {n!r}")
        self.n = n
        self._changed: list[list] = []   # per active entry: (library, previous count)

    def __enter__(self) -> "limited_threads":
        with _lock:
            limit = get_threads() if self.n is None else (self.n or None)
            changed = []
            if limit is not None:
                for lib in _libraries():
                    old = lib.get_num_threads()
                    if old != limit:
                        lib.set_num_threads(limit)
                        changed.append((lib, old))
            self._changed.append(changed)
        return self

    def __exit__(self, *exc) -> None:
        with _lock:
            for lib, old in reversed(self._changed.pop()):
                lib.set_num_threads(old)


def blas_threads() -> dict[str, int]:
    """Current thread count of each loaded BLAS/OpenMP library, by file name (for reports and tests)."""
    with _lock:
        return {os.path.basename(lib.filepath): lib.get_num_threads() for lib in _libraries()}


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def evaluation_threads() -> int:
    """Threads that evaluate one large batch of poses (:class:`casadical.model._symbolic.Model`), each its own block.

    ``CASADICAL_EVAL_THREADS`` if set (a whole number >= 1), else the cores
    this process may use, at most :data:`EVAL_MAX`. The results do not
    depend on it: every pose is evaluated alone, by the same code.
    """
    text = os.environ.get(EVAL_ENV, "").strip()
    if not text:
        return max(1, min(usable_cores(), EVAL_MAX))
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise SettingError(f"environment variable {EVAL_ENV} must be a whole number >= 1; got {text!r}")
    return n


_pool: tuple | None = None   # (size, ThreadPoolExecutor) of evaluation_pool()


def evaluation_pool():
    """The process-wide pool of at least :func:`evaluation_threads` threads.

    A larger setting makes a larger pool; the old one is never shut down (a
    caller may still be queuing its blocks there): once nothing refers to
    it, its threads finish their work and end. Callers submit one task per
    block, so a pool larger than the setting runs no more threads than that.
    """
    global _pool
    n = evaluation_threads()
    with _lock:
        if _pool is None or _pool[0] < n:
            from concurrent.futures import ThreadPoolExecutor

            _pool = (n, ThreadPoolExecutor(n, thread_name_prefix="casadical-eval"))
        return _pool[1]


def _after_fork_in_child() -> None:
    """A forked child has none of its parent's threads: a lock held by one of them, or its pool, is void."""
    global _lock, _pool
    _lock, _pool = threading.RLock(), None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)
