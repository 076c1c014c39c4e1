"""Ctrl-C and SIGTERM stop the work, also inside CasADi's solvers, and end child processes.

CasADi polls Python's signal handlers while IPOPT iterates; when a handler
raises :class:`KeyboardInterrupt` it catches the exception, prints a
``KeyboardInterruptException`` warning and *returns* the last iterate as if
the solve had merely failed. A calibration would then be written as if
nothing happened. Every signal handler installed here counts the signals
it receives, so a caller can tell afterwards that a call was interrupted
and raise :class:`KeyboardInterrupt` itself (:func:`noticed`); a command's
outputs are not put in place when a signal came during its work, even one
that a library turned into another exception or swallowed
(:func:`casadical.runtime._files.outputs_together`).

The command line turns SIGTERM into the same path as Ctrl-C
(:func:`handle_signals`): a :class:`Terminated` (a ``KeyboardInterrupt``)
is raised in the main thread, every ``finally`` and ``with`` on the way
cleans up (staged outputs, a Dask cluster), and the
command exits 143 (130 for Ctrl-C) with one line. The process of the
command line (:func:`command_process`) answers a signal at every moment
with one line and that exit code: before the work (while Python imports) it
ends at once; once a command's outputs are in place (:func:`finish`), a
signal no longer stops anything and is said when the process ends, its
outputs kept and complete.

``CASADICAL_SIGNAL_AT=POINT[:SIGNAL[:group]]`` makes the process send itself a
signal (default SIGTERM; ``group``: to its process group) the first time it reaches a named moment of a
command (:func:`checkpoint`, :data:`POINTS`), and
``CASADICAL_PAUSE_AT=POINT:FIFO`` makes it wait there until a test lets
it go on: the tests stop commands, or run two at once, at the moments they
choose, without waiting on a clock.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading
from typing import Iterator

#: signals received by the handlers of this module (counted, so that a call that swallowed one is noticed)
_received = 0
#: the last signal received (signal number), for the exit code
last_signal: int | None = None
#: :data:`_received` when a command last said it answered the signals itself (:func:`answered`)
_answered = -1
#: signals that came after the command's outputs were in place (:func:`finish`): said when it ends
_late: list[int] = []
#: the command is past the point of no return (its outputs are in place): a signal stops nothing
_finished = False
#: how many outputs the last command put in place (for the line that says a late signal)
_outputs = 0
#: inside :func:`handle_signals` (a command's work)
_active = False
#: the command line's process (:func:`command_process`): its work has begun (else a signal ends it at once)
_work_begun = False
#: the exit code of the command line's process, for :func:`_end_process`
_exit_code = 0

#: environment variable naming a moment at which the process signals itself (tests; :func:`checkpoint`)
SIGNAL_AT_ENV = "CASADICAL_SIGNAL_AT"
#: environment variable naming a moment at which the process waits on a named pipe (tests; :func:`checkpoint`)
PAUSE_AT_ENV = "CASADICAL_PAUSE_AT"
#: the moments :func:`checkpoint` knows: every command's, in the order it reaches them, then a study's
POINTS = ("start", "work", "compile", "solver", "output", "figures", "commit", "exit",
          "study-folder", "study-locked", "cluster", "repetition")
_fired = _paused = False


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) received: handled like Ctrl-C, exit 128 + the signal's number."""

    def __init__(self, signum: int = signal.SIGTERM):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _count(signum: int) -> None:
    global _received, last_signal
    _received += 1
    last_signal = signum


