"""What a round screens: every candidate cause the data can test, for the robot and for each session; and
every kind the data cannot test, with why and what would allow it.

Each kind of cause is a candidate of the robot (one value for every
session) and, with data of several sessions, of each session alone
(``... @S``: a gear error, an encoder scale, a compliance or the mount's
give of one session's set-up). A joint coupling (joint j's angle error
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
base pose's). Periodic errors come from the periodograms of the residual's
joint angle errors: the robot's over every pose, each session's over its
own poses (a gear error of one session is diluted in the others'). A drift
and a warm-up belong to their session by nature: with several sessions only
their own are tried.

A linear axis (a prismatic joint: a track, a column) has its own kinds
instead of a revolute joint's compliance, progressive stiffness and
coupling (ISO 230-1): its scale per metre, a periodic error per metre from
:data:`MIN_CYCLES` cycles over the travel the data cover, play by the
motion (and by the load where gravity pushes along it), its straightness
across it in x and y and its carriage's roll, pitch and yaw; the robot's
only (a property of the axis, as a coupling is of the wrist) but for the
per-joint kinds a session may have on its own.

A kind the data cannot test is never skipped in silence: :class:`NotTried`
says why and what would allow it (the links' masses or a payload column
for a compliance, the poses' times for a drift or a warm-up, a temperature
for a thermal expansion, a joint range for a harmonic).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..data.measurements import Measurements
from ..robot import Robot
from ..stats.physics import sign_changes
from ..terms.carriage_angle import ANGLES as CARRIAGE_ANGLES
from ..terms.definitions import known
from ..terms.mount_compliance import max_mount_moment, mount_moments
from ..terms.periodic import phase
from ..terms.straightness import DIRECTIONS as STRAIGHTNESS_DIRECTIONS
from .candidates import Candidate
from .design import ONE_AT_A_TIME, moving_joint
from .periodogram import Periodogram, joint_errors, periodogram
from .plots import joint_view
from .settings import DiagnosisSettings

#: kinds of one joint each session can have on its own (thermal expansion changes the geometry: the robot's)
PER_JOINT = ("joint_compliance", "nonlinear_stiffness", "encoder_scale", "backlash")
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
        A cause name (``joint_compliance``, ``drift``, ...; several
        joined by ``, `` when one reason stops them all).
    joints : list of int
        The joints it concerns ([]: all, or none in particular).
    why : str
    allow : str
        What would let the diagnosis try it.
    """

    cause: str
    why: str
    allow: str
    joints: list[int] = field(default_factory=list)

    def text(self) -> str:
        on = f" of joint{'s' if len(self.joints) > 1 else ''} {', '.join(map(str, self.joints))}" \
            if self.joints else ""
        return f"{self.cause.replace('_', ' ')}{on}: {self.why}; {self.allow}"

    def to_dict(self) -> dict:
        d = {"cause": self.cause, "why": self.why, "allow": self.allow}
        if self.joints:
            d["joints"] = list(self.joints)
        return d


