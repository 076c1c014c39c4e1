"""Summaries of a study's results: the comparison table and the plots.

For every plan (and number of poses) and method: how many repetitions
succeeded, the median and interquartile range of a metric (by default the
validation mean error), the median error against the true positions, and
the win rate against a baseline method: the share of repetitions, among
those where both succeeded, in which the method's metric is lower (ties
count half). Repetitions are paired: every method of a plan calibrates on
the same poses and is judged on the same validation poses.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ._store import ResultStore
from ._task import COLUMNS

#: columns a summary can rank by
METRICS = tuple(name for name, kind in COLUMNS if kind == "float")


@dataclass
class SummaryRow:
    """One method on one plan (and number of poses); errors in mm."""

    plan: str
    n_poses: int
    method: str
    runs: int
    ok: int
    median: float
    q25: float
    q75: float
    true_median: float
    win_rate: float | None
    pairs: int
    stiffness_error_median: float
    fit_time_median: float
    placements: int = 0
    rows_per_point: int = 0
    distance_error_median: float = float("nan")


@dataclass
class Summary:
    """The comparison table of a study.

    Attributes
    ----------
    name : str
    metric : str
        Column the median, IQR and win rate are of.
    baseline : str
    repetitions : int
        Distinct repetitions in the results.
    rows : list of SummaryRow
    values : dict
        ``(plan, n_poses, method)`` -> the metric of its successful repetitions (for plots).
    """

    name: str
    metric: str
    baseline: str
    repetitions: int
    rows: list[SummaryRow]
    values: dict = field(default_factory=dict, repr=False)
    touch: bool = False

    def to_dict(self) -> dict:
        """The table as JSON-ready data (``win_rate`` None for the baseline; NaN where no repetition succeeded)."""
        keep = (lambda r: r) if self.touch else (  # noqa: E731
            lambda r: {k: v for k, v in r.items() if k not in ("placements", "rows_per_point",
                                                               "distance_error_median")})
        return {"name": self.name, "metric": self.metric, "baseline": self.baseline,
                "repetitions": self.repetitions, "rows": [keep(asdict(r)) for r in self.rows]}

    def table(self) -> str:
        """Markdown table; a study of touches: placements and rows per socket, the distance error beside the
        metric (by default the consistency on fresh placements), the true error after the best rigid motion."""
        columns = _TOUCH_COLUMNS if self.touch else _COLUMNS
        out = [f"study {self.name}: {self.repetitions} repetitions; {self.metric} over the repetitions "
               f"that succeeded; win rate = share of paired repetitions with a lower {self.metric} than "
               f"{self.baseline}", "",
               "| " + " | ".join(h.format(baseline=self.baseline) for h, _ in columns) + " |",
               "|" + "---|" * len(columns)]
        out += ["| " + " | ".join(cell(r) for _, cell in columns) + " |" for r in self.rows]
        return "\n".join(out)


def _win(r: SummaryRow) -> str:
    return "-" if r.win_rate is None else f"{100 * r.win_rate:.0f} % of {r.pairs}"


#: the table's columns, (header, cell of a row), of a study of a tracker's poses and of one of touches
_COLUMNS = (
    ("plan", lambda r: r.plan), ("poses", lambda r: str(r.n_poses)), ("method", lambda r: r.method),
    ("ok", lambda r: f"{r.ok}/{r.runs}"), ("median", lambda r: _num(r.median)),
    ("IQR", lambda r: f"{_num(r.q25)} - {_num(r.q75)}"), ("true error, median", lambda r: _num(r.true_median)),
    ("win rate vs {baseline}", _win), ("stiffness error, median (%)", lambda r: _num(r.stiffness_error_median, 2)),
    ("fit time, median (s)", lambda r: _num(r.fit_time_median, 3)))
_TOUCH_COLUMNS = (
    ("plan", lambda r: r.plan), ("placements", lambda r: str(r.placements)),
    ("rows per socket", lambda r: str(r.rows_per_point)), ("rows", lambda r: str(r.n_poses)),
    ("method", lambda r: r.method), ("ok", lambda r: f"{r.ok}/{r.runs}"), ("median", lambda r: _num(r.median)),
    ("IQR", lambda r: f"{_num(r.q25)} - {_num(r.q75)}"),
    ("distance error, median", lambda r: _num(r.distance_error_median)),
    ("true error, median", lambda r: _num(r.true_median)), ("win rate vs {baseline}", _win),
    ("fit time, median (s)", lambda r: _num(r.fit_time_median, 3)))


def _num(x: float, digits: int = 4) -> str:
    if not np.isfinite(x):
        return "-" if np.isnan(x) else "inf"
    return f"{x:.{digits}f}" if abs(x) < 1e4 else f"{x:.3g}"


def _median(x: np.ndarray) -> float:
    x = x[~np.isnan(x)]
    return float(np.median(x)) if len(x) else float("nan")


def summarize(results: str | Path | ResultStore, baseline: str | None = None,
              metric: str | None = None) -> Summary:
    """The comparison table of a results folder.

    Parameters
    ----------
    results : path or ResultStore
    baseline : str, optional
        Method the win rates are against (default: the protocol's first method).
    metric : str, optional
        A float column of the results (:data:`METRICS`); default ``val_mean_mm``, for a study of touches
        ``val_consistency_mm``.

    Raises
    ------
    InputError
        Not a results folder, unknown baseline or metric.
    """
    store = results if isinstance(results, ResultStore) else ResultStore.open(results)
    touch = bool(store.manifest.get("touch"))
    metric = metric or ("val_consistency_mm" if touch else "val_mean_mm")
    if metric not in METRICS:
        raise InputError(f"unknown metric {metric!r}; choose from {', '.join(METRICS)}")
    methods = store.manifest["methods"]
    if baseline is None:
        baseline = methods[0]
    match = {m.lower(): m for m in methods}.get(baseline.strip().lower())
    if match is None:
        raise InputError(f"no method {baseline!r} in this study; its methods: {', '.join(methods)}",
                         file=str(store.path))
    baseline = match
    table = store.read()
    col = {c: np.asarray(table.column(c).to_numpy(zero_copy_only=False))
           for c in ("repetition", "plan", "n_poses", "method", "status", metric, "val_true_mean_mm",
                     "stiffness_error_pct", "fit_time_s", "val_distance_error_mm")}
    ok = col["status"] == "ok"
    usable = ok & ~np.isnan(col[metric])          # e.g. no stiffness error for a kinematic method
    rows, values = [], {}
    for plan in store.manifest["plans"]:
        for n in plan["poses"]:
            cell = (col["plan"] == plan["name"]) & (col["n_poses"] == n)
            if not cell.any():
                continue
            base = cell & usable & (col["method"] == baseline)
            base_of = dict(zip(col["repetition"][base].tolist(), col[metric][base].tolist()))
            for m in methods:
                sel = cell & (col["method"] == m)
                good = sel & usable
                v = col[metric][good]
                values[(plan["name"], n, m)] = v
                q25, med, q75 = np.percentile(v, [25, 50, 75]) if len(v) else (np.nan,) * 3
                win, pairs = None, 0
                if m != baseline:
                    b = np.array([base_of.get(r, np.nan) for r in col["repetition"][good].tolist()])
                    paired = ~np.isnan(b)
                    pairs = int(paired.sum())
                    if pairs:
                        a, b = v[paired], b[paired]
                        win = float(((a < b).sum() + 0.5 * (a == b).sum()) / pairs)
                with np.errstate(invalid="ignore"):
                    done = sel & ok
                    where = {}
                    if touch:
                        k = plan["poses"].index(n)
                        where = {"placements": plan["placements"], "rows_per_point": plan["rows_per_point"][k],
                                 "distance_error_median": _median(col["val_distance_error_mm"][done])}
                    rows.append(SummaryRow(plan["name"], int(n), m, int(sel.sum()), int(done.sum()), float(med),
                                           float(q25), float(q75), _median(col["val_true_mean_mm"][done]), win,
                                           pairs, _median(col["stiffness_error_pct"][done]),
                                           _median(col["fit_time_s"][done]), **where))
    return Summary(store.manifest.get("name", ""), metric, baseline, len(set(col["repetition"].tolist())),
                   rows, values, touch)


def plot_summary(summary: Summary, folder: str | Path, overwrite: bool = False) -> list[Path]:
    """Write ``errors.png`` (distribution per method and plan) and, if a plan has several
    sizes, ``poses.png`` (median and IQR against the number of poses, per method).

    Returns
    -------
    list of Path
        The files written.
    """
    from ..methods._compare import pyplot

    plt = pyplot()
    folder = Path(folder)
    written = [_plot_errors(plt, summary, folder / "errors.png", overwrite)]
    sizes: dict[str, list[int]] = {}
    for plan, n, _ in summary.values:
        sizes.setdefault(plan, []).append(n)
    if any(len(set(v)) > 1 for v in sizes.values()):
        written.append(_plot_poses(plt, summary, folder / "poses.png", overwrite))
    return written


def _save(plt, fig, path: Path, overwrite: bool) -> Path:
    from ..methods._compare import save_png

    fig.tight_layout()
    save_png(plt, fig, path, overwrite)
    return path


def _plot_errors(plt, summary: Summary, path: Path, overwrite: bool) -> Path:
    cells = list(dict.fromkeys((p, n) for p, n, _ in summary.values))
    methods = list(dict.fromkeys(m for _, _, m in summary.values))
    cols = min(3, len(cells))
    nrows = -(-len(cells) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(1.2 + cols * max(3.0, 0.9 * len(methods)), 3.4 * nrows),
                             squeeze=False, sharey=True)
    data = np.concatenate([v for v in summary.values.values() if len(v)] or [np.array([1.0])])
    data = data[np.isfinite(data) & (data > 0)]
    log = len(data) > 0 and data.max() > 30 * data.min()
    for ax, (plan, n) in zip(axes.flat, cells):
        vals = [summary.values[(plan, n, m)] for m in methods]
        ax.boxplot([v if len(v) else [np.nan] for v in vals], showfliers=True)
        ax.set_xticks(range(1, len(methods) + 1), methods, rotation=30, ha="right", fontsize=8)
        ax.set_title(f"{plan}, {n} poses", fontsize=9)
        if ax in axes[:, 0]:
            ax.set_ylabel(f"{summary.metric}")
        if log:
            ax.set_yscale("log")
    for ax in list(axes.flat)[len(cells):]:
        ax.set_visible(False)
    fig.suptitle(f"study {summary.name}: {summary.metric} over {summary.repetitions} repetitions", fontsize=10)
    return _save(plt, fig, path, overwrite)


def _plot_poses(plt, summary: Summary, path: Path, overwrite: bool) -> Path:
    methods = list(dict.fromkeys(m for _, _, m in summary.values))
    plans = list(dict.fromkeys(p for p, _, _ in summary.values))
    fig, axes = plt.subplots(1, len(methods), figsize=(0.6 + 3.6 * len(methods), 3.4), squeeze=False)
    for ax, m in zip(axes.flat, methods):
        for k, plan in enumerate(plans):
            pts = sorted((n, v) for (p, n, mm), v in summary.values.items() if p == plan and mm == m and len(v))
            if not pts:
                continue
            ns = [n for n, _ in pts]
            q = np.array([np.percentile(v, [25, 50, 75]) for _, v in pts])
            ax.plot(ns, q[:, 1], marker="o", color=f"C{k}", label=plan)
            ax.fill_between(ns, q[:, 0], q[:, 2], color=f"C{k}", alpha=0.2)
        ax.set_title(m, fontsize=9)
        ax.set_xlabel("calibration poses")
        ax.set_ylabel(f"{summary.metric} (median, IQR)")
        ax.legend(fontsize=7)
    fig.suptitle(f"study {summary.name}: error against the number of poses", fontsize=10)
    return _save(plt, fig, path, overwrite)
