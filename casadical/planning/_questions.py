"""The open questions of a diagnosis report: what the data could not tell, as parameters of a model.

A diagnosis says honestly what it could not resolve (``diagnose --json``):

- **ambiguous** causes: a finding whose ``ambiguous_with`` lists another
  cause that explains the same residual on these poses (an encoder scale
  and a first harmonic over a narrow range). Model: the final model plus
  the other cause; the parameters asked about: both causes'; the test
  that tells them apart: the accepted cause's parameters, with the other
  in the model;
- **unexplained** structure the structure screen found (a finding with a
  ``term``: its flexible term as a cause of one's own, :mod:`casadical.diagnosis._structure`).
  Model: the final model plus that term; tested: its coefficients, at their
  fitted values;
- **unexplained** structure: significant structure that could not be named
  (``holds_up.structures``: a harmonic not resolved from its neighbours,
  a trend whose halves differ, ...). Model: the final model plus the
  structure's candidate and the alternatives it could not be told from
  (every harmonic of its band; for a trend, the first harmonic); tested:
  the candidate's own parameters;
- **scope**, the robot's or one session's own (data of several sessions):
  a finding whose ``ambiguous_with`` lists the same cause of another scope
  (``escale1`` and ``escale1@A``: session B's poses barely move joint 1,
  so they cannot say whether B has the scale error too), and an
  unexplained structure seen in one session (``holds_up.structures[]``
  whose candidate names a ``session``). Model: the final model plus the
  other scope's cause (a session's own term acts at its poses only, on top
  of the robot's); tested: for a finding, the accepted cause's parameters;
  for a structure, the robot's, at the values the session showed (its
  other sessions' poses would show it too). The poses that answer it are
  in another session: the candidates' ``session`` column, or
  ``plan-poses --session S``;
- **law**: a named cause that follows a session covariate by a law (a
  mount compliance growing with a column's height): does it hold at
  another value of the column? Model: the final model; tested: the law's
  parameters. The poses that answer it are those of another session, at a
  value of the column the data do not have: candidate poses with that
  column (``height_m``) in the candidates' file;
- **not significant**: a parameter of a named cause in the final model
  whose t-test does not reject zero. Model: the final model; tested: it.

Each question carries the size of the effect it tests (the fitted values),
so that a plan can say the chance of telling the alternatives apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from ..diagnosis._candidates import Candidate
from ..errors import InputError
from ..terms import CAUSES
from ..terms._definitions import by_name, definitions_from_list


@dataclass
class Question:
    """One open question of a report.

    Attributes
    ----------
    number : int
        1-based, in report order (``--question N``).
    kind : str
        ``ambiguous``, ``unexplained``, ``scope``, ``law`` or ``not significant``.
    text : str
        The question in words.
    extra : list of Candidate
        Causes added to the final model for this question.
    interest : list of str
        Parameters the question asks about (the others are nuisance).
    tested : dict of str to float
        The parameters whose test answers the question and their sizes (SI,
        the report's fitted values): the chance of telling is the power of
        that test if these are the true values.
    level : float
        Significance level of that test.
    finding : int
        Index of the finding in the report's ``findings``.
    terms : tuple of TermDefinition
        The causes of one's own its model may name (the terms file's and the report's flexible terms).
    """

    number: int
    kind: str
    text: str
    extra: list[Candidate]
    interest: list[str]
    tested: dict[str, float]
    level: float
    finding: int
    notes: list[str] = field(default_factory=list)
    terms: tuple = ()

    def to_dict(self) -> dict:
        return {"number": self.number, "kind": self.kind, "text": self.text,
                "model_extra": [c.to_dict() for c in self.extra], "parameters": self.interest,
                "tested": self.tested, "level": self.level, "finding": self.finding}


#: a report's candidate fields -> Candidate's (the fields this casadical knows; others are left out)
_FIELDS = {f: f for f in ("cause", "joint", "harmonic", "source", "session", "source_joint", "direction",
                          "angle")} | {
    "time_constant_s": "time_constant", "law": "law"}


def _candidate(d: dict, terms: dict) -> Candidate:
    """The candidate of a report's entry ``d`` (``terms``: the user terms' definitions by name)."""
    known = Candidate.__dataclass_fields__
    d = dict(d)
    if isinstance(d.get("law"), dict):      # {"column": "height_m", "degree": 2}: "height_m:2"
        law = d["law"]
        d["law"] = str(law.get("column")) + (f":{law['degree']}" if law.get("degree", 1) != 1 else "")
    c = Candidate(**{v: d[k] for k, v in _FIELDS.items() if d.get(k) is not None and v in known})
    if d.get("user"):       # a cause of the user's own: its parameters from its definition (--terms FILE)
        definition = terms.get(c.cause)
        if definition is None:
            raise InputError(f"the report names {c.cause!r}, a cause of your own: give its terms file with --terms "
                             "FILE")
        c = replace(c, user=tuple(f"{c.cause}.{p}" for p in definition.parameter_names), definition=definition)
    return c


def _plannable(cause: str | None) -> bool:
    """A named cause of the catalogue whose parameters the poses can be planned for (not the geometry, nor the GP
    compensator, a warm-up or a cause of the user's own)."""
    kind = CAUSES.get(cause)
    return kind is not None and kind.named and kind.plannable


def _scope(c: Candidate) -> str:
    return f"session {c.session}'s own" if c.session is not None else "the robot's"


def open_questions(report: dict, final_values: dict[str, float], path: str = "", terms=()) -> list[Question]:
    """The open questions of a ``diagnose --json`` document, in report order.

    Parameters
    ----------
    report : dict
        The parsed REPORT.json.
    final_values : dict of str to float
        The final model's parameter values in SI units (the report's are in display units).
    path : str
        The report file, for messages.
    terms : iterable of TermDefinition
        The causes of one's own the report names (its terms file's); the flexible terms of the structure the
        report could not name it carries itself.

    Raises
    ------
    InputError
        A report written before the fields the questions need (``holds_up.structures[].candidate``,
        ``final.parameters[].significant``).
    """
    alpha = float((report.get("settings") or {}).get("alpha", 0.001))
    # a structure is screened among every joint's harmonics: the diagnosis' level, corrected for them (at most)
    settings = report.get("settings") or {}
    n_joints = len((report.get("robot_description") or {}).get("joint", [])) or 1
    scan_level = alpha / (n_joints * int(settings.get("max_harmonic", 60)))
    out: list[Question] = []
    seen: set = set()
    defs = by_name(terms)

    def add(kind, text, extra, interest, tested, level, k):
        key = (tuple(sorted(interest)), tuple(sorted(tested)))
        if key in seen:
            return
        seen.add(key)
        out.append(Question(len(out) + 1, kind, text, extra, interest, tested, level, k))

    for k, f in enumerate(report.get("findings", [])):
        if _plannable(f.get("cause")) and f.get("in_model", True):
            a = _candidate(f, defs)
            for b in f.get("ambiguous_with", []):
                other = _candidate(b, defs)
                # the level the diagnosis told them apart at (its round's corrected level)
                level = 10 ** b["test"]["log10_level"] if "test" in b else alpha
                names = a.parameter_names()
                if other.shared() == a.shared():
                    # the same cause, another scope: the poses could not tell the robot's from one session's
                    kind = "scope"
                    text = f"{a.shared().label(short=True)}: {_scope(a)} or {_scope(other)}?"
                else:
                    kind, text = "ambiguous", f"{a.label(short=True)} or {other.label(short=True)}?"
                add(kind, f"{text} (finding {k + 1})", [other],
                    names + [n for n in other.parameter_names() if n not in names],
                    {n: final_values[n] for n in names if n in final_values}, level, k)
            text = a.kind.open_question(a)
            if text is not None:
                names = a.parameter_names()
                add("law", f"{text} (finding {k + 1})", [], names,
                    {n: final_values[n] for n in names if n in final_values}, alpha, k)
        unexplained = f.get("cause") in CAUSES and CAUSES[f["cause"]].unexplained
        if unexplained and not f.get("in_model", False) and f.get("term"):
            # structure the structure screen found: its flexible term, a cause of one's own, is the question
            d = definitions_from_list([f["term"]], path, key=f"findings[{k}].term")[0]
            defs[d.name] = d
            user = tuple(f"{d.name}.{p}" for p in d.parameter_names)
            # structure of one session only: its term in that session (a term of one session, ``NAME@S``)
            own = Candidate(d.name, f.get("joint"), user=user, session=f.get("session"), definition=d)
            add("unexplained", f"{f.get('where', d.name)}: which form, and how large? (finding {k + 1})",
                [own], own.parameter_names(),
                {n: p.start for n, p in zip(own.parameter_names(), d.parameters)}, scan_level, k)
            continue
        if unexplained and not f.get("in_model", False):
            periodic_seen: set = set()
            for item in (f.get("holds_up") or {}).get("structures", []):
                if "candidate" not in item:
                    raise InputError("the report was written by an older casadical (its unexplained structure "
                                     "does not name its candidate): run diagnose again", file=path,
                                     column=f"findings[{k}].holds_up.structures")
                cand = _candidate(item["candidate"], defs)
                tested = {n: float(v) for n, v in (item.get("values") or {}).items()}
                where = f" in session {cand.session}" if cand.session is not None else ""
                if cand.harmonic is not None:
                    # the first is the strongest; the ones set aside after it are mostly its leakage into the
                    # neighbouring harmonics, which its band already asks about
                    if (cand.joint, cand.session) in periodic_seen:
                        continue
                    periodic_seen.add((cand.joint, cand.session))
                    lo, hi = item.get("band", [cand.harmonic, cand.harmonic])
                    extra = [replace(cand, harmonic=h) for h in range(lo, hi + 1)]
                    text = (f"joint {cand.joint}{where}: which harmonic, {lo}..{hi}?" if hi > lo else
                            f"joint {cand.joint}{where}: harmonic {cand.harmonic}, or something else?")
                elif cand.kind.question(cand) is not None:
                    extra, text = cand.kind.question(cand)
                else:
                    extra = [cand]
                    text = f"joint {cand.joint}{where}: {cand.label(short=True)}, or something else?"
                interest = [n for c in extra for n in c.parameter_names()]
                add("unexplained", text + f" (finding {k + 1})", extra, list(dict.fromkeys(interest)), tested,
                    scan_level, k)
                if cand.session is not None:
                    # seen in one session: is it the robot's (the other sessions' poses would show it too)?
                    shared = cand.shared()
                    names = cand.parameter_names() + shared.parameter_names()
                    add("scope", f"{shared.label(short=True)} seen in session {cand.session}: {_scope(cand)} or "
                        f"the robot's? (finding {k + 1})", [cand, shared], names,
                        {n: tested[m] for n, m in zip(shared.parameter_names(), cand.parameter_names())
                         if m in tested}, scan_level, k)
    params = (report.get("final") or {}).get("parameters", [])
    if params and not any("significant" in p for p in params):
        raise InputError("the report was written by an older casadical (its final parameters have no "
                         "significance): run diagnose again", file=path, column="final.parameters")
    named = {n: k for k, f in enumerate(report.get("findings", [])) if _plannable(f.get("cause"))
             and f.get("in_model", True) for n in _candidate(f, defs).parameter_names()}
    for p in params:
        name = p["name"]
        if p.get("significant") is False and name in named and name in final_values:
            t = p.get("t")
            add("not significant", f"{name}: not significant (t = {t:.2f}); how large is it? "
                f"(finding {named[name] + 1})" if t is not None else f"{name}: not significant",
                [], [name], {name: final_values[name]}, 0.05, named[name])
    for question in out:
        question.terms = tuple(defs.values())
    return out
