"""Figures of the HTML reports as inline SVG, written directly: a fixed layout, no plotting library.

A :class:`Figure` is a grid of :class:`Axes`; each records what it shows
(points, lines, bars, cells, text) and :meth:`Figure.svg` lays the grid out
once and writes the ``<svg>`` element. Units are points (1/72 inch) as in
the figure's ``viewBox``; the element is ``width``pt wide, shown at 96 px per
inch and scaled down on narrow screens by the page's CSS.

The layout is computed, not measured: the margins are made from the tick
labels and axis labels with text widths estimated from the advance widths of
DejaVu Sans (the widest of the fonts the figures name), so every label fits
in any of them. Text stays text (selectable, checked in a browser). Every
point of a pose can carry an SVG ``<title>``: hovering it shows the pose's
CSV line and its error. No script, no id, no external reference: the page
stays self-contained and the same from run to run.
"""

from __future__ import annotations

import html
import math

import numpy as np

#: colour-blind safe (Paul Tol's "bright"): before / after and series
BEFORE, AFTER, CURVE = "#EE6677", "#4477AA", "#228833"
SERIES = ("#4477AA", "#EE6677", "#228833", "#CCBB44", "#66CCEE", "#AA3377", "#BBBBBB")
GRID, INK = "#e3e3e3", "#000"
FONT = "'DejaVu Sans', 'Liberation Sans', Arial, sans-serif"
#: font sizes (pt): tick labels, axis labels, legends, small text in the axes
TICK, LABEL, LEGEND, SMALL = 8.5, 9.5, 9.0, 8.0
TICK_LEN, PAD = 3.5, 3.0

#: colour maps as 17 evenly spaced stops (matplotlib's viridis and RdBu_r), interpolated linearly between them
VIRIDIS = ("#440154", "#48186a", "#472d7b", "#424086", "#3b528b", "#33638d", "#2c728e", "#26828e", "#21918c",
           "#1fa088", "#28ae80", "#3fbc73", "#5ec962", "#84d44b", "#addc30", "#d8e219", "#fde725")
RDBU = ("#053061", "#175290", "#2a71b2", "#3f8ec0", "#6bacd1", "#9bc9e0", "#c2ddec", "#e0ecf3", "#f7f6f6",
        "#fbe5d8", "#fbccb4", "#f5aa89", "#e48066", "#d05548", "#ba2832", "#930e26", "#67001f")

esc = html.escape

# --- text -------------------------------------------------------------------------------------------

#: advance widths of DejaVu Sans in em (rounded up); others 0.70
_WIDTH = {**dict.fromkeys("0123456789", 0.637), **dict.fromkeys(" .,:;'|!", 0.34), "i": 0.28, "l": 0.28, "j": 0.28,
          "f": 0.36, "t": 0.40, "r": 0.42, "(": 0.40, ")": 0.40, "[": 0.40, "]": 0.40, "-": 0.37, "/": 0.34,
          "\u2212": 0.84, "+": 0.84, "=": 0.84, "\u00b1": 0.84, "%": 0.95, "m": 0.98, "w": 0.82, "M": 0.87,
          "W": 0.99, "I": 0.30, "J": 0.30, **dict.fromkeys("abdeghnopqu", 0.64), **dict.fromkeys("ckvxyzs", 0.60)}


def text_width(text: str, size: float) -> float:
    """The width of ``text`` at font size ``size`` (pt), never less than DejaVu Sans gives."""
    return 1.02 * size * sum(_WIDTH.get(c, 0.70) for c in text)


def fmt(x: float) -> str:
    """A coordinate: two decimals at most, no trailing zeros."""
    s = f"{x:.2f}".rstrip("0").rstrip(".")
    return "0" if s == "-0" else s


def _text(x: float, y: float, s: str, size: float, anchor: str = "middle", rotate: float = 0, fill: str = INK,
          baseline: str = "") -> str:
    rot = f' transform="rotate({fmt(rotate)} {fmt(x)} {fmt(y)})"' if rotate else ""
    extra = f' dominant-baseline="{baseline}"' if baseline else ""
    col = f' fill="{fill}"' if fill != INK else ""
    return (f'<text x="{fmt(x)}" y="{fmt(y)}" font-size="{size:g}" text-anchor="{anchor}"{extra}{col}{rot}>'
            f"{esc(s)}</text>")


# --- ticks ------------------------------------------------------------------------------------------


