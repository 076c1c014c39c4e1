"""The model of a specification for a data set: covariate references from the data, a base pose per session.

Used by stage ``build_model`` (:mod:`._build`, :mod:`._further`) and by the
diagnosis, which builds the models it tries for the same data.
"""

from __future__ import annotations

from ..data._measurements import Measurements
from ..errors import InputError
from ..model._symbolic import Model, parse_spec
from ..robot import Robot
from ..terms import ErrorTerm, ReferencedTerm, SessionLocal, make_term
from ..terms._tool_points import named_points, with_tool_points


def set_references(terms: list[ErrorTerm], data: Measurements) -> None:
    """Terms driven by a covariate take its reference over the data (its mean; a warm-up's start) as their
    reference (a term of one session: over that session's poses); a term written over a range of a column, that
    range (:meth:`~casadical.terms._base.ErrorTerm.refer`)."""
    for t in terms:
        inner = t.inner if isinstance(t, SessionLocal) else t
        inner.refer(data)
        if isinstance(inner, ReferencedTerm):
            col = data.get(inner.reference_covariate)
            if col is not None and isinstance(t, SessionLocal):
                col = col[data.sessions == t.session_name] if data.sessions is not None else col[:0]
            if col is not None and len(col):
                t.t_ref = inner.reference_value(col)


def with_sessions(terms: list[ErrorTerm], data: Measurements, tools: bool | list[str] = False) -> list[ErrorTerm]:
    """``terms`` with a base pose per session (:class:`~casadical.terms._sessions.SessionFrames`) when ``data``
    holds several sessions; ``tools``: every session other than the first (True), or those named, has its own
    tool too."""
    names = data.session_names
    # a tool of several points (its rows name them)
    terms = with_tool_points([t for t in terms if t.name != "sessions"], data)
    if tools and named_points(data):
        raise InputError("a tool per session (--session-tool) and a tool column naming each row's tool point: "
                         "give each point its offset by name (the tool column) and leave out --session-tool, or "
                         "the other way round", file=data.path, column="tool")
    if len(names) < 2:
        if tools:
            raise InputError("a tool per session needs data of several sessions (several files, or a session "
                             "column)", file=data.path)
        return terms
    own = names[1:] if tools is True else list(tools or [])
    return terms + [make_term("sessions", names=names, tools=own)]


def model_for(robot: Robot, spec: str | list[ErrorTerm], data: Measurements, jit: bool | None = None,
              session_tools: bool | list[str] = False, user_terms=()) -> Model:
    """The model of ``spec`` for ``data``: terms driven by a covariate referenced to its mean there, and a base
    pose per session (``session_tools``: a tool too) when ``data`` holds several sessions; ``user_terms``: the
    definitions of the causes of one's own ``spec`` may name."""
    terms = parse_spec(spec, user_terms) if isinstance(spec, str) else spec
    set_references(terms, data)
    return Model(robot, with_sessions(terms, data, session_tools), jit=jit)
