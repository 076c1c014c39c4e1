"""Figures of the HTML reports: matplotlib drawn to inline SVG, one shared style.

Figures are made with :class:`matplotlib.figure.Figure` directly, never
through ``pyplot``: no display, no global backend switch in the caller's
program, nothing kept open. Text stays text in the SVG (``svg.fonttype
none``: small files, selectable, checked for overflow in a browser) and
every figure gets its own id salt, so several figures on one page never
share clip-path ids while the output stays the same from run to run.
"""

from __future__ import annotations

import contextlib
import functools
import html
import io
import os
import re
import signal
import sys
import threading

import numpy as np
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..runtime.interrupts import checkpoint

#: colour-blind safe (Paul Tol's "bright"): before / after and series
BEFORE, AFTER, CURVE = "#EE6677", "#4477AA", "#228833"
SERIES = ("#4477AA", "#EE6677", "#228833", "#CCBB44", "#66CCEE", "#AA3377", "#BBBBBB")

STYLE = {
    "svg.fonttype": "none",
    "font.family": "sans-serif",
    "font.sans-serif": ["DejaVu Sans", "Liberation Sans", "Arial"],
    "font.size": 9.5,
    "axes.titlesize": 10,
    "axes.labelsize": 9.5,
    "legend.fontsize": 9,
    "xtick.labelsize": 8.5,
    "ytick.labelsize": 8.5,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.grid": True,
    "grid.color": "#e3e3e3",
    "grid.linewidth": 0.7,
    "axes.axisbelow": True,
    "axes.xmargin": 0.03,
    "axes.ymargin": 0.06,
    "lines.linewidth": 1.6,
    "lines.markersize": 4,
    "legend.frameon": False,
}


def styled(build):
    """Decorator: ``build`` (a function making a figure) runs in the report style.

    matplotlib reads most style settings when an artist is made, so the whole
    drawing, not only the figure's creation, runs inside the style.
    """
    @functools.wraps(build)
    def run(*args, **kwargs):
        with rc_context(STYLE):
            return build(*args, **kwargs)
    return run


def figure(width_in: float = 6.4, height_in: float = 3.4, nrows: int = 1, ncols: int = 1,
           **subplots) -> tuple[Figure, np.ndarray]:
    """A figure and its axes (always a 2-D array); call it inside a :func:`styled` function.

    Parameters
    ----------
    width_in, height_in : float
        Size in inches (shown at 96 px per inch, scaled down on narrow screens).
    nrows, ncols : int
    **subplots
        Passed to :meth:`matplotlib.figure.Figure.subplots` (``sharex`` ...).
    """
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    return fig, fig.subplots(nrows, ncols, squeeze=False, **subplots)


def ticks(ax: Axes, x: bool = True, y: bool = True, n: int = 7, least: int = 4) -> None:
    """Enough ticks on linear axes: about ``n`` and never fewer than ``least``."""
    for use, axis in ((x, ax.xaxis), (y, ax.yaxis)):
        if use and axis.get_scale() == "linear":
            axis.set_major_locator(MaxNLocator(nbins=n, min_n_ticks=least))


def legend_above(ax: Axes, ncols: int | None = None, **kwargs) -> None:
    """The legend in one row above the axes, where it can never cover data."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0, 1.01), ncols=ncols or len(handles),
                  borderaxespad=0.2, handlelength=1.6, columnspacing=1.2,
                  **kwargs)


def ecdf(ax: Axes, before, after, before_label: str, after_label: str) -> None:
    """Empirical cumulative distributions of position errors (mm) before and after, as step lines."""
    for values, label, colour in ((before, before_label, BEFORE), (after, after_label, AFTER)):
        v = np.sort(np.asarray(values, float))
        if len(v):
            ax.step(np.concatenate([[v[0]], v]), np.arange(len(v) + 1) / len(v), where="post",
                    color=colour, label=label)
    ax.set(xlabel="position error (mm)", ylabel="share of poses with a smaller error", ylim=(0, 1.02))
    ticks(ax)


_HEADER = re.compile(r"^.*?(?=<svg)", re.S)


def to_svg(fig: Figure, key: str, label: str) -> str:
    """The figure as an ``<svg>`` element to put in a page.

    Parameters
    ----------
    fig : Figure
    key : str
        Unique on the page (salts the SVG's internal ids).
    label : str
        Accessible name of the image (``aria-label``).
    """
    buf = io.StringIO()
    with rc_context({**STYLE, "svg.hashsalt": key}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    svg = _HEADER.sub("", buf.getvalue(), count=1)
    svg = svg.replace("<svg ", f'<svg role="img" aria-label="{html.escape(label)}" ', 1)
    return re.sub(r"<metadata>.*?</metadata>\s*", "", svg, count=1, flags=re.S)


_JOBS: list = []   # what the processes of render() draw (inherited through fork, never pickled)
#: held by render() while it draws: matplotlib is not thread-safe, and a child forked while another thread
#: draws could inherit a lock that thread held and never get it (the call would hang)
_DRAWING = threading.RLock()


def _draw(jobs, indices) -> list[str]:
    out = []
    for i in indices:
        fig, key, label = jobs[i]
        out.append(to_svg(fig() if callable(fig) else fig, key, label))
    return out


def _draw_inherited(indices) -> list[str]:
    return _draw(_JOBS, indices)


#: the signals a figure worker is forked with blocked, until it has set its own handlers
_HELD = {signal.SIGINT, signal.SIGTERM}


def _child_start(parent: int) -> None:
    """First thing in a forked figure worker: die with the parent, leave signals to it.

    Linux's ``PR_SET_PDEATHSIG`` sends the worker SIGKILL when the process
    that forked it ends, however it ends (even killed outright): no worker
    outlives the command, none waits on a pipe no one reads. Ctrl-C, sent to
    the terminal's whole process group, is the parent's to handle (it ends
    the workers); SIGTERM ends a worker at once, without the parent's
    Python handler.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    # forked with both blocked (_render_in): one that came before the lines above is taken by them, never by the
    # parent's Python handler copied into this process (a KeyboardInterrupt here printed 'Process ForkProcess-1:')
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD)
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)   # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):   # not Linux's C library: the parent's clean-up alone ends the workers
        pass
    if os.getppid() != parent:          # the parent ended before the line above took effect
        os._exit(1)