def nice_ticks(lo: float, hi: float, n: int = 7, least: int = 4) -> list[float]:
    """Ticks at round steps (1, 2, 2.5, 5 times a power of ten) inside [lo, hi]: the most that are at most
    ``n + 1``, and at least ``least`` when a finer round step gives them."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    e = math.floor(math.log10((hi - lo) / max(n, 1))) - 1
    finer: list[float] | None = None
    for step in (m * 10.0 ** k for k in range(e, e + 5) for m in (1, 2, 2.5, 5)):
        first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
        ticks = [i * step for i in range(first, last + 1)]
        if len(ticks) <= n + 1:
            return finer if len(ticks) < least and finer is not None else ticks
        finer = ticks
    return finer or []


def tick_labels(ticks: list[float]) -> list[str]:
    """Tick labels with the decimals their step needs, a true minus sign."""
    if not ticks:
        return []
    step = min((abs(b - a) for a, b in zip(ticks, ticks[1:])), default=abs(ticks[0]) or 1.0)
    d = 0
    while d < 8 and abs(round(step, d) - step) > 1e-9 * max(step, 1e-300):
        d += 1
    big = max(abs(t) for t in ticks)
    out = []
    for t in ticks:
        s = f"{t:.{d}f}" if big < 1e6 else f"{t:.3g}"
        if float(s) == 0:
            s = s.lstrip("-")
        out.append(s.replace("-", "\u2212"))
    return out


def bands(lo: float, hi: float, n: int = 12) -> np.ndarray:
    """Bounds of about ``n`` bands at round values covering [lo, hi] (as matplotlib's filled contours)."""
    t = nice_ticks(lo, hi, n, 2)
    step = t[1] - t[0] if len(t) > 1 else (hi - lo) or 1.0
    first, last = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
    return np.arange(first, max(last, first + 1) + 1) * step


def colour_at(stops: tuple[str, ...], t: float) -> str:
    """The colour of a map of evenly spaced ``stops`` at ``t`` in [0, 1] (clipped; NaN: white)."""
    if not math.isfinite(t):
        return "#ffffff"
    t = min(max(t, 0.0), 1.0) * (len(stops) - 1)
    i = min(int(t), len(stops) - 2)
    f = t - i
    a, b = (tuple(int(s[k:k + 2], 16) for k in (1, 3, 5)) for s in (stops[i], stops[i + 1]))
    return "#" + "".join(f"{round(x + f * (y - x)):02x}" for x, y in zip(a, b))


# --- axes -------------------------------------------------------------------------------------------


class Axes:
    """One panel: what it shows, recorded now and drawn by :meth:`Figure.svg` once the layout is known."""

    def __init__(self):
        self.items: list[tuple] = []
        self.xlabel = self.ylabel = ""
        self.xlim: tuple[float, float] | None = None
        self.ylim: tuple[float, float] | None = None
        self.xmargin, self.ymargin = 0.03, 0.06
        self.xticks_n, self.yticks_n, self.xleast, self.yleast = 7, 7, 4, 4
        self.categories: list[str] | None = None      # x tick labels at 0, 1, ...
        self.rotate = 0.0                              # of the x tick labels (deg, counter-clockwise)
        self.row_names: list[str] | None = None       # a heat map's labelled rows and columns
        self.grid_x = self.grid_y = True
        self.legend = False
        self.visible = True
        self.show_xticklabels = self.show_yticklabels = True
        self.tick_size = TICK
        self.corner = ""                               # a label in the top right corner
        self.colorbar: tuple | None = None             # (stops, vmin, vmax, label)
        self.square = False
        self.zero_floor = False                        # bars and histograms stand on y = 0

    # -- what it shows

    def points(self, x, y, colour: str, r: float = 1.3, alpha: float = 1.0, label: str = "",
               titles: list[str] | None = None, edge: str = "", legend_r: float | None = None) -> None:
        """A point per (x, y) (NaN: none), each with its hover title if given."""
        self.items.append(("points", np.asarray(x, float), np.asarray(y, float), colour, r, alpha, titles, edge))
        if label:
            self.items.append(("key", "point", colour, label, legend_r or max(r, 2.5), edge, alpha))

    def line(self, x, y, colour: str, width: float = 1.6, dash: str = "", marker: str = "", ms: float = 4.0,
             label: str = "", titles: list[str] | None = None) -> None:
        """A polyline through (x, y), broken at NaN; ``marker`` 'o' or 's' at each point."""
        self.items.append(("line", np.asarray(x, float), np.asarray(y, float), colour, width, dash, marker, ms,
                           titles))
        if label:
            self.items.append(("key", "line", colour, label, width, dash, marker, ms))

    def step(self, x, y, colour: str, label: str = "") -> None:
        """A step line, each value held up to the next x (matplotlib's ``where='post'``)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if len(x):
            self.line(np.repeat(x, 2)[1:], np.repeat(y, 2)[:-1], colour, label=label)

    def bars(self, left, width, height, colour: str, alpha: float = 1.0, label: str = "",
             titles: list[str] | None = None, values: list[str] | None = None) -> None:
        """Bars from y = 0; ``values``: a label above each bar."""
        self.zero_floor = True
        self.items.append(("bars", np.asarray(left, float), np.asarray(width, float), np.asarray(height, float),
                           colour, alpha, titles, values))
        if label:
            self.items.append(("key", "box", colour, label, alpha))

    def hline(self, y: float, colour: str = "#555", width: float = 0.8) -> None:
        self.items.append(("hline", float(y), colour, width))

    def vline(self, x: float, colour: str = "#888", width: float = 0.9, dash: str = "1,2") -> None:
        self.items.append(("vline", float(x), colour, width, dash))

    def cells(self, x_edges, y_edges, values, stops: tuple[str, ...], vmin: float, vmax: float,
              levels=None, titles=None) -> None:
        """A heat map: cell (i, j) between x_edges[j:j+2] and y_edges[i:i+2] coloured by values[i, j] on a map
        from ``vmin`` to ``vmax``; ``levels``: the bounds of bands of one colour each (as filled contours)."""
        self.items.append(("cells", np.asarray(x_edges, float), np.asarray(y_edges, float),
                           np.asarray(values, float), stops, vmin, vmax, levels, titles))
        self.xmargin = self.ymargin = 0.0
        self.grid_x = self.grid_y = False

    # -- limits and ticks

    def _data(self, axis: int) -> list[np.ndarray]:
        out = []
        for it in self.items:
            kind = it[0]
            if kind in ("points", "line"):
                out.append(it[1 + axis])
            elif kind == "bars":
                out.append(np.concatenate([it[1], it[1] + it[2]]) if axis == 0 else np.append(it[3], 0.0))
            elif kind == "cells":
                out.append(it[1 + axis])
            elif kind == "hline" and axis == 1 or kind == "vline" and axis == 0:
                out.append(np.array([it[1]]))
        return out

    def data_range(self, axis: int) -> tuple[float, float]:
        v = [a[np.isfinite(a)] for a in self._data(axis)]
        v = [a for a in v if a.size]
        if not v:
            return 0.0, 1.0
        return float(min(a.min() for a in v)), float(max(a.max() for a in v))

    def limits(self, axis: int, lo: float, hi: float) -> tuple[float, float]:
        """Limits from a data range: the range plus the margin (bars keep y = 0 as their floor)."""
        fixed = self.xlim if axis == 0 else self.ylim
        if fixed is not None:
            return fixed
        if self.categories is not None and axis == 0:
            lo, hi = min(lo, 0.0), max(hi, len(self.categories) - 1.0)
        if hi <= lo:
            d = abs(lo) * 0.05 or 0.5
            lo, hi = lo - d, hi + d
        m = (hi - lo) * (self.xmargin if axis == 0 else self.ymargin)
        a, b = lo - m, hi + m
        if axis == 1 and self.zero_floor and lo >= 0:
            a = 0.0
        return a, b


def figure(width_in: float = 6.4, height_in: float = 3.4, nrows: int = 1, ncols: int = 1,
           sharex: bool | str = False, sharey: bool | str = False) -> tuple[Figure, list[list[Axes]]]:
    """A figure and its grid of axes (``ax[row][col]``); ``sharex``/``sharey``: True (all) or 'row' / 'col'."""
    fig = Figure(width_in, height_in, nrows, ncols, sharex, sharey)
    for r, row in enumerate(fig.axes):     # shared axes: tick labels on the outer panels only
        for c, a in enumerate(row):
            a.show_xticklabels = not (sharex in (True, "all", "col") and r < nrows - 1)
            a.show_yticklabels = not (sharey in (True, "all", "row") and c > 0)
    return fig, fig.axes


class Figure:
    """A grid of :class:`Axes` of a given size (inches), written as one ``<svg>`` by :meth:`svg`."""

    def __init__(self, width_in: float, height_in: float, nrows: int = 1, ncols: int = 1,
                 sharex: bool | str = False, sharey: bool | str = False):
        self.W, self.H = 72.0 * width_in, 72.0 * height_in
        self.nrows, self.ncols = nrows, ncols
        self.axes = [[Axes() for _ in range(ncols)] for _ in range(nrows)]
        self.sharex, self.sharey = sharex, sharey

    # -- layout

    def _shared(self, share, r: int, c: int) -> list[Axes]:
        if share is True or share == "all":
            return [a for row in self.axes for a in row]
        if share == "row":
            return list(self.axes[r])
        if share == "col":
            return [row[c] for row in self.axes]
        return [self.axes[r][c]]

    def _ticks(self):
        """Limits, ticks and tick labels of every axes: {id: (xlim, ylim, xt, yt, xl, yl)}."""
        out = {}
        for r, row in enumerate(self.axes):
            for c, a in enumerate(row):
                lims = []
                for axis, share in ((0, self.sharex), (1, self.sharey)):
                    group = [g for g in self._shared(share, r, c) if g.visible] or [a]
                    ranges = [g.data_range(axis) for g in group]
                    lims.append(a.limits(axis, min(x for x, _ in ranges), max(x for _, x in ranges)))
                (x0, x1), (y0, y1) = lims
                if a.categories is not None:
                    xt, xl = list(range(len(a.categories))), list(a.categories)
                elif a.row_names is not None:
                    xt = [k + 0.5 for k in range(len(a.row_names))]
                    xl = list(a.row_names)
                else:
                    xt = [t for t in nice_ticks(x0, x1, a.xticks_n, a.xleast)]
                    xl = tick_labels(xt)
                if a.row_names is not None:
                    yt, yl = [k + 0.5 for k in range(len(a.row_names))], list(a.row_names)
                else:
                    yt = nice_ticks(y0, y1, a.yticks_n, a.yleast)
                    yl = tick_labels(yt)
                out[id(a)] = ((x0, x1), (y0, y1), xt, yt, xl, yl)
        return out

    def _legend_rows(self, a: Axes, x0: float) -> list[list[tuple]]:
        """The legend's entries in rows that fit between ``x0`` and the figure's right edge."""
        keys = [it for it in a.items if it[0] == "key"]
        rows: list[list[tuple]] = [[]]
        x = x0
        for k in keys:
            w = 18 + 4 + text_width(k[3], LEGEND)
            if rows[-1] and x + w > self.W - 4:
                rows.append([])
                x = x0
            rows[-1].append((x, k))
            x += w + 12
        return rows if keys else []

    def svg(self, label: str) -> str:
        """The figure as an ``<svg>`` element (``label``: its accessible name)."""
        for _ in range(6):       # fewer ticks where their labels would not fit side by side, then again
            t = self._ticks()
            left, right, top, bottom, aw, ah, legends = self._layout(t)
            if not self._thin(t, aw, ah):
                break
        out = [f'<svg xmlns="http://www.w3.org/2000/svg" role="img" aria-label="{esc(label)}" '
               f'width="{fmt(self.W)}pt" height="{fmt(self.H)}pt" viewBox="0 0 {fmt(self.W)} {fmt(self.H)}" '
               f'font-family="{FONT}">',
               f'<rect width="{fmt(self.W)}" height="{fmt(self.H)}" fill="#fff"/>']
        for r in range(self.nrows):
            for c in range(self.ncols):
                a = self.axes[r][c]
                if not a.visible:
                    continue
                x = sum(left[:c + 1]) + sum(right[:c]) + c * aw
                y = sum(top[:r + 1]) + sum(bottom[:r]) + r * ah
                w, h = aw, ah
                if a.square:
                    side = min(w, h)
                    x, y, w, h = x + (w - side) / 2, y, side, side
                out.append(self._draw(a, (x, y, w, h), t[id(a)], legends.get(id(a), [])))
        out.append("</svg>")
        return "".join(out)

    def _thin(self, t, aw: float, ah: float) -> bool:
        """Fewer ticks on each numeric axis whose labels do not fit along it (the whole row or column when
        shared); True if any changed."""
        changed = False
        for r, row in enumerate(self.axes):
            for c, a in enumerate(row):
                if not a.visible or a.categories is not None or a.row_names is not None:
                    continue
                _, _, xt, yt, xl, yl = t[id(a)]
                w = aw * (1.0 if not a.square else min(aw, ah) / aw)
                if a.show_xticklabels and len(xl) > 2 and \
                        sum(text_width(s, a.tick_size) for s in xl) + 6 * len(xl) > w and a.xticks_n > 2:
                    for g in self._shared(self.sharex, r, c):
                        g.xticks_n, g.xleast = max(2, len(xl) - 2), 2
                    changed = True
                if len(yl) > 2 and len(yl) * a.tick_size * 1.5 > ah and a.yticks_n > 2:
                    for g in self._shared(self.sharey, r, c):
                        g.yticks_n, g.yleast = max(2, len(yl) - 2), 2
                    changed = True
        return changed

    def _layout(self, t):
        """Margins of each column (left, right) and row (top, bottom), the axes' size, the legends' rows."""
        R, C = self.nrows, self.ncols
        vis = [[a.visible for a in row] for row in self.axes]
        line_h = 1.25
        # the margins of each column (left, right) and each row (top, bottom)
        left = [0.0] * C
        right = [6.0] * C
        top = [7.0] * R
        bottom = [4.0] * R
        for r in range(R):
            for c in range(C):
                a = self.axes[r][c]
                if not vis[r][c]:
                    continue
                _, _, xt, yt, xl, yl = t[id(a)]
                ts = a.tick_size
                yw = max((text_width(s, ts) for s in yl), default=0.0) if a.show_yticklabels else 0.0
                ylab = len(a.ylabel.split("\n")) * LABEL * line_h + 2 if a.ylabel else 0.0
                left[c] = max(left[c], 4 + ylab + yw + PAD + TICK_LEN)
                if a.colorbar is not None:
                    vmin, vmax = a.colorbar[1:3]
                    cw = max((text_width(s, TICK) for s in tick_labels(nice_ticks(vmin, vmax, 6, 4))), default=0)
                    right[c] = max(right[c], 10 + 11 + TICK_LEN + PAD + cw + 4 + LABEL * line_h + 4)
                if xl and a.show_xticklabels:
                    if a.rotate:
                        s, co = math.sin(math.radians(a.rotate)), math.cos(math.radians(a.rotate))
                        ww = max(text_width(s_, ts) for s_ in xl)
                        xh = ww * s + ts * co + TICK_LEN + PAD
                        left[c] = max(left[c], text_width(xl[0], ts) * co + 6)
                    else:
                        xh = ts * line_h + TICK_LEN + PAD
                        right[c] = max(right[c], text_width(xl[-1], ts) / 2 + 2)
                else:
                    xh = TICK_LEN
                xlab = LABEL * line_h + 3 if a.xlabel else 0.0
                bottom[r] = max(bottom[r], xh + xlab + 2)
        aw = (self.W - sum(left) - sum(right)) / C
        # legends above their axes (rows wrapping at the right edge)
        legends = {}
        for r in range(R):
            for c in range(C):
                a = self.axes[r][c]
                if a.legend and vis[r][c]:
                    rows = self._legend_rows(a, sum(left[:c + 1]) + sum(right[:c]) + c * aw)
                    legends[id(a)] = rows
                    top[r] = max(top[r], len(rows) * LEGEND * 1.5 + 4)
        ah = (self.H - sum(top) - sum(bottom)) / R
        return left, right, top, bottom, aw, ah, legends

    # -- drawing

    @staticmethod
    def _draw(a: Axes, box, ticks, legend) -> str:
        X, Y, W, H = box
        (x0, x1), (y0, y1), xt, yt, xl, yl = ticks
        flip = a.row_names is not None              # a heat map: row 0 at the top

        def px(v):
            return X + (np.asarray(v, float) - x0) / (x1 - x0) * W

        def py(v):
            f = (np.asarray(v, float) - y0) / (y1 - y0)
            return Y + (f if flip else 1 - f) * H

        out = ["<g>"]
        if a.grid_x or a.grid_y:
            g = []
            if a.grid_x:
                g += [f"M{fmt(float(px(v)))} {fmt(Y)}V{fmt(Y + H)}" for v in xt]
            if a.grid_y:
                g += [f"M{fmt(X)} {fmt(float(py(v)))}H{fmt(X + W)}" for v in yt]
            out.append(f'<path d="{"".join(g)}" stroke="{GRID}" stroke-width="0.7" fill="none"/>')
        for it in a.items:
            kind = it[0]
            if kind == "cells":
                out.append(_cells(it, px, py))
            elif kind == "bars":
                out.append(_bars(it, px, py))
            elif kind == "line":
                out.append(_line(it, px, py))
            elif kind == "points":
                out.append(_points(it, px, py))
            elif kind == "hline":
                out.append(f'<path d="M{fmt(X)} {fmt(float(py(it[1])))}H{fmt(X + W)}" stroke="{it[2]}" '
                           f'stroke-width="{it[3]:g}"/>')
            elif kind == "vline":
                out.append(f'<path d="M{fmt(float(px(it[1])))} {fmt(Y)}V{fmt(Y + H)}" stroke="{it[2]}" '
                           f'stroke-width="{it[3]:g}" stroke-dasharray="{it[4]}"/>')
        # spines, ticks, tick labels
        if a.row_names is None:
            out.append(f'<path d="M{fmt(X)} {fmt(Y)}V{fmt(Y + H)}H{fmt(X + W)}" stroke="{INK}" stroke-width="0.8" '
                       'fill="none"/>')
        tk = [f"M{fmt(float(px(v)))} {fmt(Y + H)}v{TICK_LEN}" for v in xt]
        tk += [f"M{fmt(X)} {fmt(float(py(v)))}h{-TICK_LEN}" for v in yt]
        if a.row_names is None:
            out.append(f'<path d="{"".join(tk)}" stroke="{INK}" stroke-width="0.8"/>')
        base = Y + H + TICK_LEN + PAD
        if a.show_xticklabels:
            for v, s in zip(xt, xl):
                xv = float(px(v))
                if a.rotate:
                    out.append(_text(xv, base, s, a.tick_size, "end", -a.rotate, baseline="central"))
                else:
                    out.append(_text(xv, base + 0.78 * a.tick_size, s, a.tick_size))
        for v, s in zip(yt, yl if a.show_yticklabels else []):
            out.append(_text(X - TICK_LEN - PAD, float(py(v)) + 0.34 * a.tick_size, s, a.tick_size, "end"))
        # axis labels
        if a.xlabel:
            if a.show_xticklabels and xl:
                if a.rotate:
                    s, co = math.sin(math.radians(a.rotate)), math.cos(math.radians(a.rotate))
                    drop = max(text_width(s_, a.tick_size) for s_ in xl) * s + a.tick_size * co
                else:
                    drop = a.tick_size * 1.25
            else:
                drop = 0.0
            out.append(_text(X + W / 2, base + drop + LABEL * 1.0, a.xlabel, LABEL))
        if a.ylabel:
            lines = a.ylabel.split("\n")
            yw = max((text_width(s, a.tick_size) for s in yl), default=0.0) if a.show_yticklabels else 0.0
            xc = X - TICK_LEN - PAD - yw - 3 - (len(lines) - 1) * LABEL * 1.25 - 0.22 * LABEL
            for k, s in enumerate(lines):
                xk = xc + k * LABEL * 1.25
                out.append(_text(xk, Y + H / 2, s, LABEL, rotate=-90))
        if a.corner:
            w = text_width(a.corner, LEGEND)
            out.append(f'<rect x="{fmt(X + W - w - 6)}" y="{fmt(Y + 3)}" width="{fmt(w + 4)}" '
                       f'height="{fmt(LEGEND * 1.3)}" fill="#fff"/>')
            out.append(_text(X + W - 4, Y + 3 + LEGEND * 1.0, a.corner, LEGEND, "end"))
        if a.colorbar is not None:
            out.append(_colorbar(a.colorbar, X + W + 10, Y, H))
        for k, row in enumerate(legend):
            yk = Y - 4 - (len(legend) - k - 0.5) * LEGEND * 1.5
            for xk, key in row:
                out.append(_key(xk, yk, key))
        out.append("</g>")
        return "".join(out)


# --- what an axes holds, as SVG ----------------------------------------------------------------------


def _titled(shape: str, title: str | None) -> str:
    return f"{shape[:-2]}><title>{esc(title)}</title></{shape[1:shape.index(' ')]}>" if title else shape


def _points(it, px, py) -> str:
    _, x, y, colour, r, alpha, titles, edge = it
    ok = np.isfinite(x) & np.isfinite(y)
    xs, ys = px(x), py(y)
    op = f' fill-opacity="{alpha:g}"' if alpha < 1 else ""
    st = f' stroke="{edge}" stroke-width="0.5"' if edge else ""
    out = [f'<g fill="{colour}"{op}{st}>']
    rr = f"{r:g}"
    for k in np.flatnonzero(ok):
        c = f'<circle cx="{fmt(xs[k])}" cy="{fmt(ys[k])}" r="{rr}"/>'
        out.append(_titled(c, titles[k] if titles is not None else None))
    out.append("</g>")
    return "".join(out)


def _line(it, px, py) -> str:
    _, x, y, colour, width, dash, marker, ms, titles = it
    ok = np.isfinite(x) & np.isfinite(y)
    xs, ys = px(x), py(y)
    d, pen = [], False
    for k in range(len(x)):
        if ok[k]:
            d.append(f"{'L' if pen else 'M'}{fmt(xs[k])} {fmt(ys[k])}")
        pen = bool(ok[k])
    da = f' stroke-dasharray="{dash}"' if dash else ""
    out = [f'<path d="{"".join(d)}" stroke="{colour}" stroke-width="{width:g}" fill="none" '
           f'stroke-linejoin="round"{da}/>']
    if marker:
        out.append(f'<g fill="{colour}">')
        for k in np.flatnonzero(ok):
            if marker == "s":
                s = f'<rect x="{fmt(xs[k] - ms / 2)}" y="{fmt(ys[k] - ms / 2)}" width="{ms:g}" height="{ms:g}"/>'
            else:
                s = f'<circle cx="{fmt(xs[k])}" cy="{fmt(ys[k])}" r="{ms / 2:g}"/>'
            out.append(_titled(s, titles[k] if titles is not None else None))
        out.append("</g>")
    return "".join(out)


def _bars(it, px, py) -> str:
    _, left, width, height, colour, alpha, titles, values = it
    op = f' fill-opacity="{alpha:g}"' if alpha < 1 else ""
    out = [f'<g fill="{colour}"{op}>']
    zero = float(py(0.0))
    for k in range(len(left)):
        xa, xb, top = float(px(left[k])), float(px(left[k] + width[k])), float(py(height[k]))
        s = (f'<rect x="{fmt(xa)}" y="{fmt(min(top, zero))}" width="{fmt(xb - xa)}" '
             f'height="{fmt(abs(zero - top))}"/>')
        out.append(_titled(s, titles[k] if titles is not None else None))
    out.append("</g>")
    for k, v in enumerate(values or []):
        xa, xb, top = float(px(left[k])), float(px(left[k] + width[k])), float(py(height[k]))
        out.append(_text((xa + xb) / 2, top - 2.5, v, SMALL))
    return "".join(out)


def _cells(it, px, py) -> str:
    _, xe, ye, v, stops, vmin, vmax, levels, titles = it
    if levels is not None:           # bands of one colour each, coloured at their middle
        nb = len(levels) - 1
        f = (np.clip(np.searchsorted(levels, v, side="right") - 1, 0, nb - 1) + 0.5) / nb
    else:
        f = (v - vmin) / ((vmax - vmin) or 1.0)
    xs, ys = px(xe), py(ye)
    # colours of 256 steps of the map (a banded map's bands fall on their middles exactly enough)
    table = [colour_at(stops, k / 255) for k in range(256)]
    index = np.where(np.isfinite(f), np.rint(np.clip(f, 0, 1) * 255), -1).astype(int)
    out = ['<g shape-rendering="crispEdges">']
    paths: dict[str, list[str]] = {}           # without titles: one path a colour, a run of cells a rectangle
    for i in range(v.shape[0]):
        ya, yb = sorted((float(ys[i]), float(ys[i + 1])))
        cols = ["#ffffff" if k < 0 else table[k] for k in index[i]]
        j = 0
        while j < v.shape[1]:
            k = j + 1
            while titles is None and k < v.shape[1] and cols[k] == cols[j]:
                k += 1
            xa, xb = sorted((float(xs[j]), float(xs[k])))
            w, h = fmt(xb - xa + 0.3), fmt(yb - ya + 0.3)
            if titles is None:
                paths.setdefault(cols[j], []).append(f"M{fmt(xa)} {fmt(ya)}h{w}v{h}h-{w}z")
            else:
                out.append(_titled(f'<rect x="{fmt(xa)}" y="{fmt(ya)}" width="{w}" height="{h}" fill="{cols[j]}"/>',
                                   titles[i][j]))
            j = k
    out += [f'<path d="{"".join(d)}" fill="{c}"/>' for c, d in paths.items()]
    out.append("</g>")
    return "".join(out)


def _colorbar(cb, x: float, y: float, h: float) -> str:
    stops, vmin, vmax, label = cb[:4]
    bands = cb[4] if len(cb) > 4 else None           # the bounds of a banded map's colours
    n = len(bands) - 1 if bands is not None else 64
    out = ['<g shape-rendering="crispEdges">']
    for k in range(n):
        a, b = (bands[k], bands[k + 1]) if bands is not None else (vmin + (vmax - vmin) * k / n,
                                                                   vmin + (vmax - vmin) * (k + 1) / n)
        ya, yb = (y + h * (1 - (v - vmin) / ((vmax - vmin) or 1.0)) for v in (b, a))
        out.append(f'<rect x="{fmt(x)}" y="{fmt(ya)}" width="11" height="{fmt(yb - ya + 0.3)}" '
                   f'fill="{colour_at(stops, (k + 0.5) / n)}"/>')
    out.append("</g>")
    ticks = nice_ticks(vmin, vmax, 6, 4)
    labels = tick_labels(ticks)
    d = []
    for tv, s in zip(ticks, labels):
        yv = y + h * (1 - (tv - vmin) / ((vmax - vmin) or 1.0))
        d.append(f"M{fmt(x + 11)} {fmt(yv)}h{TICK_LEN}")
        out.append(_text(x + 11 + TICK_LEN + PAD, yv + 0.34 * TICK, s, TICK, "start"))
    out.append(f'<path d="{"".join(d)}" stroke="{INK}" stroke-width="0.8"/>')
    out.append(f'<rect x="{fmt(x)}" y="{fmt(y)}" width="11" height="{fmt(h)}" fill="none" stroke="{INK}" '
               'stroke-width="0.8"/>')
    cw = max((text_width(s, TICK) for s in labels), default=0.0)
    out.append(_text(x + 11 + TICK_LEN + PAD + cw + 4 + 0.8 * LABEL, y + h / 2, label, LABEL, rotate=-90))
    return "".join(out)


def _key(x: float, y: float, key) -> str:
    kind, colour, label = key[1], key[2], key[3]
    if kind == "line":
        width, dash, marker, ms = key[4:]
        da = f' stroke-dasharray="{dash}"' if dash else ""
        s = (f'<path d="M{fmt(x)} {fmt(y)}h18" stroke="{colour}" stroke-width="{width:g}"{da}/>')
        if marker == "s":
            s += (f'<rect x="{fmt(x + 9 - ms / 2)}" y="{fmt(y - ms / 2)}" width="{ms:g}" height="{ms:g}" '
                  f'fill="{colour}"/>')
        elif marker:
            s += f'<circle cx="{fmt(x + 9)}" cy="{fmt(y)}" r="{ms / 2:g}" fill="{colour}"/>'
    elif kind == "box":
        op = f' fill-opacity="{key[4]:g}"' if key[4] < 1 else ""
        s = f'<rect x="{fmt(x)}" y="{fmt(y - 4.5)}" width="18" height="9" fill="{colour}"{op}/>'
    else:
        r, edge, alpha = key[4], key[5], key[6]
        st = f' stroke="{edge}" stroke-width="0.5"' if edge else ""
        op = f' fill-opacity="{max(alpha, 0.8):g}"' if alpha < 0.8 else ""
        s = f'<circle cx="{fmt(x + 9)}" cy="{fmt(y)}" r="{r:g}" fill="{colour}"{st}{op}/>'
    return s + _text(x + 22, y + 0.34 * LEGEND, label, LEGEND, "start")


def ecdf(ax: Axes, before, after, before_label: str, after_label: str) -> None:
    """Empirical cumulative distributions of position errors (mm) before and after, as step lines."""
    for values, label, colour in ((before, before_label, BEFORE), (after, after_label, AFTER)):
        v = np.sort(np.asarray(values, float))
        if len(v):
            ax.step(np.concatenate([[v[0]], v]), np.arange(len(v) + 1) / len(v), colour, label=label)
    ax.xlabel, ax.ylabel, ax.ylim = "position error (mm)", "share of poses with a smaller error", (0.0, 1.02)
