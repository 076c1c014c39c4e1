"""One self-contained HTML page: sections, tables, numbered figures, footnotes.

No script, no network: the CSS is inline and every figure is inline SVG
(written by :mod:`._svg`, a hover title on each pose's mark), so
the file opens anywhere, is mailed as one attachment and prints. Every
table sits in a scroll container, so a wide table scrolls on its own and
the page never does; figures scale down to the page width.
"""

from __future__ import annotations

import contextlib
import html
import math
import time
from dataclasses import dataclass, field
from typing import Callable

from ._figures import render
from ._svg import Figure

CSS = """
:root{--ink:#1d1d1f;--muted:#666;--line:#d6d6d6;--faint:#f4f5f7;--good:#1a7f37;--bad:#b42318}
*{box-sizing:border-box}
body{font:15px/1.5 system-ui,-apple-system,"Segoe UI","DejaVu Sans",sans-serif;color:var(--ink);
 max-width:1180px;margin:0 auto;padding:1.2em 1.6em 3em}
h1{font-size:1.6em;margin:.2em 0 .4em}h2{font-size:1.25em;margin:1.8em 0 .5em;border-bottom:1px solid var(--line)}
h3{font-size:1.05em;margin:1.4em 0 .3em}
p,li{max-width:75em;overflow-wrap:anywhere}
.lead{font-size:1.05em}
.muted,.note{color:var(--muted)}
.good{color:var(--good)}.bad{color:var(--bad)}
.scroll{max-width:100%;overflow-x:auto;margin:.5em 0 1em}
table{border-collapse:collapse;font-variant-numeric:tabular-nums;font-size:.9em}
th,td{border-bottom:1px solid var(--line);padding:.25em .6em;text-align:right;vertical-align:top;white-space:nowrap}
th{background:var(--faint);font-weight:600;white-space:normal;vertical-align:bottom}
td.t,th.t{text-align:left}
td.w,th.w{white-space:normal;min-width:16em;max-width:42em;text-align:left}
td.s,th.s{white-space:normal;text-align:left;min-width:6em}
tr.off td{color:var(--muted)}
tr.weak td{background:#fdf1dc}
tr.has-detail td{border-bottom:none}
tr.detail td{font-size:.92em;padding-top:0;max-width:none}
td small{font-size:.8em}
abbr[title]{text-decoration:underline dotted;cursor:help}
figure{margin:1em 0 1.4em;max-width:100%}
figure svg{display:block;max-width:100%;height:auto}
figcaption{font-size:.9em;color:var(--muted);max-width:75em}
dl.kv{display:grid;grid-template-columns:max-content 1fr;gap:.15em 1em;margin:.5em 0}
dl.kv dt{color:var(--muted)}dl.kv dd{margin:0}
ol.notes{font-size:.9em}
ol.notes li{overflow-wrap:anywhere}
code{font-size:.92em;overflow-wrap:anywhere}
details{margin:.3em 0 .6em;max-width:75em}summary{cursor:pointer;color:var(--muted)}
@media print{body{max-width:none;padding:0;font-size:11pt}.scroll{overflow:visible}
 figure,tr{break-inside:avoid}h2,h3{break-after:avoid}}
"""

esc = html.escape

#: more model specifications than this are folded (a click, or a link to one, opens them)
FOLD_FOOTNOTES = 12


class Raw(str):
    """HTML that is already escaped (a link, an abbreviation)."""


def content(x) -> str:
    """A table cell's HTML: :class:`Raw` as it is, anything else as escaped text."""
    return str(x) if isinstance(x, Raw) else esc(str(x))


