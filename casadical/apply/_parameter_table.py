"""The controller-ready parameter table: nominal, identified, difference and std of every
geometric parameter in the robot's own convention (what a controller's calibration offsets
are entered from), plus the base pose, the tool and any joint compliance.

Angles in degrees, lengths in mm, as in the calibration JSON.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..parameters import Parameter
from ..robot import Robot
from ..terms import make_term
from ..terms._compliance import JointCompliance
from ..terms._geometric import Geometric

if TYPE_CHECKING:
    from ..result import CalibrationResult

COLUMNS = ("joint", "name", "unit", "nominal", "identified", "difference", "std", "identifiable", "fixed",
           "reason")
TRANSFORMS = {
    "mdh": "modified DH (Craig): link i = Rx(alpha) Tx(a) Rz(q + theta) Tz(d)",
    "dh": "standard DH: link i = Rz(q + theta) Tz(d) Tx(a) Rx(alpha)",
}
#: where Hayati's beta (and b) enter the link transform of each convention
HAYATI = {"mdh": "Ry(beta) Ty(b) after Tx(a)", "dh": "Ry(beta) Ty(b) after Rx(alpha)"}
#: significant digits of the CSV's numbers: a value converted from metres or radians (-0.5723 m -> -572.3 mm)
#: reads as written, not -572.3000000000001 (the conversion's rounding, 1e-16 relative)
DIGITS = 15
#: what the base pose rows are (a calibration's): not parameters with a nominal value
BASE_REASON = "a pose, not a parameter: where the robot stands in the measurement frame"


@dataclass
class TableRow:
    """One parameter; numbers in display units (deg, mm, ...), NaN where there is none."""

    joint: int | None
    name: str
    unit: str
    nominal: float
    identified: float
    difference: float
    std: float
    identifiable: bool | None
    fixed: bool | None
    reason: str = ""

    def cells(self) -> list:
        return [self.joint, self.name, self.unit, self.nominal, self.identified, self.difference, self.std,
                self.identifiable, self.fixed, self.reason]


@dataclass
class ParameterTable:
    """The rows of :func:`parameter_table` and what the header says about them."""

    robot: str
    convention: str
    model: str
    rows: list[TableRow]
    base: str = "base_pose_* = robot base in the measurement frame"
    #: joints that are linear axes (prismatic: q, in mm, adds to d and theta is constant)
    prismatic: tuple = ()

    @property
    def hayati(self) -> list[int]:
        """Joints with a Hayati ``beta`` or ``b`` row (parameters a plain DH/MDH table has no entry for)."""
        return sorted({r.joint for r in self.rows if r.joint is not None and re.fullmatch(r"(beta|b)\d+", r.name)})

    @property
    def heading(self) -> str:
        joints = self.hayati
        extra = (f" with Hayati's beta on joint{'s' if len(joints) > 1 else ''} {', '.join(map(str, joints))}"
                 if joints else "")
        return f"{self.robot}: {self.convention.upper()} parameter table{extra}"

    @property
    def conventions(self) -> str:
        joints = self.hayati
        link = TRANSFORMS[self.convention]
        if joints:
            link += (f", and for joint{'s' if len(joints) > 1 else ''} {', '.join(map(str, joints))} Hayati's "
                     f"{HAYATI[self.convention]} (a nearly parallel axis, which DH alone cannot describe; a "
                     "controller that takes plain DH has no entry for them)")
        linear = [i for i, p in enumerate(self.prismatic, start=1) if p]
        if linear:
            link += (f"; joint{'s' if len(linear) > 1 else ''} {', '.join(map(str, linear))} prismatic (a linear "
                     "axis): Rz(theta) Tz(d + q), q its reading in mm")
        return (f"{link}; measured point = base * links * Tx(tool_x) Ty(tool_y) Tz(tool_z); angles in deg, lengths "
                f"in mm; {self.base}")

    def to_csv(self) -> str:
        """CSV: one comment line (``#``) with the title, the column names, one line per row; full precision."""
        out = io.StringIO()
        out.write(f"# {self.heading} ({self.model}); {self.conventions}\n")
        w = csv.writer(out, lineterminator="\n")
        w.writerow(COLUMNS)
        for r in self.rows:
            w.writerow([_csv(c) for c in r.cells()])
        return out.getvalue()

    def to_markdown(self) -> str:
        """Markdown: a heading, the conventions, a table rounded for reading (0.1 um, 1e-6 deg), and a
        calibration's base as a pose (a table of its own)."""
        lines = [f"# {self.heading}", "", f"Model: {self.model}; {self.conventions}. Full precision: the CSV "
                 "table.", "", "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
        pose = [r for r in self.rows if r.name.startswith("base_pose_") and r.reason == BASE_REASON]
        for r in self.rows:
            if r not in pose:
                lines.append("| " + " | ".join(_md(c, r.unit) for c in r.cells()) + " |")
        if pose:
            lines += ["", "Robot base in the measurement frame (a pose; its uncertainty is that of the base_* "
                      "deviations in the calibration JSON):", "",
                      "| " + " | ".join(f"{r.name[len('base_pose_'):]} ({r.unit})" for r in pose) + " |",
                      "|" + "---|" * len(pose), "| " + " | ".join(_md(r.identified, r.unit) for r in pose) + " |"]
        return "\n".join(lines) + "\n"


def parameter_table(source: "CalibrationResult | Robot", description: str | None = None) -> ParameterTable:
    """The parameter table of a calibration (identified vs nominal) or of a robot (nominal only).

    Rows, in order: every link parameter in the robot's convention, the tool
    offset, loop lengths (if any), the base pose in the measurement frame,
    then joint compliances ``c<j>`` and the stiffnesses ``k<j> = 1/c<j>``.
    ``std`` is empty where the value was not estimated (fixed, not
    identifiable, nominal) and for the absolute base pose (its uncertainty
    is that of the ``base_*`` deviations in the calibration JSON).
    """
    calibrated = not isinstance(source, Robot)
    if calibrated:
        robot, model = source.model.robot, f"calibration, model {source.model.spec}"
        params = list(source.parameters)
        xyz, rpy = source.base_pose()
        stiffness = source.stiffness()
    else:
        robot, model = source, "nominal values of the robot file"
        params = make_term("geometric").parameters(robot)
        xyz, rpy, stiffness = robot.base_xyz, robot.base_rpy, {}
    rows = [_row(p, calibrated) for p in params if p.term == Geometric.name and p.group != "base"]
    nominal = np.concatenate([robot.base_xyz * 1000, np.degrees(robot.base_rpy)])
    actual = np.concatenate([np.asarray(xyz) * 1000, np.degrees(rpy)])
    for k, axis in enumerate(("x", "y", "z", "roll", "pitch", "yaw")):
        unit = "mm" if k < 3 else "deg"
        if calibrated:      # where the tracker saw the robot: no nominal value, no correction to enter
            rows.append(TableRow(None, f"base_pose_{axis}", unit, math.nan, float(actual[k]), math.nan, math.nan,
                                 True, False, BASE_REASON))
        else:
            rows.append(TableRow(None, f"base_pose_{axis}", unit, float(nominal[k]), float(nominal[k]), 0.0,
                                 math.nan, None, True, "nominal"))
    rows += [_row(p, calibrated) for p in params if p.term == JointCompliance.name]
    for j, (k, sk) in stiffness.items():
        rows.append(TableRow(j, f"k{j}", "N*m/rad", math.nan, k, math.nan, sk, True, False, f"derived: 1/c{j}"))
    base = base_words(source) if calibrated else \
        "base_pose_* = robot base in the measurement frame, the robot file's (nominal)"
    return ParameterTable(robot.name, robot.convention, description or model, rows, base, robot.prismatic)


def base_words(result: "CalibrationResult") -> str:
    """What the ``base_pose_*`` rows are: the reference pose of the calibration moved by its fitted deviations (and
    each other session's base, which the rows do not hold)."""
    def pose(xyz, rpy) -> str:
        return (f"xyz [{', '.join(f'{v * 1000:.3f}' for v in xyz)}] mm, rpy "
                f"[{', '.join(f'{math.degrees(v):.4f}' for v in rpy)}] deg")

    sessions = result.sessions
    text = ("base_pose_* = robot base in the measurement frame" + (f" of session {sessions[0]}" if sessions else "")
            + f": the calibration's reference pose base0 ({pose(*result.base_reference())}, the closed-form "
              "alignment its fit started from) moved by its fitted deviations base_x .. base_yaw")
    for s in sessions[1:]:
        text += (f"; session {s}: its reference {pose(*result.base_reference(s))} moved by base_x@{s} .. "
                 f"base_yaw@{s} gives {pose(*result.base_pose(s))}")
    return text


def _row(p: Parameter, calibrated: bool) -> TableRow:
    """A parameter as in the calibration JSON (display units, flags); a robot's: nominal, fixed."""
    f = p.to_display
    if not calibrated:
        return TableRow(p.joint, p.name, p.display_unit, f(p.nominal), f(p.nominal), 0.0, math.nan, None, True,
                        "nominal")
    return TableRow(p.joint, p.name, p.display_unit, f(p.nominal), f(p.value), f(p.value) - f(p.nominal),
                    f(p.std) if math.isfinite(p.std) else math.nan,
                    bool(p.identifiable) if p.identifiable is not None else not p.fixed, p.fixed, p.reason)


def _csv(c) -> str:
    if c is None or (isinstance(c, float) and math.isnan(c)):
        return ""
    if isinstance(c, bool):
        return "true" if c else "false"
    return repr(float(f"{c:.{DIGITS}g}")) if isinstance(c, float) else str(c)


def _md(c, unit: str) -> str:
    if c is None or (isinstance(c, float) and math.isnan(c)):
        return ""
    if isinstance(c, bool):
        return "yes" if c else "no"
    if isinstance(c, float):
        if unit == "mm":
            return f"{c:.4f}"
        if unit == "deg":
            return f"{c:.6f}"
        return f"{c:.6g}"
    return str(c).replace("|", "\\|")
