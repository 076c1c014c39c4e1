"""Ctrl-C and SIGTERM stop the work, also inside CasADi's solvers, and end child processes.

CasADi polls Python's signal handlers while IPOPT iterates; when a handler
raises :class:`KeyboardInterrupt` it catches the exception, prints a
``KeyboardInterruptException`` warning and *returns* the last iterate as if
the solve had merely failed. A calibration would then be written as if
nothing happened. Every signal handler installed here counts the signals
it receives, so a caller can tell afterwards that a call was interrupted
and raise :class:`KeyboardInterrupt` itself (:func:`noticed`).

The command line turns SIGTERM into the same path as Ctrl-C
(:func:`handle_signals`): a :class:`Terminated` (a ``KeyboardInterrupt``)
is raised in the main thread, every ``finally`` and ``with`` on the way
cleans up (staged outputs, forked figure workers, a Dask cluster), and the
command exits 143 (130 for Ctrl-C) with one line.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from typing import Iterator

#: signals received by the handlers of this module (counted, so that a call that swallowed one is noticed)
_received = 0
#: the last signal received (signal number), for the exit code
last_signal: int | None = None


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) received: handled like Ctrl-C, exit 128 + the signal's number."""

    def __init__(self, signum: int = signal.SIGTERM):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise(signum, frame) -> None:
    """The handler of this module: count the signal, raise KeyboardInterrupt (Terminated for SIGTERM)."""
    global _received, last_signal
    _received += 1
    last_signal = signum
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


def received() -> int:
    """How many signals the handlers of this module have received so far in this process."""
    return _received


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def handle_signals() -> Iterator[None]:
    """SIGINT raises KeyboardInterrupt and SIGTERM/SIGHUP :class:`Terminated` while inside (main thread).

    The previous handlers are restored on exit. Outside the main thread
    (where Python cannot set handlers) this does nothing.
    """
    if not _in_main_thread():
        yield
        return
    names = ("SIGINT", "SIGTERM", "SIGHUP")
    old = {}
    try:
        for name in names:
            sig = getattr(signal, name, None)
            if sig is None:
                continue
            prev = signal.getsignal(sig)
            if name == "SIGHUP" and prev == signal.SIG_IGN:   # nohup: keep ignoring the hang-up
                continue
            old[sig] = prev
            signal.signal(sig, _raise)
        yield
    finally:
        for sig, prev in old.items():
            with contextlib.suppress(ValueError, TypeError):
                signal.signal(sig, prev if prev is not None else signal.SIG_DFL)


@contextlib.contextmanager
def noticed() -> Iterator[None]:
    """Around a call that may swallow a KeyboardInterrupt (CasADi's ``nlpsol``): raise it afterwards.

    In the main thread, Python's default Ctrl-C handler is replaced by a
    counting one for the duration of the call (a handler already installed
    by :func:`handle_signals` counts anyway). If a signal arrived during the
    call, :class:`KeyboardInterrupt` (or :class:`Terminated`) is raised when
    the call returns, whatever it returned.
    """
    start = _received
    swapped = False
    if _in_main_thread() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _raise)
        swapped = True
    stderr = sys.stderr
    sys.stderr = _Quiet(stderr)
    try:
        yield
    finally:
        if isinstance(sys.stderr, _Quiet):
            sys.stderr.end()
            sys.stderr = stderr
        if swapped:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if _received != start:     # also when the call raised something else because of the interrupt
            if last_signal not in (None, signal.SIGINT):
                raise Terminated(last_signal)
            raise KeyboardInterrupt


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Ctrl-C or SIGTERM inside the block is raised when the block ends (a start that must not stop halfway).

    For code that, cut short, leaves what it made beyond reach: a Dask
    cluster half started cannot be closed, and its workers would complain
    at exit. Only signals with a Python handler (the default Ctrl-C one, or
    :func:`handle_signals`') are deferred; in another thread this does
    nothing.
    """
    if not _in_main_thread():
        yield
        return
    got: list[int] = []
    old = {}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        prev = signal.getsignal(sig) if sig is not None else None
        if callable(prev):
            old[sig] = prev
            signal.signal(sig, lambda signum, frame: got.append(signum))
    try:
        yield
    finally:
        for sig, prev in old.items():
            signal.signal(sig, prev)
    if got:
        global _received, last_signal
        _received += 1
        last_signal = got[0]
        if got[0] == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(got[0])


class _Quiet:
    """sys.stderr without CasADi's ``KeyboardInterruptException`` warning (the interrupt is reported once).

    CasADi writes a warning in pieces: lines are passed on when complete.
    """

    def __init__(self, stream):
        self._stream = stream
        self._line = ""

    def write(self, text):
        self._line += text
        if "\n" in self._line:
            head, _, self._line = self._line.rpartition("\n")
            kept = [line for line in head.split("\n") if "KeyboardInterruptException" not in line]
            if kept:
                self._stream.write("\n".join(kept) + "\n")
        return len(text)

    def end(self):
        """Pass on a last incomplete line."""
        if self._line and "KeyboardInterruptException" not in self._line:
            self._stream.write(self._line)
        self._line = ""

    def __getattr__(self, name):
        return getattr(self._stream, name)


def exit_code(e: KeyboardInterrupt) -> int:
    """The exit code of a command stopped by ``e``: 128 + the signal's number (130 for Ctrl-C, 143 for SIGTERM)."""
    return 128 + int(getattr(e, "signum", signal.SIGINT))