def not_tried(robot: Robot, cal: Measurements, torques: np.ndarray, settings: DiagnosisSettings) -> list[NotTried]:
    """Every kind of cause ``cal`` cannot test on ``robot``, with why and what would allow it.

    ``torques``: the gravity torques of the poses (N m) under a first fit.
    """
    out = []
    revolute = [j for j, jt in enumerate(robot.joints, start=1) if not jt.prismatic]
    linear = [j for j in range(1, robot.n + 1) if j not in revolute]
    if linear:
        out.append(NotTried("joint_compliance, nonlinear_stiffness, joint_coupling",
                            "a prismatic joint (a linear axis): these are errors of a revolute joint's angle (a "
                            "linear axis' are screened: its scale, periodic error and backlash along it, its "
                            "straightness, its carriage's roll, pitch and yaw; the column's or the track's give "
                            "under the arm's moment is the mount compliance)",
                            "no data can: a linear axis has no such error", linear))
        still_axes = [j for j in linear if np.ptp(cal.q[:, j - 1]) <= 0]
        if still_axes:
            out.append(NotTried("encoder_scale, joint_periodic, straightness, carriage_angle",
                                "the linear axis does not move in the data", "poses over the axis' travel",
                                still_axes))
    payload = cal.get("payload_kg")
    masses = any(j.mass > 0 for j in robot.joints) or robot.payload_mass > 0 or (
        payload is not None and np.any(payload > 0))
    if not masses:
        out.append(NotTried("joint_compliance, nonlinear_stiffness, backlash by the load",
                            "the robot file gives no link masses and no payload, and the poses no payload_kg: the "
                            "gravity torques are unknown",
                            "give the links' mass_kg and com_m in the robot file, or a payload_kg column of a "
                            "known payload"))
    else:
        idle = [j for j in revolute if np.max(np.abs(torques[:, j - 1]), initial=0.0) < NO_TORQUE]
        level = [j for j in linear if np.max(np.abs(torques[:, j - 1]), initial=0.0) < NO_TORQUE]
        if level:
            out.append(NotTried("backlash by the load", "gravity does not push the linear axis along it (a level "
                                "track)", "nothing these poses could change; play by the direction of motion is "
                                "tried", level))
        if idle:
            out.append(NotTried("joint_compliance, nonlinear_stiffness, backlash by the load",
                                "gravity does not load them at any pose (an axis along gravity, or no mass beyond it)",
                                "nothing these poses could change: gravity never loads such a joint", idle))
        one_sign = [j for j in range(1, robot.n + 1) if j not in idle + level
                    and not sign_changes(np.sign(torques[:, j - 1]), "")[0]]
        if one_sign:
            out.append(NotTried("backlash by the load", "the gravity torque keeps one sign over the poses (play "
                                "would be a constant joint offset)", "poses on both sides of the balance, at least "
                                "5 each", one_sign))
    if max_mount_moment(robot) <= 0:
        out.append(NotTried("mount_compliance", "the robot file gives no link masses and no payload: the moment of "
                            "the weights about the base is unknown",
                            "give the links' mass_kg and com_m (or a payload) in the robot file"))
    elif not moment_changes(robot, cal):
        out.append(NotTried("mount_compliance", "the moment of the weights about the base hardly changes over the "
                            "poses (a constant tilt is the base pose's)",
                            "poses that swing the arm's weight about the base: joint 1 turning with the arm "
                            "stretched, the arm stretched and folded, or payloads"))
    if robot.n > 1 and one_at_a_time(cal):
        out.append(NotTried("joint_coupling", "the poses move one joint at a time: a joint's error that follows "
                            "another joint's reading would show at one configuration of the arm only",
                            "poses that move the joints together (random poses, or casadical plan-poses)"))
    one_way = [j for j in range(1, robot.n + 1) if not sign_changes(cal.moves[:, j - 1], "")[0]]
    if one_way:
        out.append(NotTried("backlash by the motion", "the joint moves in one direction only between the rows",
                            "poses approached from both directions, in measurement order", one_way))
    if cal.get("time_s") is None:
        out.append(NotTried("drift, warmup", "the poses have no times (time_s)",
                            "a time_s column, or --row-spacing-s SECONDS if the rows are in time order at a regular "
                            "spacing"))
    temp = cal.get("temperature_c")
    if temp is None:
        out.append(NotTried("thermal_expansion", "the poses have no temperature (temperature_c)",
                            "a temperature_c column, measured while the temperature changes"))
    elif np.ptp(temp) <= 0.1:
        out.append(NotTried("thermal_expansion", f"the temperature varies by {np.ptp(temp):.2g} K only",
                            "measure while the temperature changes by a few kelvin"))
    still = [j for j in revolute if np.ptp(cal.q[:, j - 1]) <= 0]
    if still:
        out.append(NotTried("joint_periodic, encoder_scale, joint_coupling", "the joint does not move in the data",
                            "poses over the joint's range", still))
    short = {j: math.degrees(np.ptp(cal.q[:, j - 1])) for j in revolute if j not in still}
    short = {j: r for j, r in short.items() if r < SHORT_RANGE_DEG}
    if short:
        top = max(short.values())
        out.append(NotTried("joint_periodic (low harmonics)",
                            f"over the {', '.join(f'{r:.0f}' for r in short.values())} deg these joints cover, "
                            f"harmonics below about {360 / top:.0f} cycles per turn complete less than a period and "
                            "cannot be told from the geometry or an encoder scale",
                            "measure the joints over a wider range (half a turn or more)", sorted(short)))
    low = {j: lowest_harmonic(cal, j) for j in linear if np.ptp(cal.q[:, j - 1]) > 0}
    low = {j: h for j, h in low.items() if h > 1}
    if low:
        out.append(NotTried("joint_periodic (low harmonics of a linear axis)",
                            "over the " + ", ".join(f"{np.ptp(cal.q[:, j - 1]) * 1000:.0f}" for j in low)
                            + f" mm these axes cover, harmonics below {', '.join(map(str, low.values()))} cycles per "
                            f"metre complete fewer than {MIN_CYCLES} cycles: a bow or a slope of the position, not a "
                            "pitch error", "measure over more of the axis' travel", sorted(low)))
    h = max_harmonic(cal, settings)
    if h < settings.max_harmonic:
        out.append(NotTried("joint_periodic (high harmonics)",
                            f"harmonics above {h} are not scanned: {len(cal)} calibration poses (three per harmonic)",
                            f"{3 * settings.max_harmonic} or more poses (to scan up to --max-harmonic "
                            f"{settings.max_harmonic})"))
    return out