@dataclass
class Page:
    """A report under construction; :meth:`html` gives the document.

    Parameters
    ----------
    title : str
    """

    title: str
    parts: list[str] = field(default_factory=list)
    footnotes: list[str] = field(default_factory=list)
    _figures: list[tuple] = field(default_factory=list)   # (index in parts, figure or maker, anchor, caption)

    def heading(self, text: str, level: int = 2, anchor: str | None = None) -> None:
        ident = f' id="{esc(anchor)}"' if anchor else ""
        self.parts.append(f"<h{level}{ident}>{esc(text)}</h{level}>")

    def para(self, html_text: str, cls: str = "") -> None:
        """A paragraph of HTML (escape what comes from data with :func:`esc`)."""
        self.parts.append(f"<p{f' class={cls!r}' if cls else ''}>{html_text}</p>")

    def items(self, entries: list[str], tag: str = "ul") -> None:
        """A list of HTML entries."""
        if entries:
            self.parts.append(f"<{tag}>" + "".join(f"<li>{e}</li>" for e in entries) + f"</{tag}>")

    def details(self, summary: str, text: str) -> None:
        """Text folded under a one-line summary (a click opens it)."""
        self.parts.append(f"<details><summary>{esc(summary)}</summary><p class='muted'>{esc(text)}</p></details>")

    @contextlib.contextmanager
    def folded(self, summary: str):
        """What is added inside the ``with`` block is folded under a one-line summary (a click opens it): the
        evidence a reader opens on demand takes no room on the page."""
        self.parts.append(f"<details><summary>{esc(summary)}</summary>")
        try:
            yield
        finally:
            self.parts.append("</details>")

    def pairs(self, entries: list[tuple[str, str]]) -> None:
        """Label / HTML value pairs, aligned."""
        self.parts.append('<dl class="kv">' + "".join(f"<dt>{esc(k)}</dt><dd>{v}</dd>" for k, v in entries)
                          + "</dl>")

    def table(self, header: list, rows: list[list], text_columns: tuple[int, ...] = (0,),
              wrap_columns: tuple[int, ...] = (), row_classes: list[str] | None = None,
              details: list[str] | None = None, soft_columns: tuple[int, ...] = ()) -> None:
        """A table in its own scroll container.

        Parameters
        ----------
        header : list
            Column titles (text or :class:`Raw`).
        rows : list of list
            Cells: text or :class:`Raw` HTML.
        text_columns : tuple of int
            Left-aligned columns (numbers are right-aligned).
        wrap_columns : tuple of int
            Long text that wraps (every other cell stays on one line).
        soft_columns : tuple of int
            Short text that may break over lines where the page is narrow
            (no minimum width: a table of them fits a narrow window).
        row_classes : list of str, optional
            A class per row (``off`` greys a row out).
        details : list of str, optional
            Text per row (may be empty) shown on a line of its own under the
            row, across every column but the first: long explanations that
            would make a column too wide.
        """
        def kind(k: int) -> str:
            return "w" if k in wrap_columns else "s" if k in soft_columns else ("t" if k in text_columns else "")

        out = ['<div class="scroll"><table>']
        out.append("<thead><tr>" + "".join(
            f"<th{_cls(kind(k))}>{content(h)}</th>" for k, h in enumerate(header)) + "</tr></thead><tbody>")
        for i, row in enumerate(rows):
            rc = row_classes[i] if row_classes else ""
            detail = details[i] if details else ""
            out.append(f"<tr{_cls(' '.join(filter(None, (rc, 'has-detail' if detail else ''))))}>"
                       + "".join(f"<td{_cls(kind(k))}>{content(x)}</td>" for k, x in enumerate(row)) + "</tr>")
            if detail:
                out.append(f"<tr{_cls(' '.join(filter(None, (rc, 'detail'))))}><td></td>"
                           f"<td class='w' colspan='{len(row) - 1}'>{esc(detail)}</td></tr>")
        out.append("</tbody></table></div>")
        self.parts.append("".join(out))

    def figure(self, fig: Figure | Callable[[], Figure], anchor: str, caption: str) -> Raw:
        """Add a numbered figure; returns a link to it for the text (``figure N``).

        ``fig``: a figure, or a function that makes it: then it is made only
        by :meth:`html`.
        """
        self._figures.append((len(self.parts), fig, anchor, caption))
        self.parts.append("")   # the figure, drawn by html()
        return self.ref(anchor, f"figure {len(self._figures)}")

    @staticmethod
    def ref(anchor: str, text: str) -> Raw:
        return Raw(f'<a href="#{esc(anchor)}">{esc(text)}</a>')

    def footnote(self, text: str) -> int:
        """Number of the footnote holding ``text`` (added once)."""
        if text not in self.footnotes:
            self.footnotes.append(text)
        return self.footnotes.index(text) + 1

    def html(self, progress: Callable[[str], None] | None = None) -> str:
        """The document; ``progress`` receives a line before and after the figures are drawn."""
        say = progress or (lambda _: None)
        if self._figures:
            say(f"html report: drawing {len(self._figures)} figures")
        t0 = time.perf_counter()
        svgs = render([(fig, anchor, caption) for _, fig, anchor, caption in self._figures])
        if self._figures:
            say(f"html report: figures drawn in {time.perf_counter() - t0:.1f} s")
        for n, ((i, _, anchor, caption), svg) in enumerate(zip(self._figures, svgs), start=1):
            self.parts[i] = (f'<figure id="{esc(anchor)}">{svg}<figcaption><b>Figure {n}.</b> {esc(caption)}'
                             "</figcaption></figure>")
        notes = ""
        if self.footnotes:
            items = ('<ol class="notes">' + "".join(f'<li id="fn{k}"><code>{esc(t)}</code></li>'
                                                  for k, t in enumerate(self.footnotes, 1)) + "</ol>")
            if len(self.footnotes) > FOLD_FOOTNOTES:   # a long legend opens on a click (or on a link to it)
                items = (f"<details><summary>The full specification behind each short label above "
                         f"({len(self.footnotes)} labels; a model whose specification is its label has none)"
                         f"</summary>{items}</details>")
            notes = '<h2 id="footnotes">Model specifications</h2>' + items
        return ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
                "<meta name='viewport' content='width=device-width, initial-scale=1'>"
                f"<title>{esc(self.title)}</title><style>{CSS}</style></head><body>\n"
                + "\n".join(self.parts) + notes + "\n</body></html>\n")


