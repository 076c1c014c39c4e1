"""Candidate extensions of the model, and how to compose them into a model specification."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..terms.carriage_angle import DEGREES as ANGLE_DEGREES
from ..terms.straightness import DEGREES as STRAIGHTNESS_DEGREES

#: causes in a few words, for reports (``unexplained`` of no joint: the GP compensator; of a joint: ``unexplained j1``)
SHORT = {"geometric": "kinematic", "joint_compliance": "compliance", "nonlinear_stiffness": "progressive stiffness",
         "joint_periodic": "periodic", "encoder_scale": "encoder scale", "backlash": "backlash",
         "thermal_expansion": "thermal", "drift": "drift", "warmup": "warm-up", "joint_coupling": "coupling",
         "mount_compliance": "mount compliance", "straightness": "straightness", "carriage_angle": "carriage"}


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
        :mod:`casadical.terms.user`; ``cause`` is its name): its parameters'
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

    def shared(self) -> "Candidate":
        """The same cause with one value for every session."""
        return replace(self, session=None)

    @property
    def scope(self) -> str | None:
        """``session`` for a cause of one session (or a drift or a warm-up, which belong to their session by
        nature)."""
        return "session" if self.session is not None or self.cause in ("drift", "warmup") else None

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
        takes the residual)."""
        return {"mount_compliance": 2, "drift": 3, "warmup": 3, "joint_periodic": 4, "joint_coupling": 5}.get(
            self.cause, 1)

    @property
    def family(self) -> "Candidate":
        """The cause with its setting scanned left out: a warm-up's time constants are one cause scanned over a
        grid (counted as tests, as harmonics are), and a round fits only its best-scoring one."""
        return replace(self, time_constant=None) if self.cause == "warmup" else self

    def label(self, short: bool = False) -> str:
        """``joint_periodic joint 2 harmonic 17``; short (reports): ``periodic j2 h17``."""
        if short and self.cause == "unexplained" and self.joint is None:
            return "GP compensator"
        parts = [SHORT.get(self.cause, self.cause.replace("_", " ")) if short else self.cause]
        if self.joint is not None:
            link = self.cause == "thermal_expansion"
            parts.append(("link" if link else "j") + str(self.joint) if short
                         else f"{'link' if link else 'joint'} {self.joint}")
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
        return d

    def parameter_names(self) -> list[str]:
        """Names of the parameters this candidate adds to a model."""
        if self.session is not None:
            return [f"{n}@{self.session}" for n in self.shared().parameter_names()]
        if self.user:
            return list(self.user)
        j, h = self.joint, self.harmonic
        return {
            "joint_compliance": [f"c{j}"],
            "nonlinear_stiffness": [f"c{j}", f"cubic{j}"],   # a progressive spring has a linear part too
            "joint_periodic": [f"gear{j}_s{h}", f"gear{j}_c{h}"],
            "encoder_scale": [f"escale{j}"],
            "backlash": [f"backlash{j}" if self.source != "motion" else f"backlash_m{j}"],
            "thermal_expansion": ["thermal_alpha" if j is None else f"thermal_alpha{j}"],
            "drift": ["drift_x", "drift_y", "drift_z"],
            "warmup": ["warmup_x", "warmup_y", "warmup_z"],
            "joint_coupling": [f"cpl{j}_{self.source_joint}"],
            "mount_compliance": ["cmount"],
            "straightness": [f"straight{j}{self.direction}_p{k}" for k in STRAIGHTNESS_DEGREES],
            "carriage_angle": [f"{self.angle}{j}_p{k}" for k in ANGLE_DEGREES],
        }[self.cause]


def compose_spec(candidates: list[Candidate], geometric: bool = True) -> str:
    """Model specification holding every candidate (same terms merged; a session's own terms ``...@s``)."""
    parts = ["kinematic" if geometric else "nominal"] + _terms([c for c in candidates if c.session is None])
    for s in dict.fromkeys(c.session for c in candidates if c.session is not None):
        parts += [f"{t}@{s}" for t in _terms([c.shared() for c in candidates if c.session == s])]
    return "+".join(parts)


def _terms(candidates: list[Candidate]) -> list[str]:
    """The term specifications of candidates of one scope."""
    cubic = sorted({c.joint for c in candidates if c.cause == "nonlinear_stiffness"})
    comp = sorted({c.joint for c in candidates if c.cause == "joint_compliance"} | set(cubic))
    links = sorted({c.joint for c in candidates if c.cause == "thermal_expansion" and c.joint is not None})
    per = sorted({(c.joint, c.harmonic) for c in candidates if c.cause == "joint_periodic"})
    enc = sorted({c.joint for c in candidates if c.cause == "encoder_scale"})
    blt = sorted({c.joint for c in candidates if c.cause == "backlash" and c.source != "motion"})
    blm = sorted({c.joint for c in candidates if c.cause == "backlash" and c.source == "motion"})
    parts = []
    if comp:
        parts.append(f"joint_compliance[{','.join(map(str, comp))}]")
    if cubic:
        parts.append(f"nonlinear_stiffness[{','.join(map(str, cubic))}]")
    if per:
        parts.append(f"joint_periodic[{','.join(f'{j}:{h}' for j, h in per)}]")
    if enc:
        parts.append(f"encoder_scale[{','.join(map(str, enc))}]")
    if blt:
        parts.append(f"backlash[{','.join(map(str, blt))}]")
    if blm:
        parts.append(f"backlash_motion[{','.join(map(str, blm))}]")
    if any(c.cause == "thermal_expansion" and c.joint is None for c in candidates):
        parts.append("thermal_expansion")
    if links:
        parts.append(f"thermal_expansion[{','.join(map(str, links))}]")
    if any(c.cause == "drift" for c in candidates):
        parts.append("drift")
    parts += [f"warmup[{c.time_constant:g}]" for c in candidates if c.cause == "warmup"][:1]
    parts += sorted({c.cause for c in candidates if c.user})     # causes of the user's own, by their names
    cpl = sorted({(c.joint, c.source_joint) for c in candidates if c.cause == "joint_coupling"})
    if cpl:
        parts.append(f"joint_coupling[{','.join(f'{j}:{k}' for j, k in cpl)}]")
    if any(c.cause == "mount_compliance" for c in candidates):
        parts.append("mount_compliance")
    for cause, key in (("straightness", "direction"), ("carriage_angle", "angle")):
        axis = sorted({(c.joint, getattr(c, key)) for c in candidates if c.cause == cause})
        if axis:
            parts.append(f"{cause}[{','.join(f'{j}:{k}' for j, k in axis)}]")
    return parts


