"""The diagnosis in words: what it means for the robot, each finding in a few words, its size, what to do.

The reports (terminal summary, HTML page, JSON) open with one row per
finding: a short label, where it lives, its size in the final model (with
its relative standard error), its gain on the validation poses, whether it
is of the robot or of the measurement session, and one line saying what to
do. These functions make those cells from a :class:`~.report.Finding` and
the final model; they never compute anything the diagnosis did not decide.
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..result import CalibrationResult
    from .report import DiagnosisReport, Finding

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


def gain_words(drop_mm: float | None, digits: int = 4, unit: str = " mm") -> str:
    """A drop of an error in words, never a signed number: ``0.0292 mm better``, ``0.0030 mm worse``."""
    if drop_mm is None or not math.isfinite(drop_mm):
        return "-"
    if round(drop_mm, digits) == 0:
        return "no change"
    return f"{abs(drop_mm):.{digits}f}{unit} {'better' if drop_mm > 0 else 'worse'}"


def g3(x: float) -> str:
    """Three significant digits, a power of ten written short: ``5.38e4``, ``0.0123``."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), f"{x:.3g}")


def relative(std: float, value: float) -> str:
    """`` +- 6.2 %``: a standard error relative to its value ('' when unknown)."""
    if not (math.isfinite(std) and math.isfinite(value)) or value == 0:
        return ""
    r = 100 * abs(std / value)
    return f" +- {r:.1f} %" if r < 10 else f" +- {r:.0f} %" if r < 1000 else " +- > 999 %"


def label(f: "Finding") -> str:
    """A finding in a few words: ``geometry``, ``compliance j2``, ``periodic j2 h17``, ``drift @B``,
    ``coupling j6<-j5``, ``mount compliance``, ``GP compensator``, ``unexplained j1``."""
    c = f.candidate
    if c.cause == "geometric":
        return "geometry"
    if c.cause == "unexplained":
        return "GP compensator" if f.in_model else f"unexplained j{c.joint}" if c.joint else "unexplained"
    return c.label(short=True)


def where(f: "Finding") -> str:
    """Where a finding lives: ``joint 2``, ``link 3``, ``measurement frame, session B``, ..."""
    c = f.candidate
    if c.cause == "geometric":
        return "links, base and tool"
    if c.cause == "unexplained":
        if f.in_model:
            sessions = [s for s in (f.holds_up or {}).get("length_scales_deg", {}) if s]
            return "what the causes leave" + (f", sessions {', '.join(sessions)}" if len(sessions) > 1 else "")
        if f.structure:
            return _structure_where(f.structure, c.joint)
        return f"joint {c.joint}" if c.joint else ""
    if c.cause == "thermal_expansion":
        text = "every link" if c.joint is None else f"link {c.joint}"
    elif c.cause == "drift":
        text = "measurement frame"
    elif c.cause == "mount_compliance":
        text = "the base's mount"
    elif c.cause == "straightness":
        text = f"axis {c.joint}, across it in {c.direction}"
    elif c.cause == "carriage_angle":
        text = f"axis {c.joint}'s carriage, {c.angle}"
    elif c.cause == "joint_coupling":
        text = f"joint {c.joint}, from joint {c.source_joint}'s reading"
    else:
        text = f"joint {c.joint}"
    if c.cause == "backlash":
        text += ", by the last move" if c.source == "motion" else ", by the load"
    return text + (f", session {c.session}" if c.session is not None else "")


def _structure_where(structure: dict, joint: int | None) -> str:
    """Where structure the screen found lives, short: ``joint 4's angle, with q3``."""
    effect = {"angle": f"joint {joint}'s angle", "position": f"axis {joint}'s position",
              "tilt": f"joint {joint}'s axis" if joint else "the base's tilt",
              "point_base": "point, base frame",
              "point_measurement": "point, measurement frame"}.get(structure["effect"], structure["effect"])
    return f"{effect}, with {structure['covariate']}"


