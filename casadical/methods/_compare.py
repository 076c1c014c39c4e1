"""``casadical compare``: every method on the same data, side by side, with timing.

>>> from casadical.methods import compare, format_table
>>> results = compare(robot, cal, val, methods=["KM", "SKCM", "SKCM-CA"], seed=0)  # doctest: +SKIP
>>> print(format_table(results))                                                  # doctest: +SKIP
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from .. import __version__
from ..data._checks import check_held_out
from ..data._measurements import Measurements
from ..errors import CasadicalError
from ..robot import Robot
from ..runtime._files import atomic_open
from . import make_method, method_names
from ._base import Inputs, MethodResult, lookup


def parse_methods(text: str | Iterable[str] | None) -> list[str]:
    """Method names from ``"KM,SKCM"`` (or a list); all registered ones if empty. Unknown -> InputError."""
    if text is None:
        return method_names()
    items = [t.strip() for t in (text.split(",") if isinstance(text, str) else text)]
    items = [t for t in items if t]
    if not items:
        return method_names()
    names = [lookup(t).name for t in items]
    seen: set[str] = set()
    return [n for n in names if not (n in seen or seen.add(n))]


def compare(robot: Robot, cal: Measurements, val: Measurements | None = None, extra: Measurements | None = None,
            methods: str | Iterable[str] | None = None, seed: int = 0, settings: dict | None = None,
            progress: Callable[[MethodResult], None] | None = None,
            starting: Callable[[str], None] | None = None) -> list[MethodResult]:
    """Run methods on the same data (same seed each), in the order given.

    Parameters
    ----------
    robot : Robot
    cal, val, extra : Measurements
        Calibration, validation (never fitted) and extra (network training) poses.
    methods : str or list of str, optional
        Names (``"KM,SKCM"``); default all registered methods.
    seed : int
        Seed given to every method: the same seed gives the same table.
    settings : dict, optional
        Per-method settings, ``{name: {setting: value}}``.
    progress : callable, optional
        Called with each result as it is ready.
    starting : callable, optional
        Called with each method's name before it runs (a method may take a while).

    Raises
    ------
    DataFileError
        Every validation pose is a calibration (or extra) pose (:func:`casadical.data._checks.check_held_out`;
        some of them: a warning).
    """
    names = parse_methods(methods)
    settings = settings or {}
    if val is not None:              # validation poses a method has fitted would judge nothing
        for seen in (cal, extra):
            if seen is not None:
                check_held_out(seen, val)
    out = []
    for name in names:
        method = make_method(name, **settings.get(name, {}))
        if starting is not None:
            starting(name)
        res = method.run(Inputs(robot, cal, extra, int(seed)), val)
        out.append(res)
        if progress is not None:
            progress(res)
    return out


def _fmt(x: float) -> str:
    return f"{x:8.4f}" if x is not None and math.isfinite(x) else "       -"


def format_table(results: list[MethodResult], title: str = "") -> str:
    """The seeds' accuracy tables side by side: mean / max / std (mm) on calibration, validation
    (and extra, if any) poses, and the time per method."""
    if not results:
        return "(no method)"
    w = max(12, max(len(r.name) for r in results) + 2)
    groups = [("calibration", results[0].calibration)]
    for label in ("validation", "extra"):
        s = next((getattr(r, label) for r in results if getattr(r, label) is not None), None)
        if s is not None:
            groups.append((label, s))
    head1, head2 = f"{'':<{w}}", f"{'method':<{w}}"
    for k, (label, s) in enumerate(groups):
        sep = "   " if k else ""
        head1 += sep + f"{label + ' (' + str(s.n_poses) + ' poses)':^26}"
        head2 += sep + f"{'mean':>8} {'max':>8} {'std':>8}"
    head2 += f"{'time (s)':>11}"
    lines = ([title] if title else []) + [head1.rstrip(), head2, "-" * len(head2)]
    for r in results:
        line = f"{r.name:<{w}}"
        for k, (label, _) in enumerate(groups):
            st = getattr(r, label)
            line += ("   " if k else "") + (f"{_fmt(st.mean_mm)} {_fmt(st.max_mm)} "
                                             f"{_fmt(st.std_mm)}" if st else f"{'-':>26}")
        line += f"{r.time_s:11.2f}"
        lines.append(line)
    lines.append("errors in mm (position error norm per pose); time = identification + training"
                 + ("; extra = the poses the networks train on" if len(groups) > 2 or groups[-1][0] == "extra"
                    else ""))
    return "\n".join(lines)


def to_json(results: list[MethodResult], **meta) -> dict:
    """The compare JSON: ``{"methods": [{name, calibration, validation, time_s, ...}], ...}``."""
    doc = {"casadical_version": __version__, **meta, "methods": [r.to_dict() for r in results]}
    return doc


def pyplot():
    """matplotlib.pyplot with a file backend, or a one-line error if matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise CasadicalError("--plot needs matplotlib, which is not installed: pip install matplotlib") from None
    return plt


def save_png(plt, fig, path: str | Path, overwrite: bool) -> None:
    """Write ``fig`` as a PNG atomically and close it."""
    with atomic_open(path, "wb", overwrite=overwrite) as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)


def plot(results: list[MethodResult], sets: dict[str, Measurements], path: str | Path, title: str = "",
         overwrite: bool = False) -> None:
    """Per-pose position error bars per method (one panel per pose set), as the seeds' figures; PNG."""
    plt = pyplot()
    sets = {k: v for k, v in sets.items() if v is not None}
    n_max = max(len(d) for d in sets.values())
    fig, axes = plt.subplots(len(sets), 1, figsize=(min(18.0, max(8.0, 0.3 * n_max + 3.0)), 3.0 * len(sets) + 0.6),
                             squeeze=False)
    cmap = plt.get_cmap("tab20" if len(results) > 10 else "tab10")
    width = 0.85 / max(1, len(results))
    for ax, (label, data) in zip(axes[:, 0], sets.items()):
        x = np.arange(1, len(data) + 1)
        for k, r in enumerate(results):
            e = r.errors(data) * 1e3
            ax.bar(x - 0.425 + (k + 0.5) * width, e, width, color=cmap(k % cmap.N),
                   label=f"{r.name} (mean {e.mean():.3f})")
        ax.set_xlim(0.4, len(data) + 0.6)
        ax.set_ylabel("position error (mm)")
        ax.set_xlabel(f"{label} pose")
        ax.set_title(f"{label} poses" + (f": {title}" if title else ""), fontsize=10)
        if _spread(results, data):
            ax.set_yscale("log")
        ax.grid(axis="y", alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, [lb.split(" (")[0] for lb in labels], fontsize=8, ncol=min(6, len(results)),
               loc="upper center", frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / (3.0 * len(sets) + 0.6) * (1 + (len(results) - 1) // 6)))
    save_png(plt, fig, path, overwrite)


def _spread(results, data) -> bool:
    """Log scale when the methods differ by more than a factor 20 (nominal next to calibrated)."""
    means = [float(np.mean(r.errors(data))) for r in results]
    return len(means) > 1 and max(means) > 20 * max(min(means), 1e-12)