def _cls(c: str) -> str:
    return f' class="{c}"' if c else ""


def model_label(page: Page, short: str, spec: str) -> Raw:
    """A model's short label, its full specification on hover and as a numbered footnote (when they differ)."""
    if short == spec:
        return Raw(esc(spec))
    n = page.footnote(spec)
    return Raw(f'<abbr title="{esc(spec)}">{esc(short)}</abbr><sup><a href="#fn{n}">{n}</a></sup>')


# --- numbers in words -------------------------------------------------------------


def num(x: float | None, digits: int = 4) -> str:
    """A number for a table: fixed decimals, en dash when missing."""
    if x is None or not math.isfinite(x):
        return "\u2013"
    return f"{x:.{digits}f}"


def sig(x: float | None, digits: int = 4) -> str:
    """A number with ``digits`` significant digits (parameters of any size)."""
    if x is None or not math.isfinite(x):
        return "\u2013"
    return f"{x:.{digits}g}"


def gain(drop_mm: float | None, digits: int = 4, unit: str = " mm") -> Raw:
    """A drop of an error as a gain: ``0.0270 mm better`` (green) or ``0.0030 mm worse`` (red)."""
    if drop_mm is None or not math.isfinite(drop_mm):
        return Raw("\u2013")
    if round(drop_mm, digits) == 0:
        return Raw(f"no change ({abs(drop_mm):.{digits}f}{unit})")
    word, cls = ("better", "good") if drop_mm > 0 else ("worse", "bad")
    return Raw(f'<span class="{cls}">{abs(drop_mm):.{digits}f}{unit} {word}</span>')
