"""The diagnosis in words: what it means for the robot, each finding in a few words, its size, what to do.

The reports (terminal summary, HTML page, JSON) open with one row per
finding: a short label, where it lives, its size in the final model (with
its relative standard error), its gain on the validation poses, whether it
is of the robot or of the measurement session, and one line saying what to
do. These functions make those cells from a :class:`~._report.Finding` and
the final model; they never compute anything the diagnosis did not decide.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np

from .._format import g3, gain_words, relative  # noqa: F401 (the reports' short forms, where they were)

if TYPE_CHECKING:
    from ..result import CalibrationResult
    from ._report import DiagnosisReport, Finding

#: the width prose is wrapped to in the terminal; tables are narrower than :data:`MAX_LINE`
WIDTH = 132
#: no line of the terminal output is longer than this
MAX_LINE = 200


def wrap(text: str, indent: str = "", first: str | None = None, width: int = WIDTH) -> list[str]:
    """``text`` as lines of at most ``width`` characters (``first`` prefixes the first line, ``indent`` the others).

    Long words without spaces (a model specification) are broken after ``+`` and ``,``; a word longer than a
    whole line, anywhere.
    """
    first = indent if first is None else first
    tokens: list[tuple[str, str]] = []           # (piece, what joins it to the one before)
    for w in text.split():
        pieces = re.split(r"(?<=[+,])(?=\S)", w) if len(w) > 40 else [w]
        room = max(width - len(indent), 20)
        pieces = [p[k:k + room] for p in pieces for k in range(0, len(p), room)]
        tokens += [(p, " " if k == 0 else "") for k, p in enumerate(pieces)]
    lines, line, started = [], first, False
    for piece, glue in tokens:
        add = (glue if started else "") + piece
        if started and len(line) + len(add) > width:
            lines.append(line)
            line = indent + piece
        else:
            line += add
        started = True
    lines.append(line)
    return [x.rstrip() for x in lines]


def wrap_spec(spec: str, indent: str = "", first: str = "", width: int = WIDTH) -> list[str]:
    """A model specification on lines of at most ``width`` characters, broken after ``+`` and ``,``."""
    return wrap(spec, indent, first, width)


def label(f: "Finding") -> str:
    """A finding in a few words: ``geometry``, ``compliance j2``, ``periodic j2 h17``, ``drift @B``,
    ``coupling j6<-j5``, ``mount compliance``, ``GP compensator``, ``unexplained j1``."""
    return f.candidate.kind.finding_label(f) or f.candidate.label(short=True)


def where(f: "Finding") -> str:
    """Where a finding lives: ``joint 2``, ``link 3``, ``measurement frame, session B``, ... (its cause says,
    :meth:`~casadical.terms._cause.Cause.where`)."""
    return f.candidate.kind.where(f.candidate, f)


def size(f: "Finding", final: "CalibrationResult") -> str:
    """The finding's size in the final model, with its relative standard error (its cause's words,
    :meth:`~casadical.terms._cause.Cause.size`, from the final values of its parameters)."""
    c = f.candidate
    own = c.kind.finding_size(f, final)
    if own is not None:
        return own
    names = c.parameter_names()
    if any(n not in final.parameters.names for n in names):
        return ""
    P = [final.parameters[n] for n in names]
    v = np.array([p.value for p in P])
    s = np.array([p.std for p in P])
    linear = c.joint is not None and final.model.robot.joints[c.joint - 1].prismatic
    return c.kind.size(c, v, s, P, linear)


def gain(f: "Finding") -> str:
    """Its gain on the validation poses, in words (``kept out`` for structure left out of the model)."""
    return gain_words(f.gain_mm) if f.in_model else "kept out"


def scope(f: "Finding") -> str:
    """``robot``, ``session``, or ``one session`` for a cause data of one session could not place; ``robot or
    session A?`` where the poses cannot tell the robot's from that session's own."""
    other = _other_scope(f)
    if other:
        return f"robot or session {f.candidate.session or other[0].get('session')}?"
    if f.scope:
        return f.scope
    return f.candidate.kind.scope_word or ("one session" if f.in_model else "-")


def action(f: "Finding", report: "DiagnosisReport") -> str:
    """What to do about a finding, in one line (the geometry's and what no cause explains: their cause says,
    :meth:`~casadical.terms._cause.Cause.action`)."""
    c = f.candidate
    other = _name(report.transfer.get("file", "")) if report.transfer else ""
    own = c.kind.action(f)
    if own is not None:
        return own
    scope = _other_scope(f)
    rivals = [a for a in f.ambiguous_with if a not in scope]
    amb = f"; ambiguous with {', '.join(_short(a) for a in rivals)} (see the evidence)" if rivals else ""
    if scope:
        own = c.session or scope[0].get("session")
        return (f"compensate with the full model in these sessions; the robot's or session {own}'s own? these poses "
                "cannot tell (plan-poses REPORT.json picks the poses that do)" + amb)
    if f.scope == "session":
        return "re-measure it in each session; it is never carried to other data (scope session)"
    if f.scope == "robot":
        return "compensate with the full model; it holds in other sessions (scope robot)" + amb
    verdict = (f.transfer or {}).get("verdict")
    if verdict == "transfers":
        return f"compensate with the full model; it holds on {other} too (transfers)" + amb
    if verdict == "mixed":
        return (f"compensate with the full model, with care: on {other} it helps one way only (mixed); check it "
                "in another session") + amb
    if verdict == "does not transfer":
        return (f"keep it to this session: on {other} the model does better without it (does not transfer)"
                + amb)
    if verdict == "no difference":
        return f"compensate with the full model; on {other} it makes no difference" + amb
    return "compensate with the full model; whether it holds in other sessions: --transfer OTHER.csv" + amb


def _other_scope(f: "Finding") -> list[dict]:
    """The same cause of another scope (the robot's, or one session's own) that the poses cannot tell from it."""
    c = f.candidate
    return [a for a in f.ambiguous_with if a.get("cause") == c.cause and a.get("joint") == c.joint
            and a.get("harmonic") == c.harmonic and a.get("source") == c.source
            and a.get("source_joint") == c.source_joint and a.get("direction") == c.direction
            and a.get("angle") == c.angle and a.get("session") != c.session]


def _short(a: dict) -> str:
    """A candidate of an ambiguity (its dict) in a few words."""
    from ._candidates import Candidate

    return Candidate(**{k: a[k] for k in ("cause", "joint", "harmonic", "source", "session", "source_joint",
                                          "direction", "angle") if k in a}).label(short=True)


def _name(path: str) -> str:
    return path.replace("\\", "/").rsplit("/", 1)[-1]


def table(header: list[str], rows: list[list[str]], indent: str = "  ", right: tuple[int, ...] = (),
          widest: dict[int, int] | None = None) -> list[str]:
    """A plain-text table, one string per row (the header first): columns as wide as their widest cell
    (``right``: right-aligned columns); ``widest``: column -> the most characters a cell of it takes on a line, a
    longer cell wrapped on lines of its own below, the row's other cells blank there (the row's string then holds
    several lines)."""
    widest = widest or {}
    cells = [[wrap(str(x), width=widest[k]) if k in widest else [str(x)] for k, x in enumerate(r)]
             for r in [header, *rows]]
    widths = [max(len(x) for r in cells for x in r[k]) for k in range(len(header))]

    def line(parts):
        return indent + "  ".join(x.rjust(w) if k in right else x.ljust(w)
                                  for k, (x, w) in enumerate(zip(parts, widths))).rstrip()
    return ["\n".join(line([c[i] if i < len(c) else "" for c in r]) for i in range(max(map(len, r))))
            for r in cells]