def lowest_harmonic(data: Measurements, j: int) -> int:
    """The lowest harmonic (cycles per metre) screened on linear axis ``j``: :data:`MIN_CYCLES` over the travel
    ``data`` cover."""
    return max(1, math.ceil(MIN_CYCLES / max(float(np.ptp(data.q[:, j - 1])), 1e-9) - 1e-9))


def one_at_a_time(data: Measurements) -> bool:
    """The poses move one joint at a time (from a common pose, or from the pose before): a joint's error that
    follows another joint's reading shows at one configuration of the arm only, where any function of that
    reading fits it (a coupling is not tried)."""
    return moving_joint(data.q_deg[np.argsort(data.rows, kind="stable")])[0] >= ONE_AT_A_TIME


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
        self._own: dict[str, list[Periodogram]] = {}       # each session's
        self._of = None                                     # the fit they were computed for
        self.mount: list | None = None                      # scopes whose moment changes (None: the robot's)
        self.couples: bool | None = None                    # couplings are tried (the poses move joints together)
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
        """Tests behind a round's candidates: each periodic candidate stands for the harmonics scanned in its
        scope (the robot's, or one session's)."""
        per = sum(1 for c in cands if c.cause == "joint_periodic")
        scanned = self.robot.n * self.max_harmonic()
        if len(self.sessions) > 1:
            scanned += sum(self.robot.n * self.max_harmonic(self.cal.subset(self.cal.sessions == s))
                           for s in self.sessions)
        return (len(cands) - per) + scanned

    def update_periodograms(self, current) -> None:
        """Periodograms of the joint angle errors of ``current``'s residual: the robot's and each session's."""
        if self._of is current:
            return
        resid, JA = joint_view(current, self.cal)
        q = self.cal.q

        def grams(at: np.ndarray) -> list[Periodogram]:
            h = max_harmonic(self.cal.subset(at), self.s)
            out = []
            for j in range(1, self.robot.n + 1):
                s, w = joint_errors(resid[at], JA[at][:, :, j - 1])
                out.append(periodogram(phase(self.robot, j, q[at, j - 1]), s, w, j, h))
            return out

        self.periodograms = grams(np.ones(len(self.cal), bool))
        self._own = {s: grams(self.cal.sessions == s) for s in self.sessions} if len(self.sessions) > 1 else {}
        self._of = current

    def candidates(self, current, accepted: list[Candidate], excluded: set, excluded_causes: set,
                   torques) -> list[Candidate]:
        """Every candidate not yet in the model.

        ``excluded``: periodic ``(joint, harmonic, session)`` not to screen
        again; ``excluded_causes``: other candidates not to screen again;
        ``torques``: a function giving the gravity torques of the
        calibration poses under ``current``.
        """
        have = set(accepted)
        out: list[Candidate] = []
        revolute = [j for j, jt in enumerate(self.robot.joints, start=1) if not jt.prismatic]
        for j in revolute:
            out += [Candidate("joint_compliance", j), Candidate("encoder_scale", j),
                    Candidate("backlash", j, source="torque"), Candidate("backlash", j, source="motion")]
        # a linear axis' own errors (ISO 230-1): its scale (per metre), its play by the load (a column's weight) and
        # by the motion, its straightness across it and its carriage's roll, pitch and yaw as it travels
        for j in (j for j in range(1, self.robot.n + 1) if j not in revolute and np.ptp(self.cal.q[:, j - 1]) > 0):
            out += [Candidate("encoder_scale", j), Candidate("backlash", j, source="motion")]
            if np.max(np.abs(torques()[:, j - 1]), initial=0.0) >= NO_TORQUE:    # a column: its weight loads it
                out.append(Candidate("backlash", j, source="torque"))
            out += [Candidate("straightness", j, direction=d) for d in STRAIGHTNESS_DIRECTIONS]
            out += [Candidate("carriage_angle", j, angle=a) for a in CARRIAGE_ANGLES]
        several = len(self.sessions) > 1
        moving = [j for j in revolute if np.ptp(self.cal.q[:, j - 1]) > 0]
        # a coupling's source joint comes before it: a drive train passes through the joints before its joint;
        # none on poses that move one joint at a time (not_tried says why)
        if self.couples is None:
            self.couples = not one_at_a_time(self.cal)
        out += [Candidate("joint_coupling", j, source_joint=k) for j in moving for k in moving if k < j
                and self.couples]
        if self.mount is None:
            self.mount = [s for s in [None] + (self.sessions if several else [])
                          if moment_changes(self.robot, self.cal if s is None else
                                            self.cal.subset(self.cal.sessions == s))]
        out += [Candidate("mount_compliance", session=s) for s in self.mount]
        temp = self.cal.get("temperature_c")
        if temp is not None and np.ptp(temp) > 0.1:
            out.append(Candidate("thermal_expansion"))
            out += [Candidate("thermal_expansion", j) for j, jt in enumerate(self.robot.joints, start=1)
                    if abs(jt.a) + abs(jt.d) + abs(jt.b or 0.0) > 0]
        if several:      # each session's own, of every kind of one joint
            out += [replace(c, session=s) for c in out if c.cause in PER_JOINT for s in self.sessions]
        # a progressive spring where the joint's compliance is named (the robot's or the session's)
        out += [Candidate("nonlinear_stiffness", a.joint, session=a.session) for a in accepted
                if a.cause == "joint_compliance"]
        # a drift and a warm-up need the poses' times (never the row numbers); of one session by nature
        if self.cal.get("time_s") is not None:
            scopes = self.sessions if several else [None]
            out += [Candidate("drift", session=s) for s in scopes]
            if not any(a.cause == "warmup" and a.session is None for a in accepted):
                out += [Candidate("warmup", session=s, time_constant=T) for s in scopes
                        if not any(a.cause == "warmup" and a.session == s for a in accepted)
                        for T in self.warmups.get(s, [])]
        out += self.user_candidates()
        self.update_periodograms(current)
        scopes = [(None, self.periodograms)] + list(self._own.items())
        for s, grams in scopes:
            for j, pg in enumerate(grams, start=1):
                if j not in revolute and np.ptp(self.cal.q[:, j - 1]) <= 0:
                    continue
                # a linear axis' from MIN_CYCLES cycles over its travel (lowest_harmonic), a joint's from the first
                low = 1 if j in revolute else lowest_harmonic(self.cal, j)
                ranked = [int(h) for h in pg.harmonics[np.argsort(-pg.power)] if (j, int(h), s) not in excluded
                          and h >= low][:2]
                # the first harmonic always: over a small range it mimics an encoder scale error,
                # and the ambiguity can only be reported if both are screened
                hs = set(ranked) | ({low} if (j, low, s) not in excluded and low <= pg.harmonics.max(initial=0)
                                    else set())
                out += [Candidate("joint_periodic", j, h, session=s) for h in sorted(hs)]
        # a joint's play by the load and by the motion are both screened while the other is in the model: where
        # the last move follows the joint's reading (random poses in row order) the load's sign stands for the
        # motion's and a compliance together, and neither of these can come in beside it; the final check
        # (:func:`.redundancy.drop_redundant`) drops the stand-in once both are in
        return [c for c in dict.fromkeys(out) if c not in have and c not in excluded_causes
                and not (c.cause == "backlash" and not self.sign_changes(torques, c))]

    def user_candidates(self) -> list[Candidate]:
        """The causes of the user's own (a terms file's, known during the command): each the robot's (scope
        ``robot``) and, with several sessions, each session's own (scope ``robot`` or ``session``); none without
        a terms file."""
        out = []
        for d in known().values():
            cand = Candidate(d.name, d.joints[0] if d.one_joint else None,
                             user=tuple(f"{d.name}.{p}" for p in d.parameter_names))
            several = len(self.sessions) > 1
            if d.scope == "robot" or not several:
                out.append(cand)
            if several:
                out += [replace(cand, session=s) for s in self.sessions]
        return out

    def sign_changes(self, torques, cand: Candidate) -> bool:
        """Backlash needs its sign source to change sign in the data: otherwise it is a joint offset."""
        j = cand.joint
        signs = self.cal.moves[:, j - 1] if cand.source == "motion" else np.sign(torques()[:, j - 1])
        if cand.session is not None:
            signs = signs[self.cal.sessions == cand.session]
        return sign_changes(signs, "")[0]