#: How to tell apart two causes that explain the same residual on the data at hand.
TELL_APART = {
    frozenset({"encoder_scale", "joint_periodic"}):
        "measure joint {j} over a wider range (more than half a turn): a scale error grows with the "
        "angle while a first harmonic turns back",
    frozenset({"joint_compliance", "backlash"}):
        "measure the same poses with two payloads: a compliant joint deflects in proportion to the load, "
        "backlash does not",
    frozenset({"joint_compliance", "encoder_scale"}):
        "measure the same poses with two payloads, or with joint {j} at mirrored angles",
    frozenset({"backlash"}):
        "approach the same poses from both directions of joint {j}: play that follows the motion changes "
        "sign, play that follows gravity does not",
    frozenset({"thermal_expansion", "joint_compliance"}):
        "repeat poses at another temperature in random order",
    frozenset({"nonlinear_stiffness", "backlash"}):
        "measure the same poses with two payloads: a progressive spring's deflection grows smoothly with the "
        "load, backlash jumps at zero torque and stays",
    frozenset({"joint_compliance", "nonlinear_stiffness"}):
        "measure poses that load joint {j} over a wider range of torques (and with two payloads)",
    frozenset({"thermal_expansion"}):
        "measure while the arm warms up, with the links' temperatures if possible: links that grow "
        "differently need their own coefficients",
    frozenset({"thermal_expansion", "drift"}):
        "measure in random pose order while the temperature changes: thermal growth scales with the "
        "arm's reach, drift of the measurement frame does not",
    frozenset({"warmup", "drift"}):
        "measure for longer, or repeat the first poses at the end: a warm-up settles, a drift goes on",
    frozenset({"joint_coupling", "encoder_scale"}):
        "move joint {j} and the joint its error would follow independently (one still while the other turns): a "
        "scale grows with joint {j}'s own reading, a coupling with the other's",
    frozenset({"joint_coupling"}):
        "move each of the joints the error could follow while the others stand still",
    frozenset({"mount_compliance", "joint_compliance"}):
        "turn joint 1 with the arm stretched: the base's tilt follows the moment about the mount, a joint's "
        "deflection its own torque",
    frozenset({"mount_compliance", "thermal_expansion"}):
        "repeat poses at another temperature with the arm stretched and folded",
    frozenset({"straightness", "carriage_angle"}):
        "measure at each position of axis {j} with the arm stretched and folded: the carriage's angle moves the "
        "point in proportion to the arm's reach, a straightness error by the same amount at any reach",
    frozenset({"carriage_angle"}):
        "measure at each position of axis {j} with the arm reaching along each of the carriage's axes",
    frozenset({"straightness"}):
        "measure at each position of axis {j} with the tool at several heights and reaches",
    frozenset({"warmup"}):
        "measure for longer, or repeat the first poses at the end: the time constant shows in how fast the "
        "first poses' offset dies away",
}


#: what a cause of a joint varies with, for telling the robot's from one session's own
_VARIES = {"encoder_scale": "move joint {j} over a wider range", "joint_periodic": "move joint {j} over a wider range",
           "backlash": "load joint {j} with torques of both signs", "joint_compliance": "load joint {j} over a wider "
           "range of torques", "nonlinear_stiffness": "load joint {j} over a wider range of torques",
           "mount_compliance": "swing the arm's weight about the base (joint 1 turning, the arm stretched and folded)",
           "joint_coupling": "move joint {j} and its source joint independently over wider ranges",
           "straightness": "move axis {j} over more of its travel", "carriage_angle": "move axis {j} over more of its "
           "travel"}


def tell_apart(a: Candidate, b: Candidate) -> str:
    if a.shared() == b.shared() and a.session != b.session:
        own = a.session or b.session
        how = ("approach joint {j} from both directions" if a.source == "motion" else
               _VARIES.get(a.cause, "measure poses where it shows")).format(j=a.joint)
        return (f"in a session other than {own}, {how}: the robot's shows in every session, session {own}'s own "
                "only in it")
    key = frozenset({a.cause, b.cause})
    text = TELL_APART.get(key, "measure poses where the two candidates predict different errors "
                               "(wider joint ranges, other loads or temperatures)")
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