def size(f: "Finding", final: "CalibrationResult") -> str:
    """The finding's size in the final model, with its relative standard error."""
    c = f.candidate
    if c.cause == "geometric":
        n = sum(1 for p in final.parameters if p.term == "geometric" and not p.fixed and not p.name.startswith(
            "base_"))
        return f"{n} link and tool parameters"
    if c.cause == "unexplained":
        hu = f.holds_up or {}
        if f.in_model:
            k, n = hu.get("validation_known", [None, None])
            return f"applies at {k} of {n} validation poses" if n else "a Gaussian process per session"
        if f.structure:
            return f"{f.structure['size_mm']:.4f} mm on validation"
        items = hu.get("structures", [])
        if not items:
            return ""
        big = max(items, key=lambda x: x.get("amplitude_arcsec", 0.0))
        return big.get("what", "") + (f" and {len(items) - 1} more" if len(items) > 1 else "")
    names = c.parameter_names()
    if any(n not in final.parameters.names for n in names):
        return ""
    P = [final.parameters[n] for n in names]
    v = np.array([p.value for p in P])
    s = np.array([p.std for p in P])
    if c.cause in ("straightness", "carriage_angle") or (c.joint is not None and c.cause in (
            "encoder_scale", "joint_periodic", "backlash") and final.model.robot.joints[c.joint - 1].prismatic):
        return linear_size(c, v, s, P)
    if c.cause == "joint_compliance":
        if v[0] <= 0:
            return f"{names[0]} = {g3(v[0])} rad/(N m), not positive"
        return f"k{c.joint} = {g3(1 / v[0])} N m/rad{relative(s[0], v[0])}"
    if c.cause == "nonlinear_stiffness":
        how = "stiffens" if v[1] < 0 else "softens"
        return f"cubic term {g3(v[1])} rad/(N m)^3{relative(s[1], v[1])}: {how} with load"
    if c.cause == "joint_periodic":
        amp, std = amplitude(v, s)
        return f"{c.harmonic} cycles/turn, {math.degrees(amp) * 3600:.1f} arcsec{relative(std, amp)}"
    if c.cause == "encoder_scale":
        return f"{v[0] * 1e6:.0f} ppm{relative(s[0], v[0])}"
    if c.cause == "backlash":
        return f"half play {math.degrees(v[0]) * 3600:.1f} arcsec{relative(s[0], v[0])}"
    if c.cause == "thermal_expansion":
        return f"{v[0] * 1e6:.2f} ppm/K{relative(s[0], v[0])}"
    if c.cause == "joint_coupling":
        return f"{v[0] * 1e3:.3g} mrad per rad of joint {c.source_joint}{relative(s[0], v[0])}"
    if c.cause == "mount_compliance":
        return f"tilt {v[0] * 1e6:.3g} mrad per kN m of moment{relative(s[0], v[0])}"
    if c.cause == "drift":
        speed = float(np.linalg.norm(v))
        std = math.sqrt(((v * s) ** 2).sum()) / speed if speed > 0 else math.nan
        return f"{g3(speed * 1e6)} um/s{relative(std, speed)}"
    if c.user:      # a cause of the user's own: its parameters as the parameter table reads them
        return ", ".join(f"{n.split('.', 1)[-1]} = {g3(p.to_reading(p.value))} {p.reading_unit}"
                         + relative(p.std, p.value) for n, p in zip(names, P))
    return ""


def amplitude(v: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """A periodic term's amplitude from its sine and cosine parts ``v``, and its std from theirs ``s`` (along the
    amplitude, linearised)."""
    amp = math.hypot(*v)
    return amp, (math.sqrt(((v * s) ** 2).sum()) / amp if amp > 0 else math.nan)


def travel_curve(values, names: list[str]) -> np.ndarray:
    """A linear axis' straightness or carriage angle over its travel (201 points), from its Legendre coefficients
    (parameters ``..._p<degree>``)."""
    coef = np.zeros(4)
    for v, n in zip(values, names):
        coef[int(n.rsplit("_p", 1)[1])] += v
    return np.polynomial.legendre.legval(np.linspace(-1.0, 1.0, 201), coef)


def linear_size(c, v: np.ndarray, s: np.ndarray, P: list) -> str:
    """A linear axis' cause's size: mm per m, mm, the largest change over the travel (mm, mrad)."""
    if c.cause == "encoder_scale":
        return f"{v[0] * 1e3:.3g} mm per m{relative(s[0], v[0])}"
    if c.cause == "joint_periodic":
        amp, std = amplitude(v, s)
        return f"{c.harmonic} cycles/m, {amp * 1e3:.3g} mm{relative(std, amp)}"
    if c.cause == "backlash":
        return f"half play {v[0] * 1e3:.3g} mm{relative(s[0], v[0])}"
    curve = travel_curve(v, [p.name for p in P])
    return f"{np.ptp(curve) * 1e3:.3g} {'mm' if c.cause == 'straightness' else 'mrad'} over the travel"


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
    if f.cause == "geometric":
        return "robot"
    return "one session" if f.in_model else "-"


def action(f: "Finding", report: "DiagnosisReport") -> str:
    """What to do about a finding, in one line."""
    c = f.candidate
    other = _name(report.transfer.get("file", "")) if report.transfer else ""
    if c.cause == "geometric":
        return ("use the calibrated geometry: export writes it as URDF and a DH table (compensate uses the full "
                "model)")
    if c.cause == "unexplained" and f.in_model:
        return ("applies in this session where it knows; compensate and predict use it; a transfer to another "
                "session drops it (scope session)")
    if c.cause == "unexplained" and f.structure:
        instrument = f.structure["covariate"] in ("azimuth", "elevation", "distance")
        return (f"a cause no catalogue holds (a flexible term would give {gain_words(f.potential_gain_mm)} here): "
                "state it as a term of your own (the finding's term in the JSON report is one to start from) and "
                "diagnose again (docs/guide.md, 'When the report says unexplained'); plan-poses REPORT.json plans "
                "the poses that tell its form"
                + ("; a session with the instrument placed elsewhere tells the instrument's error from the robot's"
                   if instrument else ""))
    if c.cause == "unexplained":
        j = c.joint
        gain_here = gain_words(f.potential_gain_mm)
        return (f"not in the model (it would give {gain_here} here): measure joint {j} over a wider range or in "
                "another session to tell")
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
    from .candidates import Candidate

    return Candidate(**{k: a[k] for k in ("cause", "joint", "harmonic", "source", "session", "source_joint",
                                          "direction", "angle") if k in a}).label(short=True)


def _name(path: str) -> str:
    return path.replace("\\", "/").rsplit("/", 1)[-1]


def table(header: list[str], rows: list[list[str]], indent: str = "  ", right: tuple[int, ...] = ()) -> list[str]:
    """A plain-text table: columns as wide as their widest cell (``right``: right-aligned columns)."""
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]

    def line(cells):
        return indent + "  ".join(str(x).rjust(w) if k in right else str(x).ljust(w)
                                  for k, (x, w) in enumerate(zip(cells, widths))).rstrip()
    return [line(header)] + [line(r) for r in rows]
