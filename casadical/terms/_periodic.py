"""Periodic transmission (gear) error: A sin(h q_j + phi) on a joint."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .._format import relative
from ..errors import ModelError
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register
from ._cause import Cause, register_cause

#: largest amplitude admitted of a linear axis' periodic error (m, each of its two parts)
MAX_PITCH_ERROR = 1e-3


def phase(robot: Robot, j: int, q):
    """What joint ``j``'s harmonics are multiples of: its reading (rad), or ``2 pi`` times a linear axis' reading
    (m): cycles per metre (numpy or CasADi)."""
    return 2 * math.pi * q if robot.joints[j - 1].prismatic else q


@register
class JointPeriodic(ErrorTerm):
    """Harmonic ``h`` of joint ``j``: ``s sin(h q_j) + c cos(h q_j)``.

    On a linear axis (a prismatic joint) harmonic ``h`` is ``h`` cycles per metre of travel (a screw's or a
    rack's pitch error: a 10 mm pitch is harmonic 100): ``s sin(2 pi h q_j) + c cos(2 pi h q_j)``, ``s`` and
    ``c`` in metres along the axis (at most 1 mm each), as a revolute joint's are per turn in rad.

    Written linearly in ``s`` and ``c`` (amplitude ``hypot(s, c)``, phase
    ``atan2(c, s)``) so the fit has no local minima in the phase.

    Parameters
    ----------
    harmonics : list of (joint, harmonic)
        Pairs to model, e.g. ``[(2, 1), (2, 30)]``.
    """

    name = "joint_periodic"
    aliases = ("periodic",)
    cause = "joint_periodic"
    session_local = True

    def superset_member(self) -> bool:
        """The superset expresses it (its chain offsets: a harmonic's sine and cosine)."""
        return True

    def group_key(self, p: Parameter):
        """A harmonic of a joint: ``gear2_s17`` (or ``gear2_s17@B``) -> (2, 17)."""
        return (p.joint, int(p.name.split("@")[0].rsplit("_", 1)[1][1:])) if "_" in p.name else p.joint

    def weak_words(self, keys: list, joints: list[int]) -> tuple[str, str, str]:
        return ("the periodic error at " + ", ".join(f"{h} cycles per turn of joint {j}" for j, h in keys) + " is",
                "measure poses spread over " + ("its joint's" if len(joints) == 1 else "their joints'") + " range",
                f"drop {'it' if len(keys) == 1 else 'them'} from the model")

    def without(self, kept: list[Parameter], dropped: list) -> str:
        left = [jh for jh in self.harmonics if jh not in dropped]
        return f"{self.name}[{','.join(f'{j}:{h}' for j, h in left)}]" if left else ""

    def fitted_causes(self, names, joint_of, where) -> list:
        """(sine, cosine) pairs, in the order of the harmonics."""
        return [(j, list(pair), f"periodic error of joint {j}, harmonic {h}{where}")
                for (j, h), pair in zip(self.harmonics, zip(names[0::2], names[1::2]))]

    @classmethod
    def arguments(cls, args: str) -> dict:
        """``joint_periodic[2:1,2:17]``: (joint, harmonic) pairs."""
        harmonics = [tuple(int(x) for x in a.split(":")) for a in args.split(",")]
        if any(len(h) != 2 for h in harmonics):
            raise ValueError("expected joint:harmonic pairs, e.g. periodic[2:1,2:17]")
        return {"harmonics": harmonics}

    def __init__(self, harmonics: list[tuple[int, int]]):
        if not harmonics:
            raise ModelError("joint_periodic needs (joint, harmonic) pairs, e.g. periodic[2:1]")
        self.harmonics = sorted({(int(j), int(h)) for j, h in harmonics})
        if any(h < 1 for _, h in self.harmonics):
            raise ModelError("joint_periodic harmonics must be whole numbers >= 1")
        super().__init__(sorted({j for j, _ in self.harmonics}))

    def spec(self) -> str:
        return f"{self.name}[{','.join(f'{j}:{h}' for j, h in self.harmonics)}]"

    def settings(self) -> dict:
        return {"harmonics": [list(p) for p in self.harmonics]}

    def parameters(self, robot: Robot) -> list[Parameter]:
        ps = []
        for j, h in self.harmonics:
            linear = robot.joints[j - 1].prismatic if 1 <= j <= robot.n else False
            for kind in ("s", "c"):
                if linear:
                    ps.append(Parameter(f"gear{j}_{kind}{h}", 0.0, "m", 1e-5, self.name, j,
                                        lower=-MAX_PITCH_ERROR, upper=MAX_PITCH_ERROR))
                else:
                    ps.append(Parameter(f"gear{j}_{kind}{h}", 0.0, "rad", 1e-4, self.name, j,
                                        lower=-math.radians(1.0), upper=math.radians(1.0)))
        return ps

    def joint_offsets(self, ctx: Context) -> dict:
        out: dict = {}
        for j, h in self.harmonics:
            qj = phase(ctx.robot, j, ctx.q[j - 1])
            term = ctx.p[f"gear{j}_s{h}"] * ca.sin(h * qj) + ctx.p[f"gear{j}_c{h}"] * ca.cos(h * qj)
            out[j] = out.get(j, 0) + term
        return out


def amplitude(v: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """A periodic term's amplitude from its sine and cosine parts ``v``, and its std from theirs ``s`` (along the
    amplitude, linearised)."""
    amp = math.hypot(*v)
    return amp, (math.sqrt(((v * s) ** 2).sum()) / amp if amp > 0 else math.nan)


class GearError(Cause):
    """A periodic transmission error of a joint, one harmonic a candidate (:class:`JointPeriodic`)."""

    name = "joint_periodic"
    unchecked_by = "period"
    analytic = True
    own_variable = "q"
    of_own_reading = True
    checks = ("reading_halves", "resolution")
    needs = {"still_axis": "joint_periodic", "still": "joint_periodic", "short_range": "joint_periodic (low harmonics)",
             "low_linear": "joint_periodic (low harmonics of a linear axis)",
             "high_harmonics": "joint_periodic (high harmonics)"}
    short = "periodic"
    scanned = True
    tier = 4
    order = 30
    varies_text = "move joint {j} over a wider range"

    def candidates(self, data) -> list:
        """From the periodograms of the residual's joint angle errors over every pose (a gear is the robot's: one
        in every session): a joint's two strongest harmonics not excluded, and its lowest always (over a small
        range it mimics an encoder scale error, and the ambiguity can only be reported if both are screened)."""
        out = []
        for j, pg in enumerate(data.periodograms, start=1):
            if j not in data.revolute and np.ptp(data.cal.q[:, j - 1]) <= 0:
                continue
            low = data.lowest_harmonic(j)
            ranked = [int(h) for h in pg.harmonics[np.argsort(-pg.power)] if (j, int(h), None) not in data.excluded
                      and h >= low][:2]
            hs = set(ranked) | ({low} if (j, low, None) not in data.excluded and low <= pg.harmonics.max(initial=0)
                                else set())
            out += [data.make(self.name, j, h) for h in sorted(hs)]
        return out

    def size(self, cand, values, stds, params, linear) -> str:
        amp, std = amplitude(values, stds)
        if linear:
            return f"{cand.harmonic} cycles/m, {amp * 1e3:.3g} mm{relative(std, amp)}"
        return f"{cand.harmonic} cycles/turn, {math.degrees(amp) * 3600:.1f} arcsec{relative(std, amp)}"

    def unexplained_item(self, cand, values, linear) -> dict:
        s_, c_ = (values[n] for n in cand.parameter_names())
        size = math.degrees(math.hypot(s_, c_)) * 3600
        item = {"amplitude_arcsec": size, "what": f"harmonic {cand.harmonic} ({size:.1f} arcsec)"}
        if linear:
            item["what"] = f"{cand.harmonic} cycles per metre ({math.hypot(s_, c_) * 1000:.3g} mm)"
        return item

    def words(self, cand, params, robot, data, linear) -> str:
        s_, c_ = (p.value for p in params)
        if linear:
            return (f"amplitude {math.hypot(s_, c_) * 1e3:.3g} mm, phase {math.degrees(math.atan2(c_, s_)):.1f} deg, "
                    f"{cand.harmonic} cycles per metre of axis {cand.joint}")
        return (f"amplitude {math.degrees(math.hypot(s_, c_)) * 3600:.2f} arcsec, phase "
                f"{math.degrees(math.atan2(c_, s_)):.1f} deg, {cand.harmonic} cycles per turn of joint {cand.joint}")

    def figure(self, cand, data, model, params, linear) -> dict:
        j, h = cand.joint, cand.harmonic
        q = data.q[:, j - 1]
        sn, cs = (params[n].value for n in cand.parameter_names())
        if linear:
            arg = phase(model.robot, j, h * q)
            return {"x": np.degrees(arg) % 360.0, "xlabel": f"phase of {h} cycles per metre of axis {j} (deg)",
                    "effect": sn * np.sin(arg) + cs * np.cos(arg)}
        # folded by the harmonic, h cycles per turn line up into one sinusoid
        return {"x": np.degrees(h * q) % 360.0, "xlabel": f"phase of {h} cycles per turn of joint {j} (deg)",
                "effect": sn * np.sin(h * q) + cs * np.cos(h * q)}

    def analytic_term(self, cand):
        return JointPeriodic([(cand.joint, cand.harmonic)])

    def analytic_column(self, cand, k, data, JA, t0, robot):
        # its k-th column alone (sin, then cos: the same numbers, not both made for each)
        x = cand.harmonic * phase(robot, cand.joint, data.q[:, cand.joint - 1])
        return JA[:, :, cand.joint - 1] * (np.sin(x) if k == 0 else np.cos(x))[:, None]

    def parameter_names(self, cand) -> list[str]:
        return [f"gear{cand.joint}_s{cand.harmonic}", f"gear{cand.joint}_c{cand.harmonic}"]

    def terms(self, cands) -> list[ErrorTerm]:
        per = sorted({(c.joint, c.harmonic) for c in self.mine(cands)})
        return [JointPeriodic(harmonics=per)] if per else []


JOINT_PERIODIC = register_cause(GearError())
