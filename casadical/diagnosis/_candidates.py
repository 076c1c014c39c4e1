"""Candidate extensions of the model, and how they become the terms of a model."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from ..model import spec_of
from ..terms import CAUSES, Cause, ErrorTerm, SessionLocal, make_term, ordered
from ..terms._user import USER

#: the tiers of :attr:`Candidate.tier`, in the order a round tries them
TIERS = (1, 2, 3, 4, 5)


@dataclass(frozen=True)
class Candidate:
    """One possible cause of the remaining error.

    Attributes
    ----------
    cause : str
        Cause name of docs/formats.md section 4 (or ``nonlinear_stiffness``).
    joint, harmonic : int or None
        For ``thermal_expansion`` a joint means that link's own coefficient.
    source : str or None
        For backlash: ``torque`` or ``motion``.
    session : str or None
        A cause of this measurement session only (its own parameters,
        ``c2@B``), with data of several sessions; None: one value for every
        session.
    time_constant : float or None
        For a warm-up: its time constant (s).
    user : tuple of str
        For a cause of the user's own (a term of a terms file,
        :mod:`casadical.terms._user`; ``cause`` is its name): its parameters'
        names (``axis_wobble.es``, ...). Empty for the catalogue's causes.
    source_joint : int or None
        For a joint coupling: the joint whose reading ``joint``'s angle error
        follows (``joint_coupling[j:k]``, parameter ``cpl<j>_<k>``).
    direction : str or None
        For a linear axis' straightness: ``x`` or ``y``, across the axis in
        its frame (``straightness[j:x]``).
    angle : str or None
        For a linear axis' carriage angle: ``roll``, ``pitch`` or ``yaw``
        (``carriage_angle[j:pitch]``).
    law : str or None
        For a cause that follows a session covariate by a law (a mount
        compliance growing with a column's height): the column, and the law's
        degree after a colon where it is not 1 (``height_m``, ``height_m:2``;
        ``mount_compliance[height_m]``).
    definition : TermDefinition or None
        For a cause of the user's own: its term's definition, what its term
        is made of (candidates compare by the cause's name, not by it).
    """

    cause: str
    joint: int | None = None
    harmonic: int | None = None
    source: str | None = None
    session: str | None = None
    time_constant: float | None = None
    user: tuple[str, ...] = ()
    source_joint: int | None = None
    direction: str | None = None
    angle: str | None = None
    law: str | None = None
    definition: Any = field(default=None, compare=False, repr=False)

    def shared(self) -> "Candidate":
        """The same cause with one value for every session."""
        return replace(self, session=None)

    @property
    def carrier(self) -> "Candidate":
        """The candidate whose columns this one's are at per-pose factors (a session's own: at its session's
        poses; a law: at its polynomials of the column): the cause with one value for every session."""
        return replace(self, session=None, law=None)

    @property
    def kind(self) -> Cause:
        """The cause this candidate is of (its :class:`~casadical.terms._cause.Cause`; a user term's, whose name is
        never a catalogue cause's: ``USER``)."""
        return CAUSES.get(self.cause, USER)

    @property
    def scope(self) -> str | None:
        """``session`` for a cause of one session (or a drift or a warm-up, which belong to their session by
        nature)."""
        return "session" if self.session is not None or self.kind.of_session else None

    @property
    def tier(self) -> int:
        """The order in which a round tries causes; a tier is tried only when no cause of an earlier one is
        supported. 1: a physical cause of the robot with a parameter or two per joint (what a calibration
        is for, and what holds on other data); 2: a mount compliance, physical too but sharing its shape with
        a joint's own (the moment of vertical weights is the same about every point of a vertical line: the
        base's tilt about a horizontal axis is the shoulder's compliance where the shoulder stands above the
        base, as on the UR10, whose joint 2 compliance it took the place of, to be dropped as a stand-in at
        the end); 3: drift of the measurement session (it also stands for any structure that follows the
        order of the measurements); 4: a periodic error (flexible, many harmonics to choose from); 5: a joint
        coupling, last: one of n (n - 1) pairs, a straight line in another joint's reading that a joint's
        own cause, a gear error or a parallelogram's geometry also takes (tried earlier, on the closed-chain
        HH800 protocol it took the place of joint 3's encoder scale, and on the UR10 README job it took the
        place of the gear errors of the rounds that follow; tried last, it is named where none of these
        takes the residual). Each cause says its own (:attr:`~casadical.terms._cause.Cause.tier`)."""
        return self.kind.tier

    @property
    def family(self) -> "Candidate":
        """The cause with its setting scanned left out: a warm-up's time constants are one cause scanned over a
        grid (counted as tests, as harmonics are), and a round fits only its best-scoring one."""
        return self.kind.family(self)

    def label(self, short: bool = False) -> str:
        """``joint_periodic joint 2 harmonic 17``; short (reports): ``periodic j2 h17``."""
        kind = self.kind
        own = kind.label(self, short)
        if own is not None:
            return own
        parts = [kind.short_name(self) if short else self.cause]
        if self.joint is not None:
            word = kind.joint_word
            parts.append((word if word != "joint" else "j") + str(self.joint) if short else f"{word} {self.joint}")
        if self.source_joint is not None:
            parts[-1] += f"<-j{self.source_joint}" if short else f" from joint {self.source_joint}'s reading"
        if self.direction is not None:
            parts.append(self.direction if short else f"direction {self.direction}")
        if self.angle is not None:
            parts.append(self.angle)
        if self.harmonic is not None:
            parts.append(f"h{self.harmonic}" if short else f"harmonic {self.harmonic}")
        if self.source == "motion":
            parts.append("(motion)" if short else "(direction of motion)")
        if self.time_constant is not None:
            parts.append(f"{self.time_constant:.3g} s" if short else f"time constant {self.time_constant:.3g} s")
        if self.law is not None:
            column, _, degree = self.law.partition(":")
            parts.append((f"~{column}" if short else f"over {column}") + (f" (degree {degree})" if degree else ""))
        if self.session is not None:
            parts.append(f"@{self.session}" if short else f"in session {self.session}")
        return " ".join(parts)

    def to_dict(self) -> dict:
        d: dict = {"cause": self.cause}
        if self.joint is not None:
            d["joint"] = self.joint
        if self.harmonic is not None:
            d["harmonic"] = self.harmonic
        if self.source is not None:
            d["source"] = self.source
        if self.session is not None:
            d["session"] = self.session
        if self.time_constant is not None:
            d["time_constant_s"] = self.time_constant
        if self.user:
            d["user"] = True
        if self.source_joint is not None:
            d["source_joint"] = self.source_joint
        if self.direction is not None:
            d["direction"] = self.direction
        if self.angle is not None:
            d["angle"] = self.angle
        if self.law is not None:
            column, _, degree = self.law.partition(":")
            d["law"] = {"column": column, "degree": int(degree or 1)}
        return d

    def parameter_names(self) -> list[str]:
        """Names of the parameters this candidate adds to a model."""
        if self.session is not None:
            return [f"{n}@{self.session}" for n in self.shared().parameter_names()]
        return self.kind.parameter_names(self)


def compose_terms(candidates: list[Candidate], geometric: bool = True) -> list[ErrorTerm]:
    """The terms of a model holding every candidate (a cause's candidates of one scope in one term; a session's
    own in terms of that session, :class:`~casadical.terms.SessionLocal`), with the geometry free (``geometric``)
    or nominal. New terms at each call: a model binds its terms and sets their references."""
    terms = ([make_term("geometric")] if geometric else []) + _terms([c for c in candidates if c.session is None])
    for s in dict.fromkeys(c.session for c in candidates if c.session is not None):
        terms += [SessionLocal(t, s) for t in _terms([c.shared() for c in candidates if c.session == s])]
    return terms


def model_spec(candidates: list[Candidate], geometric: bool = True) -> str:
    """The specification of :func:`compose_terms`' model (a step's name in reports and the final model's)."""
    return spec_of(compose_terms(candidates, geometric), geometric)


def _terms(candidates: list[Candidate]) -> list[ErrorTerm]:
    """The terms of candidates of one scope, each cause's in its order (:attr:`~casadical.terms._cause.Cause.order`)."""
    return [term for cause in ordered("order", (USER,)) for term in cause.terms(candidates)]


def tell_apart(a: Candidate, b: Candidate) -> str:
    """What to measure to tell ``a`` from ``b`` (each cause says how to tell it from others,
    :attr:`~casadical.terms._cause.Cause.tell_apart`)."""
    if a.shared() == b.shared() and a.session != b.session:
        own = a.session or b.session
        how = a.kind.varies(a).format(j=a.joint)
        return (f"in a session other than {own}, {how}: the robot's shows in every session, session {own}'s own "
                "only in it")
    text = a.kind.tell_apart.get(b.cause) or b.kind.tell_apart.get(a.cause) or (
        "measure poses where the two candidates predict different errors (wider joint ranges, other loads or "
        "temperatures)")
    return text.format(j=a.joint if a.joint is not None else b.joint)


def shortlist(scored: list, tier: int, level: float, n: int) -> list:
    """The candidates of ``tier`` a round fits for real: up to ``n`` of those whose score passes ``level``
    (log10 p), best first, one of each :attr:`Candidate.family` (the ten time constants of a warm-up would
    otherwise fill the round and leave the drift they must be told from unfitted)."""
    out, seen = [], set()
    for sc in scored:
        c = sc.candidate
        if c.tier == tier and sc.log10_p < level and c.family not in seen:
            seen.add(c.family)
            out.append(sc)
    return out[:n]


def own_parameters(cand: Candidate, accepted: list[Candidate]) -> list[str]:
    """The parameters only ``cand`` brings (a progressive stiffness shares its linear part with the compliance)."""
    others = {n for a in accepted if a != cand for n in a.parameter_names()}
    return [n for n in cand.parameter_names() if n not in others]
