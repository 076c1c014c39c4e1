"""The cause registry: what each cause of the catalogue is, in one object defined in its term's module.

A *cause* is what a diagnosis names (docs/formats.md section 4: ``joint_compliance``, ``joint_periodic``, ...).
Its :class:`Cause` object holds everything the rest of the package needs to know of it: the parameters a
candidate of it adds and the error terms its candidates become (:meth:`Cause.terms`), its words (a short label,
where it acts, its size, how to tell it from another cause), its place in the search (tier, order among a
model's terms), whether each session may have its own, and which checks its acceptance asks. The diagnosis,
the reports, the planning and the physics rules ask these objects; none of them compares a cause's name. A term
module defines its cause beside its :class:`~._base.ErrorTerm` and registers it with :func:`register_cause`, so
that adding a cause means writing one module.

A :class:`Candidate`-like object (``casadical.diagnosis._candidates.Candidate``) carries the cause's name and its
arguments (``joint``, ``harmonic``, ``source``, ``session``, ``time_constant``, ``source_joint``, ``direction``,
``angle``, ``law``, ``user`` and a user term's ``definition``); the hooks below read them. No candidate becomes a
string the model parses back: its cause makes its terms.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

#: every registered cause by name (the catalogue's, the geometry and ``unexplained``); a user term's causes are
#: not registered here: :data:`USER` answers for them all (their definitions travel with the terms a command is
#: given, never in module state)
CAUSES: dict[str, "Cause"] = {}


class Cause:
    """One cause of position error, as the diagnosis and the reports know it.

    Subclass it in the term's module, set the class attributes that differ from the defaults, override the
    hooks whose answer depends on the candidate, and register one instance with :func:`register_cause`.
    """

    #: the cause's name in reports and JSON (docs/formats.md section 4)
    name: ClassVar[str] = ""
    #: a few words for tables (``compliance``, ``periodic``); the name with spaces if empty
    short: ClassVar[str] = ""
    #: the order in which a round tries causes: a tier is tried only when no cause of an earlier one is supported
    #: (casadical.diagnosis._candidates.Candidate.tier says why each is where it is)
    tier: ClassVar[int] = 1
    #: its place among the causes: in lists of them and where its terms stand in a model specification
    order: ClassVar[int] = 1000
    #: belongs to its measurement session by nature (a drift, a warm-up): its scope is ``session``
    of_session: ClassVar[bool] = False
    #: what of a measurement session the cause is, where it may differ from one session to the next (``the
    #: mount``, ``the instrument's set-up``, ``the temperature``): its candidates may be a session's own
    #: (:meth:`candidates` says which). None: a property of the robot, with one value whatever the session (a
    #: joint's stiffness, encoder scale, gear error, play, coupling: a physics rule, never a session's own)
    session_part: ClassVar[str | None] = None
    #: the word before its joint number (``joint 2``; a thermal expansion's ``link 3``)
    joint_word: ClassVar[str] = "joint"
    #: causes a candidate of this one needs in the model too (a progressive spring has a linear part)
    requires: ClassVar[tuple[str, ...]] = ()
    #: what the data must hold to test it, by condition (``casadical.diagnosis._catalogue.CONDITIONS``: ``masses``,
    #: ``time``, ``still``, ...), with the words that name it where they lack it (``backlash by the load``)
    needs: ClassVar[dict[str, str]] = {}
    #: a candidate stands for a scan of many (a periodic error's harmonics): the tests it stands for are counted by
    #: the scan, not one by one
    scanned: ClassVar[bool] = False
    #: how to tell it from another cause that explains the same residual, by the other's name (its own name: from
    #: itself, e.g. of another joint or source); ``{j}`` is the joint. A pair's text stands in one of the two.
    tell_apart: ClassVar[dict[str, str]] = {}
    #: what to measure so that it varies, to tell the robot's from one session's own (``{j}``: the joint)
    varies_text: ClassVar[str] = "measure poses where it shows"

    #: the geometry (links, base and tool): the reference a diagnosis extends, not a cause it names
    geometry: ClassVar[bool] = False
    #: structure no named cause explains (the GP compensator's, or kept out of the model)
    unexplained: ClassVar[bool] = False
    #: how the cause's value at a pose can go unchecked by the calibration poses (casadical.diagnosis._worst_case):
    #: ``torque`` or ``reading`` (linear in its joint's gravity torque or reading: beyond their range it
    #: extrapolates), ``period`` (a harmonic: in a gap of its joint's readings wider than half its period); None
    unchecked_by: ClassVar[str | None] = None
    #: the kinds of structure of set-aside poses it could explain (casadical.stats._outliers: ``order``, ``load``,
    #: ``direction``, ``region``)
    explains_set_aside: ClassVar[tuple[str, ...]] = ()
    #: causes a compliance-like cause of the same joint can look like where it could not be tried (no masses),
    #: by name
    looks_like: ClassVar[tuple[str, ...]] = ()
    #: the checks a candidate's acceptance asks beyond the statistics (casadical.diagnosis._nameable):
    #: ``reading_halves`` (the same over either half of the range of the joint it follows, :meth:`reading`),
    #: ``resolution`` (told from its neighbouring harmonics and the geometry), ``time_halves`` (the same over
    #: either half of the time), ``versus_drift`` (told from a drift), ``versus_harmonics`` (told from a
    #: periodic error of its joint)
    checks: ClassVar[tuple[str, ...]] = ()
    #: the cause its ``versus_...`` check tells it from (a warm-up: the drift), by name
    rival: ClassVar[str | None] = None
    #: kinds of fold that cannot judge it (a warm-up: the time folds; no later pose shows the start)
    unjudged_folds: ClassVar[frozenset[str]] = frozenset()
    #: a function of its own joint's reading (an encoder scale, a periodic error): two such causes of a joint are
    #: rivals that a short range cannot tell apart
    of_own_reading: ClassVar[bool] = False
    #: the variable of the structure screen it follows (``tau``: its joint's gravity torque, ``q``: a joint's
    #: reading, ``moment``: the moment of the weights about the mount); None: none of them
    own_variable: ClassVar[str | None] = None
    #: the first-order part of any structure of its own variable (a compliance, an encoder scale)
    first_order: ClassVar[bool] = False
    #: a linear axis' cause that moves the carriage (across the axis or turning it): no pair of the structure
    #: screen is its shape in general
    axis_shape: ClassVar[bool] = False

    #: its candidates' columns in a round's screen are computed from the directions of the joints' angles (or
    #: in the measurement frame) rather than taken from the model's Jacobian: :meth:`analytic_term` and
    #: :meth:`analytic_column` (a periodic error, a joint coupling, a warm-up)
    analytic: ClassVar[bool] = False

    #: the poses that tell it from its rivals can be planned (a warm-up's are in time, not in the arm's
    #: configuration)
    plannable: ClassVar[bool] = True

    def question(self, cand: Any) -> tuple[list, str] | None:
        """What structure of this cause kept out of the model asks (casadical.planning._questions): the candidates
        to plan for and the question in words; None: the candidate itself, "or something else?"."""
        return None

    def open_question(self, cand: Any) -> str | None:
        """What a named finding of this cause leaves open that only other sessions can answer (a law over a session
        covariate: its form between and beyond the values measured), in words; None by default."""
        return None

    @property
    def named(self) -> bool:
        """A cause the diagnosis names (not the geometry, nor what no cause explains)."""
        return not (self.geometry or self.unexplained)

    # -- naming -------------------------------------------------------------------------------------------

    def short_name(self, cand: Any) -> str:
        """The cause in a few words (:attr:`short`)."""
        return self.short or self.name.replace("_", " ")

    def family(self, cand: Any) -> Any:
        """The candidate with the setting a round scans left out (a warm-up's time constant); itself by default."""
        return cand

    def label(self, cand: Any, short: bool) -> str | None:
        """A candidate's label where the cause words it its own way (the GP compensator); None: the usual words
        (``casadical.diagnosis._candidates.Candidate.label``)."""
        return None

    def parameter_names(self, cand: Any) -> list[str]:
        """The names of the parameters a candidate adds to a model (the robot's; a session's own add ``@S``)."""
        raise NotImplementedError(f"cause {self.name} adds no parameters")

    def terms(self, cands: list) -> list:
        """The error terms of the candidates of one scope that are this cause's, as a model holds them (``cands``:
        all of the scope, for causes that take another's joints: a compliance those of a progressive spring)."""
        return []

    def candidates(self, data: Any) -> list:
        """The candidates of this cause the calibration poses can test (the robot's, and where the cause is of a
        session, :attr:`session_part`, each session's own or a law over a session covariate). ``data`` is the
        diagnosis' catalogue
        (``casadical.diagnosis._catalogue.Catalogue``): what the poses allow (its joints that move, loads,
        sessions, times, periodograms, the causes accepted so far) and ``data.make(name, ...)`` makes a
        candidate. None by default (a cause the search never screens: the geometry)."""
        return []

    def untested(self, data: Any) -> list[tuple[list[int], str, str]]:
        """What of this cause the calibration poses cannot test beyond the shared conditions of :attr:`needs`:
        (joints, why, what would allow it) each; ``data`` as :meth:`candidates`' (its robot, poses, torques).
        None by default."""
        return []

    def factors(self, cand: Any, data: Any, cal: Any):
        """A candidate whose columns are its :attr:`~casadical.diagnosis._candidates.Candidate.carrier`'s at per-pose
        factors beyond a session's indicator (a law over a session covariate): the factors (N, k) of its k
        parameters per parameter of the carrier at the poses of ``data`` (``cal``: the calibration poses the law is
        written over); None by default."""
        return None

    def carried(self, cand: Any, params: list) -> list:
        """The parameters (:class:`~casadical.model.parameters.Parameter`, named as the candidate's) of a candidate
        whose columns are its carrier's (a session's own, a law), made from the carrier's: as they are by default (a
        mount's differ in their bounds)."""
        return params

    def screenable(self, cand: Any, data: Any) -> bool:
        """Whether ``cand`` can be screened on these poses beyond what :meth:`candidates` knew (a play's sign must
        change in its scope); yes by default."""
        return True

    def reading(self, cand: Any) -> int | None:
        """The joint whose reading the cause follows (an encoder scale: its own; a coupling: its source); None."""
        return cand.joint if self.of_own_reading else None

    def own_shape(self, cand: Any) -> tuple[str, str, int | None] | None:
        """The (covariate, effect, joint) of the structure screen that is the cause's own shape: its
        :attr:`own_variable` of its joint (or of the joint it follows), acting on its joint's angle; None without
        one, or without a joint."""
        if self.own_variable is None or cand.joint is None:
            return None
        return f"{self.own_variable}{self.reading(cand) or cand.joint}", "angle", cand.joint

    def analytic_term(self, cand: Any):
        """An :attr:`analytic` cause: the term of one candidate, whose parameters (their scales) the screen uses."""
        raise NotImplementedError(f"cause {self.name} is not analytic")

    def analytic_column(self, cand: Any, k: int, data: Any, JA, t0: dict, robot: Any):
        """An :attr:`analytic` cause: the unscaled column (N, 3) of the ``k``-th parameter of ``cand`` at the poses
        of ``data``; ``JA`` (N, 3, n): how the tool point moves with each joint's angle; ``t0``: each session's
        first time (None: the only one's)."""
        raise NotImplementedError(f"cause {self.name} is not analytic")

    def varies(self, cand: Any) -> str:
        """What to measure so that the cause varies (:attr:`varies_text`)."""
        return self.varies_text

    # -- words of a finding (casadical.diagnosis._words) -------------------------------------------------------

    #: a finding's scope in words where its cause always has one (the geometry: ``robot``); None: as the
    #: diagnosis found it
    scope_word: ClassVar[str | None] = None

    def step_label(self, cand: Any) -> str | None:
        """A step of the search in a few words where the cause words it its own way (``kinematic``); None:
        ``+`` and the candidate's short label."""
        return None

    def long_label(self, finding: Any) -> str | None:
        """A finding's label in full where the cause words it its own way; None: the candidate's label."""
        return None

    def finding_label(self, finding: Any) -> str | None:
        """A finding's label where the cause words it its own way (``geometry``); None: the candidate's short
        label."""
        return None

    def place(self, cand: Any) -> str:
        """Where the cause acts, without its session: ``joint 2`` by default."""
        return f"joint {cand.joint}"

    def where(self, cand: Any, finding: Any) -> str:
        """Where a finding of the cause lives: :meth:`place` and, for a session's own, the session."""
        return self.place(cand) + (f", session {cand.session}" if cand.session is not None else "")

    def finding_size(self, finding: Any, final: Any) -> str | None:
        """A finding's size where it is not its parameters' (the geometry's count of them); None: :meth:`size`."""
        return None

    def size(self, cand: Any, values, stds, params: list, linear: bool) -> str:
        """The size of a finding in a few words (``k2 = 5.38e4 N m/rad +- 6.2 %``) from its parameters' final
        ``values``, ``stds`` and :class:`~casadical.parameters.Parameter` objects; ``linear``: its joint is a
        linear axis (metres where a revolute joint has radians). Nothing by default."""
        return ""

    def action(self, finding: Any) -> str | None:
        """What to do about a finding where the cause says it its own way; None: the diagnosis' words by its
        scope and transfer."""
        return None

    # -- words of structure kept out, of a finding's evidence, its figure (casadical.diagnosis._findings, plots) --

    def unexplained_item(self, cand: Any, values: dict, linear: bool) -> dict:
        """What a candidate of the cause that was fitted but could not be named describes (a structure kept out
        of the model: ``{"what": words, ...sizes}``), from its fitted ``values`` by name. By default a joint's
        part that follows its load (a compliance's words)."""
        return load_item(cand, values, progressive=False)

    def words(self, cand: Any, params: list, robot: Any, data: Any, linear: bool) -> str:
        """A named finding's size in words for its evidence (``stiffness k2 = 5.38e+04 N m/rad (std 3.3e+03)``),
        from its parameters in the final model; ``data``: the calibration poses. Nothing by default."""
        return ""

    def figure(self, cand: Any, data: Any, model: Any, params: Any, linear: bool) -> dict | None:
        """What a finding's figure plots: ``{"x", "xlabel", "effect"}`` (a joint's: its partial residual against
        the variable the cause follows, with the fitted ``effect`` per pose, rad or m) or ``{"x", "xlabel",
        "along"}`` (the residual before and after against that variable: its norm with ``along`` None, else
        along the direction of the cause's parameters, named ``along``). None: the errors against the rows."""
        return None

    def mine(self, cands: list) -> list:
        """The candidates among ``cands`` that are of this cause."""
        return [c for c in cands if c.kind is self]

    def __repr__(self) -> str:
        return f"<cause {self.name}>"


def register_cause(cause: "Cause") -> "Cause":
    """Make ``cause`` known by its name (a term module calls it once, at import)."""
    CAUSES[cause.name] = cause
    return cause


def session_parts() -> list[str]:
    """What can differ from one measurement session to the next, in words (``the mount``, ``the instrument's
    set-up``, ...): the registered causes' :attr:`Cause.session_part`, in their order, each once."""
    return list(dict.fromkeys(c.session_part for c in ordered("order") if c.session_part))


def ordered(key: str, extra: tuple = ()) -> list["Cause"]:
    """The registered causes (and ``extra`` ones: the user's) sorted by the class attribute ``key``
    (``order``), then by name."""
    return sorted([*CAUSES.values(), *extra], key=lambda c: (getattr(c, key), c.name))


def load_item(cand: Any, values: dict, progressive: bool) -> dict:
    """A structure that follows a joint's load, in words (as if a compliance ``c<j>``)."""
    c = values.get(f"c{cand.joint}", 0.0)
    k = 1 / c if c > 0 else math.inf
    return {"load_compliance": c,
            "what": (f"a part that follows the joint's load (as if k = {k:.3g} N m/rad"
                     f"{', progressive' if progressive else ''})") if c > 0 else
            f"a part that follows the joint's load with the wrong sign (c = {c:.3g} rad/(N m))"}
