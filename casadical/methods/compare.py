"""``casadical compare``: every method on the same data, side by side, with timing.

>>> from casadical.methods.compare import compare, format_table
>>> results = compare(robot, cal, val, methods=["KM", "SKCM", "SKCM-CA"], seed=0)  # doctest: +SKIP
>>> print(format_table(results))                                                  # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from .. import __version__
from ..data import Measurements
from ..errors import CasadicalError, InputError
from ..robot import Robot
from . import make_method, method_names
from .base import Inputs, MethodResult, lookup


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
            progress: Callable[[MethodResult], None] | None = None) -> list[MethodResult]:
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
    """
    names = parse_methods(methods)
    settings = settings or {}
    out = []
    for name in names:
        method = make_method(name, **settings.get(name, {}))
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


def _pyplot():
    """matplotlib.pyplot with a file backend, or a one-line error if matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise CasadicalError("--plot needs matplotlib, which is not installed: pip install matplotlib") from None
    return plt


def plot(results: list[MethodResult], sets: dict[str, Measurements], path: str | Path, title: str = "") -> None:
    """Per-pose position error bars per method (one panel per pose set), as the seeds' figures; PNG."""
    plt = _pyplot()
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
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _spread(results, data) -> bool:
    """Log scale when the methods differ by more than a factor 20 (nominal next to calibrated)."""
    means = [float(np.mean(r.errors(data))) for r in results]
    return len(means) > 1 and max(means) > 20 * max(min(means), 1e-12)


# --- command line -------------------------------------------------------------------


def add_commands(sub) -> None:
    """Add the ``compare`` sub-command to the casadical parser."""
    names = ", ".join(method_names())
    p = sub.add_parser(
        "compare", help="run the seed papers' calibration methods side by side",
        description="Run calibration methods on the same data and print the seeds' accuracy table "
                    "(mean / max / std of the position error in mm, calibration and validation poses) "
                    f"with the time per method. Methods: {names}.")
    p.add_argument("robot", metavar="ROBOT", help="built-in robot (ys100, hh800, ur10) or robot TOML file")
    p.add_argument("cal", metavar="CAL.csv", help="calibration poses (with x_mm, y_mm, z_mm)")
    p.add_argument("--validate", metavar="VAL.csv", help="validation poses, never used for fitting")
    p.add_argument("--json", metavar="OUT.json", help="write the results as JSON")
    p.add_argument("--methods", default="", help=f"comma-separated methods (default all: {names})")
    p.add_argument("--extra", metavar="EXTRA.csv",
                   help="further measured poses the network methods train on (the TLBO paper's Q2)")
    p.add_argument("--plot", metavar="OUT.png", help="per-pose error bars per method (PNG, needs matplotlib)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.set_defaults(func=cmd_compare)


def cmd_compare(args) -> int:
    from ..cli import _check_out
    from ..robot import load_robot

    methods = parse_methods(args.methods)        # bad names fail before any work
    inputs = [args.cal, args.validate, args.extra]
    _check_out(args.json, args.force, inputs)
    _check_out(args.plot, args.force, inputs)
    if args.json and args.plot and Path(args.json).resolve() == Path(args.plot).resolve():
        raise InputError("--json and --plot name the same file", file=args.json)
    if args.plot:
        _pyplot()                               # a missing matplotlib fails before the work, too
    robot = load_robot(args.robot)

    def read(path):
        if path is None:
            return None
        return Measurements.read_csv(path, n_joints=robot.n, require_positions=True)

    cal, val, extra = read(args.cal), read(args.validate), read(args.extra)
    print(f"compare on {robot.name}: {len(cal)} calibration poses ({args.cal})"
          + (f", {len(val)} validation poses ({args.validate})" if val is not None else "")
          + (f", {len(extra)} extra poses ({args.extra})" if extra is not None else "")
          + f", seed {args.seed}", flush=True)

    def progress(r: MethodResult) -> None:
        v = f", validation mean {r.validation.mean_mm:.4f} mm" if r.validation else ""
        print(f"  {r.name}: calibration mean {r.calibration.mean_mm:.4f} mm{v} ({r.time_s:.2f} s)",
              file=sys.stderr, flush=True)

    results = compare(robot, cal, val, extra, methods, args.seed, progress=progress)
    print()
    print(format_table(results))
    for r in results:
        comp = r.info.get("compensator")
        if isinstance(comp, dict) and not comp.get("kept", True):
            print(f"note: {r.name}: compensator {comp.get('reason', 'dropped')}")
    if args.json:
        doc = to_json(results, robot=robot.name, calibration_file=args.cal, validation_file=args.validate,
                      extra_file=args.extra, seed=args.seed)
        Path(args.json).write_text(json.dumps(doc, indent=1, allow_nan=False))
        print(f"\nresults -> {args.json}")
    if args.plot:
        plot(results, {"calibration": cal, "validation": val}, args.plot, robot.name)
        print(f"per-pose errors -> {args.plot}")
    return 0