def _end_workers(pool) -> None:
    """Stop a pool's worker processes now (an interrupt or error in the parent): no waiting for their shares."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        with contextlib.suppress(Exception):
            p.kill()
    for p in processes:
        with contextlib.suppress(Exception):
            p.join(5)


def render(jobs: list[tuple], processes: int = 1) -> list[str]:
    """``<svg>`` elements of figures, in order.

    Parameters
    ----------
    jobs : list of (Figure or callable, str, str)
        A figure or a function making one, its key and its label (:func:`to_svg`).
    processes : int
        Draw in this many processes: this one and ``processes - 1`` forked
        children, each a share of the figures (Linux only). matplotlib holds
        the GIL, so threads would not help. The SVG is the same either way.
        Where no child process can be made, or a child fails, this process
        draws its share.

    Notes
    -----
    Calls from several threads draw one after the other. Other matplotlib
    drawing in another thread while this forks could leave a child waiting
    for a lock forever: draw elsewhere with ``processes=1``.
    """
    with _DRAWING:
        return _render(jobs, processes)


def _render(jobs: list[tuple], processes: int) -> list[str]:
    n = len(jobs)
    if processes < 2 or n < 2 or not sys.platform.startswith("linux"):   # fork is safe on Linux only
        return _draw(jobs, range(n))
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    k = min(processes, n)
    shares = [list(range(i, n, k)) for i in range(k)]   # interleaved: the costly figures are spread
    try:
        pool = ProcessPoolExecutor(k - 1, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_child_start, initargs=(os.getpid(),))
    except (OSError, ValueError, ImportError):   # no semaphores or shared memory here: draw them all in this one
        return _draw(jobs, range(n))
    try:
        done = _render_in(pool, jobs, shares)
    except BaseException:          # Ctrl-C, SIGTERM, an error: the workers end with it, now
        _end_workers(pool)
        raise
    pool.shutdown(wait=True)
    out: list = [None] * n
    for share, svgs in done:
        for i, svg in zip(share, svgs):
            out[i] = svg
    return out


def _render_in(pool, jobs: list[tuple], shares: list[list[int]]) -> list[tuple[list[int], list[str]]]:
    """The shares drawn: the first here, the others by ``pool`` (or here, where a worker fails)."""
    global _JOBS
    futures = []
    _JOBS = jobs   # the children are forked at the first submit and take _JOBS as it is then
    held = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)   # until a child has its own handlers (_child_start)
    try:
        for share in shares[1:]:
            try:
                futures.append((share, pool.submit(_draw_inherited, share)))
            except Exception:  # noqa: BLE001  (no child process here: this one draws its share)
                futures.append((share, None))
    finally:
        _JOBS = []
        signal.pthread_sigmask(signal.SIG_SETMASK, held)   # a signal that came meanwhile is the parent's now
    checkpoint("figures")   # the workers draw their shares now
    done = [(shares[0], _draw(jobs, shares[0]))]
    for share, fut in futures:
        try:
            done.append((share, fut.result() if fut else _draw(jobs, share)))
        except Exception:  # noqa: BLE001  (a child that failed: its share is drawn here)
            done.append((share, _draw(jobs, share)))
    return done
