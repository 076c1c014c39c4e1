"""What a round screens: every candidate cause the data can test, for the robot and for each session; and
every kind the data cannot test, with why and what would allow it.

Each kind of cause is a candidate of the robot (one value for every
session). With data of several sessions, only what differs between them
(a cause's :attr:`~casadical.terms._cause.Cause.session_part`: the mount,
the instrument's set-up, a drift or a warm-up) is also a candidate of each
session alone (``... @S``) or follows a law over a session covariate (a
column constant within each session: a column's height); a joint's own
parameter (its stiffness, encoder scale, gear error, play, coupling) is a
property of the robot, one value whatever the session (issue 49: the
column's give, which grows with its height, was named a compliance of joint
1 "of session c_3.87"). A joint coupling (joint j's angle error
proportional to joint k's reading) is screened for every pair of joints
that move with the source before the joint (k < j): a joint's drive train
passes through the joints before it (a wrist's motors sit in the forearm),
so its error can follow their readings, never a later joint's (a later
joint's source stands for other structure: on the UR10 README job joint 1
from joint 5 took the place of joint 5's gear error). It is the robot's
only: a wrist's gearing is the same in every session, and the pairs again
per session would only dilute the level; and it is not tried on poses that
move one joint at a time (a joint's error that follows another's reading
shows at one configuration of the arm only, where it fits anything: on a
weak design of 24 such poses a coupling of joint 3 from joint 1 more than
doubled the validation error). A mount
compliance needs the robot file's masses (the moment of the weights about
the base) and a moment that changes over the poses (a constant tilt is the
base pose's). Periodic errors come from the periodogram of the residual's
joint angle errors over every pose. A drift
and a warm-up belong to their session by nature: with several sessions only
their own are tried. Structure of a joint that holds in one session only and
that no cause of a session takes is an ``unexplained`` finding naming the
session (:func:`._search.one_session`, and the structure screen's pairs of
one session, :mod:`._structure`).

A linear axis (a prismatic joint: a track, a column) has its own kinds
instead of a revolute joint's compliance, progressive stiffness and
coupling (ISO 230-1): its scale per metre, a periodic error per metre from
:data:`MIN_CYCLES` cycles over the travel the data cover, play by the
motion (and by the load where gravity pushes along it), its straightness
across it in x and y and its carriage's roll, pitch and yaw; the robot's
only (a property of the axis, as a coupling is of the wrist).

A kind the data cannot test is never skipped in silence: :class:`NotTried`
says why and what would allow it (the links' masses or a payload column
for a compliance, the poses' times for a drift or a warm-up, a temperature
for a thermal expansion, a joint range for a harmonic).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..data._covariates import session_covariates
from ..data._measurements import Measurements
from ..robot import Robot
from ..stats._physics import sign_changes
from ..terms import ordered
from ..terms._mount_compliance import max_mount_moment, mount_moments
from ..terms._periodic import phase
from ._candidates import Candidate
from ._design import ONE_AT_A_TIME, moving_of
from ._periodogram import Periodogram, joint_errors, periodogram
from ._plots import joint_view
from ._settings import DiagnosisSettings

#: time constants of the warm-ups screened: this many, from two pose spacings to a third of the session
WARMUP_STEPS = 10
#: a joint covering less than this (degrees) cannot tell its low harmonics from the geometry
SHORT_RANGE_DEG = 90.0
#: a linear axis' periodic error (a screw's or a rack's pitch) completes at least this many cycles over the travel
#: the data cover: fewer is a bow or a slope of the position error, which a scale or the geometry also takes (a
#: first harmonic over a 1.03 m column took the place of an error quadratic in the position)
MIN_CYCLES = 2
#: gravity torques below this (N m) at every pose: the joint is not loaded
NO_TORQUE = 1e-9
#: the horizontal moment of the weights must change by this share of its largest possible value over the poses
#: for the mount's give to show (a constant tilt is a rotation of the base pose)
MOMENT_CHANGE = 1e-3


@dataclass
class NotTried:
    """A kind of cause the data cannot test.

    Attributes
    ----------
    cause : str
        A cause's words (``joint_compliance``, ``backlash by the load``; several joined by ``, `` when one reason
        stops them all).
    joints : list of int
        The joints it concerns ([]: all, or none in particular).
    why : str
    allow : str
        What would let the diagnosis try it.
    condition : str
        What the data lack (a key of :data:`CONDITIONS`).
    causes : list of str
        The names of the causes it stops.
    """

    cause: str
    why: str
    allow: str
    joints: list[int] = field(default_factory=list)
    condition: str = ""
    causes: list[str] = field(default_factory=list)

    def text(self) -> str:
        on = f" of joint{'s' if len(self.joints) > 1 else ''} {', '.join(map(str, self.joints))}" \
            if self.joints else ""
        return f"{self.cause.replace('_', ' ')}{on}: {self.why}; {self.allow}"

    def to_dict(self) -> dict:
        d = {"cause": self.cause, "why": self.why, "allow": self.allow}
        if self.joints:
            d["joints"] = list(self.joints)
        return d


@dataclass
class _Data:
    """What the conditions of :func:`not_tried` read of the calibration poses."""

    robot: Robot
    cal: Measurements
    torques: np.ndarray
    settings: DiagnosisSettings

    def __post_init__(self):
        self.revolute = [j for j, jt in enumerate(self.robot.joints, start=1) if not jt.prismatic]
        self.linear = [j for j in range(1, self.robot.n + 1) if j not in self.revolute]
        payload = self.cal.get("payload_kg")
        self.masses = any(j.mass > 0 for j in self.robot.joints) or self.robot.payload_mass > 0 or (
            payload is not None and np.any(payload > 0))
        self.idle = [j for j in self.revolute if np.max(np.abs(self.torques[:, j - 1]), initial=0.0) < NO_TORQUE]
        self.level = [j for j in self.linear if np.max(np.abs(self.torques[:, j - 1]), initial=0.0) < NO_TORQUE]


def _linear_axis(d: _Data):
    return d.linear and (d.linear, "a prismatic joint (a linear axis): these are errors of a revolute joint's angle "
                         "(a linear axis' are screened: its scale, periodic error and backlash along it, its "
                         "straightness, its carriage's roll, pitch and yaw; the column's or the track's give under "
                         "the arm's moment is the mount compliance)", "no data can: a linear axis has no such error")


def _still_axis(d: _Data):
    still = [j for j in d.linear if np.ptp(d.cal.q[:, j - 1]) <= 0]
    return still and (still, "the linear axis does not move in the data", "poses over the axis' travel")


def _masses(d: _Data):
    return not d.masses and ([], "the robot file gives no link masses and no payload, and the poses no payload_kg: "
                             "the gravity torques are unknown", "give the links' mass_kg and com_m in the robot "
                             "file, or a payload_kg column of a known payload")


def _level(d: _Data):
    return d.masses and d.level and (d.level, "gravity does not push the linear axis along it (a level track)",
                                     "nothing these poses could change; play by the direction of motion is tried")


def _idle(d: _Data):
    return d.masses and d.idle and (d.idle, "gravity does not load them at any pose (an axis along gravity, or no "
                                    "mass beyond it)", "nothing these poses could change: gravity never loads such "
                                    "a joint")


def _one_sign(d: _Data):
    one_sign = [j for j in range(1, d.robot.n + 1) if j not in d.idle + d.level
                and not sign_changes(np.sign(d.torques[:, j - 1]), "")[0]]
    return d.masses and one_sign and (one_sign, "the gravity torque keeps one sign over the poses (play would be a "
                                      "constant joint offset)", "poses on both sides of the balance, at least 5 each")


def _mount_masses(d: _Data):
    return max_mount_moment(d.robot) <= 0 and ([], "the robot file gives no link masses and no payload: the moment "
                                               "of the weights about the base is unknown", "give the links' mass_kg "
                                               "and com_m (or a payload) in the robot file")


def _mount_moment(d: _Data):
    return max_mount_moment(d.robot) > 0 and not moment_changes(d.robot, d.cal) and (
        [], "the moment of the weights about the base hardly changes over the poses (a constant tilt is the base "
        "pose's)", "poses that swing the arm's weight about the base: joint 1 turning with the arm stretched, the arm "
        "stretched and folded, or payloads")


def _one_at_a_time(d: _Data):
    return d.robot.n > 1 and one_at_a_time(d.cal) and (
        [], "the poses move one joint at a time: a joint's error that follows another joint's reading would show at "
        "one configuration of the arm only", "poses that move the joints together (random poses, or casadical "
        "plan-poses)")


def _one_way(d: _Data):
    one_way = [j for j in range(1, d.robot.n + 1) if not sign_changes(d.cal.moves[:, j - 1], "")[0]]
    return one_way and (one_way, "the joint moves in one direction only between the rows", "poses approached from "
                        "both directions, in measurement order")


def _time(d: _Data):
    return d.cal.get("time_s") is None and ([], "the poses have no times (time_s)", "a time_s column, or "
                                            "--row-spacing-s SECONDS if the rows are in time order at a regular "
                                            "spacing")


def _temperature(d: _Data):
    return d.cal.get("temperature_c") is None and ([], "the poses have no temperature (temperature_c)",
                                                   "a temperature_c column, measured while the temperature changes")


def _temperature_range(d: _Data):
    temp = d.cal.get("temperature_c")
    return temp is not None and np.ptp(temp) <= 0.1 and (
        [], f"the temperature varies by {np.ptp(temp):.2g} K only", "measure while the temperature changes by a few "
        "kelvin")


def _still(d: _Data):
    still = [j for j in d.revolute if np.ptp(d.cal.q[:, j - 1]) <= 0]
    return still and (still, "the joint does not move in the data", "poses over the joint's range")


def _short_range(d: _Data):
    short = {j: math.degrees(np.ptp(d.cal.q[:, j - 1])) for j in d.revolute if np.ptp(d.cal.q[:, j - 1]) > 0}
    short = {j: r for j, r in short.items() if r < SHORT_RANGE_DEG}
    return short and (sorted(short), f"over the {', '.join(f'{r:.0f}' for r in short.values())} deg these joints "
                      f"cover, harmonics below about {360 / max(short.values()):.0f} cycles per turn complete less "
                      "than a period and cannot be told from the geometry or an encoder scale",
                      "measure the joints over a wider range (half a turn or more)")


def _low_linear(d: _Data):
    low = {j: lowest_harmonic(d.cal, j) for j in d.linear if np.ptp(d.cal.q[:, j - 1]) > 0}
    low = {j: h for j, h in low.items() if h > 1}
    return low and (sorted(low), "over the " + ", ".join(f"{np.ptp(d.cal.q[:, j - 1]) * 1000:.0f}" for j in low)
                    + f" mm these axes cover, harmonics below {', '.join(map(str, low.values()))} cycles per metre "
                    f"complete fewer than {MIN_CYCLES} cycles: a bow or a slope of the position, not a pitch error",
                    "measure over more of the axis' travel")


def _high_harmonics(d: _Data):
    h = max_harmonic(d.cal, d.settings)
    return h < d.settings.max_harmonic and (
        [], f"harmonics above {h} are not scanned: {len(d.cal)} calibration poses (three per harmonic)",
        f"{3 * d.settings.max_harmonic} or more poses (to scan up to --max-harmonic {d.settings.max_harmonic})")


#: what data may lack, in the order :func:`not_tried` says it: each a function of the poses giving (joints, why,
#: allow) where the data lack it (else something false); a cause says which it needs and its words for each
#: (:attr:`~casadical.terms._cause.Cause.needs`)
CONDITIONS = {"linear_axis": _linear_axis, "still_axis": _still_axis, "masses": _masses, "level": _level,
              "idle": _idle, "one_sign": _one_sign, "mount_masses": _mount_masses, "mount_moment": _mount_moment,
              "one_at_a_time": _one_at_a_time, "one_way": _one_way, "time": _time, "temperature": _temperature,
              "temperature_range": _temperature_range, "still": _still, "short_range": _short_range,
              "low_linear": _low_linear, "high_harmonics": _high_harmonics}


def not_tried(robot: Robot, cal: Measurements, torques: np.ndarray, settings: DiagnosisSettings) -> list[NotTried]:
    """Every kind of cause ``cal`` cannot test on ``robot``, with why and what would allow it: for each condition
    the data lack (:data:`CONDITIONS`), the causes that need it, in their order.

    ``torques``: the gravity torques of the poses (N m) under a first fit.
    """
    d = _Data(robot, cal, torques, settings)
    out = []
    for key, lacks in CONDITIONS.items():
        stopped = [c for c in ordered("order") if key in c.needs]
        found = stopped and lacks(d)
        if found:
            joints, why, allow = found
            out.append(NotTried(", ".join(c.needs[key] for c in stopped), why, allow, list(joints), key,
                                [c.name for c in stopped]))
    for cause in ordered("order"):      # what of a cause alone these poses cannot test
        out += [NotTried(cause.name, why, allow, list(joints), cause.name, [cause.name])
                for joints, why, allow in cause.untested(d)]
    return out


def lowest_harmonic(data: Measurements, j: int) -> int:
    """The lowest harmonic (cycles per metre) screened on linear axis ``j``: :data:`MIN_CYCLES` over the travel
    ``data`` cover."""
    return max(1, math.ceil(MIN_CYCLES / max(float(np.ptp(data.q[:, j - 1])), 1e-9) - 1e-9))


def one_at_a_time(data: Measurements) -> bool:
    """The poses move one joint at a time (from a common pose, or from the pose before): a joint's error that
    follows another joint's reading shows at one configuration of the arm only, where any function of that
    reading fits it (a coupling is not tried)."""
    return moving_of(data)[0] >= ONE_AT_A_TIME


def moment_changes(robot: Robot, data: Measurements) -> bool:
    """The horizontal moment of the weights about the base changes over ``data``'s poses by
    :data:`MOMENT_CHANGE` of its largest possible value (the robot has masses)."""
    top = max_mount_moment(robot)
    if top <= 0 or len(data) < 2:
        return False
    M = mount_moments(robot, data.q, data.get("payload_kg"))
    return float(np.max(np.ptp(M, axis=0))) > MOMENT_CHANGE * top


def max_harmonic(data: Measurements, settings: DiagnosisSettings) -> int:
    """The highest harmonic scanned on ``data``: three poses per harmonic, at most ``--max-harmonic``."""
    return min(settings.max_harmonic, max(len(data) // 3, 1))


def warmup_time_constants(times: np.ndarray) -> list[float]:
    """The warm-up time constants screened on one session's times: from two pose spacings to a third of the
    session, evenly on a log scale (none for fewer than 6 poses)."""
    t = np.sort(np.asarray(times, float))
    if len(t) < 6 or np.ptp(t) <= 0:
        return []
    step = float(np.median(np.diff(t)))
    lo, hi = max(2 * step, np.ptp(t) / 1000), np.ptp(t) / 3
    if not lo < hi:
        return []
    return [float(f"{x:.3g}") for x in np.geomspace(lo, hi, WARMUP_STEPS)]


class Catalogue:
    """The candidate causes of a diagnosis's calibration data, round after round.

    Parameters
    ----------
    robot : Robot
    cal : Measurements
    settings : DiagnosisSettings
    """

    def __init__(self, robot: Robot, cal: Measurements, settings: DiagnosisSettings):
        self.robot, self.cal, self.s = robot, cal, settings
        self.sessions = cal.session_names                  # [] for one session
        self.periodograms: list[Periodogram] = []          # the robot's, for the report
        self._of = None                                     # the fit they were computed for
        self.mount: list | None = None                      # scopes whose moment changes (None: the robot's)
        self.couples: bool | None = None                    # couplings are tried (the poses move joints together)
        self._memo: dict = {}                               # what a cause computes once (memo)
        t = cal.get("time_s")
        if t is None:
            self.warmups: dict[str | None, list[float]] = {}
        elif len(self.sessions) > 1:
            self.warmups = {s: warmup_time_constants(t[cal.sessions == s]) for s in self.sessions}
        else:
            self.warmups = {None: warmup_time_constants(t)}

    def max_harmonic(self, data: Measurements | None = None) -> int:
        return max_harmonic(self.cal if data is None else data, self.s)

    def n_tests(self, cands: list[Candidate]) -> int:
        """Tests behind a round's candidates: each periodic candidate stands for the harmonics scanned."""
        per = sum(1 for c in cands if c.kind.scanned)
        return (len(cands) - per) + self.robot.n * self.max_harmonic()

    def update_periodograms(self, current) -> None:
        """Periodograms of the joint angle errors of ``current``'s residual over every pose (a gear error is the
        robot's: one in every session)."""
        if self._of is current:
            return
        resid, JA = joint_view(current, self.cal)
        q, h = self.cal.q, max_harmonic(self.cal, self.s)
        self.periodograms = []
        for j in range(1, self.robot.n + 1):
            s, w = joint_errors(resid, JA[:, :, j - 1])
            self.periodograms.append(periodogram(phase(self.robot, j, q[:, j - 1]), s, w, j, h))
        self._of = current

    def candidates(self, current, accepted: list[Candidate], excluded: set, excluded_causes: set,
                   torques) -> list[Candidate]:
        """Every candidate not yet in the model: each cause's (:meth:`~casadical.terms._cause.Cause.candidates`,
        asked with this catalogue as what the data allow: the robot's, and a session's own only of a cause that
        is of a session, :attr:`~casadical.terms._cause.Cause.session_part`).

        ``excluded``: periodic ``(joint, harmonic, session)`` not to screen
        again; ``excluded_causes``: other candidates not to screen again;
        ``torques``: a function giving the gravity torques of the
        calibration poses under ``current``.
        """
        if self.couples is None:
            self.couples = not one_at_a_time(self.cal)
        if self.mount is None:
            self.mount = [s for s in [None] + (self.sessions if len(self.sessions) > 1 else [])
                          if moment_changes(self.robot, self.cal if s is None else
                                            self.cal.subset(self.cal.sessions == s))]
        self.update_periodograms(current)
        self.accepted, self.excluded, self.torques = accepted, excluded, torques
        out: list[Candidate] = []
        for cause in ordered("order"):
            out += cause.candidates(self)
        out += self.user_candidates()
        have = set(accepted)
        return [c for c in dict.fromkeys(out) if c not in have and c not in excluded_causes
                and c.kind.screenable(c, self)]

    # -- what a cause's candidates are made of (casadical.terms._cause.Cause.candidates) -----------------------

    make = Candidate

    def memo(self, key, make):
        """What a cause computes once of the calibration poses (``make()``), kept by ``key`` for the rounds."""
        if key not in self._memo:
            self._memo[key] = make()
        return self._memo[key]

    @property
    def session_covariates(self) -> dict[str, dict[str, float]]:
        """The calibration poses' session covariates (columns constant within each session: a column's height),
        with their value in each session (:func:`casadical.data._covariates.session_covariates`)."""
        return self.memo("session_covariates", lambda: session_covariates(self.cal))

    @property
    def revolute(self) -> list[int]:
        return [j for j, jt in enumerate(self.robot.joints, start=1) if not jt.prismatic]

    @property
    def moving(self) -> list[int]:
        """The revolute joints the poses move."""
        return [j for j in self.revolute if np.ptp(self.cal.q[:, j - 1]) > 0]

    @property
    def moving_axes(self) -> list[int]:
        """The linear axes the poses move."""
        return [j for j in range(1, self.robot.n + 1) if self.robot.joints[j - 1].prismatic
                and np.ptp(self.cal.q[:, j - 1]) > 0]

    def loaded(self, j: int) -> bool:
        """Gravity loads joint ``j`` at some pose."""
        return np.max(np.abs(self.torques()[:, j - 1]), initial=0.0) >= NO_TORQUE

    @property
    def temperature_varies(self) -> bool:
        temp = self.cal.get("temperature_c")
        return temp is not None and np.ptp(temp) > 0.1

    @property
    def timed(self) -> bool:
        """The poses have times (never the row numbers)."""
        return self.cal.get("time_s") is not None

    @property
    def scopes(self) -> list:
        """The scopes a cause of its session by nature is tried in: each session's, or the only one's (None)."""
        return self.sessions if len(self.sessions) > 1 else [None]

    def lowest_harmonic(self, j: int) -> int:
        """The lowest harmonic screened on joint ``j``: the first, on a linear axis :data:`MIN_CYCLES` over its
        travel."""
        return 1 if not self.robot.joints[j - 1].prismatic else lowest_harmonic(self.cal, j)

    def user_candidates(self) -> list[Candidate]:
        """The causes of the user's own (the terms of the settings, a terms file's): each the robot's (scope
        ``robot``) and, with several sessions, each session's own (scope ``robot`` or ``session``); none without
        a terms file."""
        out = []
        for d in self.s.terms:
            cand = Candidate(d.name, d.joints[0] if d.one_joint else None,
                             user=tuple(f"{d.name}.{p}" for p in d.parameter_names), definition=d)
            several = len(self.sessions) > 1
            if d.scope == "robot" or not several:
                out.append(cand)
            if several:
                out += [replace(cand, session=s) for s in self.sessions]
        return out

    def sign_changes(self, cand: Candidate) -> bool:
        """``cand``'s sign source (its joint's last move, or gravity torque) changes sign in its scope's poses."""
        j = cand.joint
        signs = self.cal.moves[:, j - 1] if cand.source == "motion" else np.sign(self.torques()[:, j - 1])
        if cand.session is not None:
            signs = signs[self.cal.sessions == cand.session]
        return sign_changes(signs, "")[0]