def stopped(signum: int) -> KeyboardInterrupt:
    """The exception a signal raises: KeyboardInterrupt for SIGINT, else :class:`Terminated`."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def _raise(signum, frame) -> None:
    """The handler of this module: count the signal, raise KeyboardInterrupt (Terminated for SIGTERM).

    Once the command's outputs are in place (:func:`finish`) the signal is
    kept for the end instead (:func:`late`).
    """
    _count(signum)
    if _finished:
        _late.append(signum)
        return
    raise stopped(signum)


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
    global _active, _finished, _outputs, _work_begun
    if not _in_main_thread():
        yield
        return
    names = ("SIGINT", "SIGTERM", "SIGHUP")
    old = {}
    _finished, _outputs, _active = False, 0, True
    _late.clear()
    _work_begun = True
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
        _finished = _active = False


def finish(outputs: int) -> None:
    """The command's ``outputs`` files are in place: from here a signal stops nothing (:func:`late`).

    Called by :func:`casadical.runtime._files.outputs_together` once its files are
    moved; :func:`handle_signals` starts the next command afresh.
    """
    global _finished, _outputs
    _outputs = outputs
    _finished = _active        # outside a command (a library's own use) signals keep their way


def since(count: int) -> KeyboardInterrupt | None:
    """The exception of the last signal if any came after :func:`received` was ``count``, else None.

    Signals a caller has answered itself (:func:`answered`) do not count.
    """
    if _received in (count, _answered):
        return None
    return stopped(last_signal if last_signal is not None else signal.SIGINT)


def answered() -> None:
    """The signals received so far were answered (a command that stopped and said so itself, exit 128 + it)."""
    global _answered
    _answered = _received


def late() -> str | None:
    """One line for the signals that came after the command's outputs were in place (None if none came).

    Each is said once: a second call says only the ones that came since.
    """
    if not _late:
        return None
    signum = _late[-1]
    _late.clear()
    what = "interrupted" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}"
    n = _outputs
    kept = f"; its {n} output{'s are' if n != 1 else ' is'} complete" if n else ""
    return f"casadical: {what} after the command had finished{kept}"


def late_exit_code() -> int | None:
    """128 + the number of the last late signal (before :func:`late` clears them), or None."""
    return 128 + _late[-1] if _late else None


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
def deferred() -> Iterator[list[int]]:
    """Ctrl-C or SIGTERM inside the block is raised when the block ends (a start that must not stop halfway).

    The block sees the signals received so far (the list it is given); if it
    calls :func:`finish`, they are kept for the end (:func:`late`) instead.

    For code that, cut short, leaves what it made beyond reach: a Dask
    cluster half started cannot be closed, and its workers would complain
    at exit. Only signals with a Python handler (the default Ctrl-C one, or
    :func:`handle_signals`') are deferred; in another thread this does
    nothing.
    """
    if not _in_main_thread():
        yield []
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
        yield got
    finally:
        for sig, prev in old.items():
            signal.signal(sig, prev)
    if got:
        _count(got[0])
        if _finished:                # the block put the outputs in place (finish): the signal is said at the end
            _late.extend(got)
            return
        raise stopped(got[0])


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


# --- the command line's process ---------------------------------------------------------------------------


def checkpoint(point: str) -> None:
    """A named moment of a command, where a test may stop the process or hold it (:data:`POINTS`).

    ``CASADICAL_SIGNAL_AT=POINT[:SIGNAL[:group]]`` (a signal name such as
    ``SIGINT``, default ``SIGTERM``): the first time the process reaches
    ``point`` it sends itself the signal, as a user or a job scheduler
    would at that moment (``group``: to its whole process group, as a
    terminal's Ctrl-C). ``CASADICAL_PAUSE_AT=POINT:FIFO``: the first time
    it reaches ``point`` it opens the named pipe FIFO and reads it to its
    end: a test that opens the pipe for writing knows the process is there,
    and lets it go on by closing it. Only for tests; without the variables
    this costs two dictionary look-ups.
    """
    global _fired, _paused
    pause = os.environ.get(PAUSE_AT_ENV)
    if pause and not _paused and pause.partition(":")[0] == point:
        _paused = True
        with open(pause.partition(":")[2], "rb") as fh:
            fh.read()
    spec = os.environ.get(SIGNAL_AT_ENV)
    if not spec or _fired:
        return
    name, _, rest = spec.partition(":")
    if name != point:
        return
    _fired = True
    sig, _, whom = rest.partition(":")
    signum = getattr(signal, sig.upper() or "SIGTERM")
    if whom == "group":
        os.killpg(os.getpgrp(), signum)
    else:
        os.kill(os.getpid(), signum)


def wanted(point: str) -> bool:
    """``CASADICAL_SIGNAL_AT`` names ``point`` (a solver may then add the hook :func:`checkpoint` needs)."""
    return os.environ.get(SIGNAL_AT_ENV, "").partition(":")[0] == point


def _in_process(signum, frame) -> None:
    """The command line's handler outside a command's work: before it, end at once; after it, say it at the end."""
    _count(signum)
    if not _work_begun:        # nothing written yet, nothing to clean up: one line, and gone
        what = "interrupted" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}"
        os.write(2, f"casadical: {what}; no output was written\n".encode())
        os._exit(128 + signum)
    _late.append(signum)


def command_process() -> None:
    """Make this process the command line's: every signal, at every moment, is one line and exit 128 + signal.

    Until a command's work begins a signal ends the process at once (it has
    written nothing); once the work is over (outputs in place or given up)
    it is kept and said when the process ends (:func:`end_process`), whatever the
    interpreter is doing then (waiting for threads, running ``atexit``).
    """
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is None or (name == "SIGHUP" and signal.getsignal(sig) == signal.SIG_IGN):
            continue
        signal.signal(sig, _in_process)
    atexit.register(_end_process)     # registered first, so run last: after threads ended and every atexit
    checkpoint("start")


def end_process(code: int) -> None:
    """End the command line's process with ``code`` (or 128 + a signal that came after the command)."""
    global _exit_code
    _exit_code = code
    atexit.register(checkpoint, "exit")   # run first at exit: while the interpreter ends
    sys.exit(code)


def _end_process() -> None:
    """The last thing the process does: a late signal said, the streams flushed, the exit code as decided.

    ``os._exit``: Python would otherwise end with SIGINT itself whenever a
    Ctrl-C passed through one of its C-level calls, whatever was caught.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    code = late_exit_code() or _exit_code
    line = late()
    if line:
        with contextlib.suppress(OSError):
            os.write(2, (line + "\n").encode())
    os._exit(code)
