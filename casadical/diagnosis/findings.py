"""Findings in words: the final model's values, the evidence, and the structure that cannot be named."""

from __future__ import annotations

import functools
import math

import numpy as np

from ..data.measurements import Measurements
from ..result import CalibrationResult
from ..terms.mount_compliance import mount_moments
from .candidates import Candidate
from .evidence import Evidence, Support
from .plots import joint_view, residual_plot
from .report import Finding
from .validation import cv_record, cv_text
from .words import travel_curve


class UnexplainedLog:
    """Significant structure of a joint's angle error that cannot be named as a cause.

    It is kept out of the model and reported as one ``unexplained`` finding
    per joint (where it lives, its size, why it cannot be named, what it
    would give on this series). Its harmonics (or the candidate) are not
    screened again.
    """

    def __init__(self) -> None:
        self.by_joint: dict[int, Finding] = {}
        self.linear: set[int] = set()                      # the robot's linear axes (their causes in mm)
        self.excluded: set[tuple] = set()                  # periodic (joint, harmonic, session or None)
        self.excluded_causes: set[Candidate] = set()       # other candidates
        self.strongest: dict[int, Candidate] = {}          # per joint, for the transfer study

    def add(self, evidence: Evidence) -> None:
        cand, values, checks = evidence.candidate, evidence.values, evidence.support.checks
        j = cand.joint
        linear = j in self.linear      # a linear axis' periodic error and play are in metres
        if cand.cause in ("straightness", "carriage_angle"):
            self.excluded_causes.add(cand)
            v = np.array([values[n] for n in cand.parameter_names() if n in values])
            size = float(np.abs(v).sum()) * 1000.0
            item = {"what": (f"a {cand.direction} straightness of the axis ({size:.3g} mm at most)"
                             if cand.cause == "straightness" else
                             f"a {cand.angle} of its carriage ({size:.3g} mrad at most)")}
        elif cand.cause == "joint_periodic":
            band = checks["resolution"].band if "resolution" in checks else (cand.harmonic, cand.harmonic)
            self.excluded.update((j, h, cand.session) for h in range(band[0], band[1] + 1))
            s_, c_ = (values[n] for n in cand.parameter_names())
            size = math.degrees(math.hypot(s_, c_)) * 3600
            item = {"harmonic": cand.harmonic, "band": list(band), "amplitude_arcsec": size,
                    "what": f"harmonic {cand.harmonic} ({size:.1f} arcsec)"}
            if linear:
                item["what"] = f"{cand.harmonic} cycles per metre ({math.hypot(s_, c_) * 1000:.3g} mm)"
        elif cand.cause == "encoder_scale":
            self.excluded_causes.add(cand)
            v = values[cand.parameter_names()[0]]
            item = {"trend_ppm": v * 1e6, "what": f"a trend along the joint's reading ({v * 1e6:.0f} ppm)"}
            if linear:
                item["what"] = f"a trend along the axis' position ({v * 1e3:.3g} mm per m)"
        elif cand.cause == "backlash":
            self.excluded_causes.add(cand)
            v = math.degrees(values[cand.parameter_names()[0]]) * 3600
            motion = cand.source == "motion"
            if v >= 0:
                what = f"a step with the sign of the joint's {'motion' if motion else 'load'} ({v:.1f} arcsec)"
            elif motion:
                what = f"a lead of {-v:.1f} arcsec in the direction of the joint's last move (play would trail)"
            else:
                what = f"a step of {-v:.1f} arcsec against the sign of the joint's load"
            item = {"half_play_arcsec": v, "what": what}
            if linear:
                item = {"half_play_mm": v / ARCSEC_PER_MM,
                        "what": f"a step with the sign of the axis' {'motion' if motion else 'load'} "
                                f"({v / ARCSEC_PER_MM:.3g} mm)"}
        elif cand.cause == "joint_coupling":
            self.excluded_causes.add(cand)
            v = values[cand.parameter_names()[0]]
            item = {"coupling": v, "what": f"a part that follows joint {cand.source_joint}'s reading "
                                           f"({v * 1e3:.3g} mrad per rad)"}
        elif cand.user:
            self.excluded_causes.add(cand)
            fitted = ", ".join(f"{n} = {values[n]:.4g}" for n in cand.parameter_names() if n in values)
            item = {"what": f"a part the user term {cand.cause} describes ({fitted}, SI units)"}
        else:
            self.excluded_causes.add(cand)
            c = values.get(f"c{j}", 0.0)
            k = 1 / c if c > 0 else math.inf
            item = {"load_compliance": c,
                    "what": (f"a part that follows the joint's load (as if k = {k:.3g} N m/rad"
                             f"{', progressive' if cand.cause == 'nonlinear_stiffness' else ''})") if c > 0 else
                    f"a part that follows the joint's load with the wrong sign (c = {c:.3g} rad/(N m))"}
        f = self.by_joint.get(j)
        if f is None:
            f = self.by_joint[j] = Finding(Candidate("unexplained", j), 0.0, "", in_model=False,
                                           potential_gain_mm=0.0, holds_up={"structures": []})
            self.strongest[j] = cand
        # what was fitted, machine-readable (plan-poses REPORT.json plans the poses that tell it)
        item.update(candidate=cand.to_dict(), values={n: values[n] for n in cand.parameter_names() if n in values},
                    test=evidence.support.test.text(),
                    cv_mm=cv_record(evidence.support.cv_before, evidence.support.cv_after), why=evidence.why)
        if "halves" in checks:
            item["halves"] = [h.to_dict() for h in checks["halves"]]
        structures = f.holds_up["structures"]
        structures.append(item)
        f.potential_gain_mm = max(f.potential_gain_mm or 0.0, evidence.potential_gain_mm)
        f.where = f"joint {j}: " + "; ".join(x["what"] for x in structures)
        f.evidence = (f"structure in joint {j}'s angle error that is significant on the calibration poses but "
                      "cannot be named as a cause: " + " | ".join(f"{x['what']}: {x['why']}" for x in structures)
                      + f". Alone it would lower this series' validation mean by up to {f.potential_gain_mm:.4f} "
                      "mm; it is kept out of the final model because it does not hold up as a cause")


def describe(findings: list[Finding], support: dict[Candidate, Support], before: dict,
             final: CalibrationResult, cal: Measurements) -> None:
    """Fill each accepted finding's parameters, evidence and figure from the final model."""
    view = functools.cache(lambda: joint_view(final, cal))   # made once, by the first figure that needs it
    for f in findings:
        cand = f.candidate
        if cand not in support:
            continue
        checks = support[cand].checks
        f.parameters = param_values(final, cand.parameter_names())
        text = (f"{support[cand].test.text()} on the calibration poses; held-out mean "
                f"{cv_text(support[cand].cv_before, support[cand].cv_after)}")
        for k in ("resolution", "versus_drift", "versus_harmonics"):
            if k in checks:
                text += "; " + checks[k].text()
        if "halves" in checks:
            text += "; " + "; ".join(h.text() for h in checks["halves"])
        size = what(cand, final, cal)
        f.evidence = text + (("; " + size) if size else "")
        f.plot = residual_plot(cand, before.get(cand, final), final, cal, view)


#: a linear axis' parameters in metres read as radians by the arcsec conversions: times this is millimetres
ARCSEC_PER_MM = math.degrees(1.0) * 3600 / 1000.0


def linear_axis_words(cand: Candidate, params: list) -> str:
    """The size of a linear axis' cause in words (mm, mm per m, mrad), from its parameters."""
    v = np.array([p.value for p in params])
    sd = np.array([p.std for p in params])
    j = cand.joint
    if cand.cause == "encoder_scale":
        return f"scale error {v[0] * 1e3:.4g} mm per m of travel of axis {j} (std {sd[0] * 1e3:.2g})"
    if cand.cause == "joint_periodic":
        return (f"amplitude {math.hypot(*v) * 1e3:.3g} mm, phase {math.degrees(math.atan2(v[1], v[0])):.1f} deg, "
                f"{cand.harmonic} cycles per metre of axis {j}")
    if cand.cause == "backlash":
        return (f"half play {v[0] * 1e3:.3g} mm along axis {j} (std {sd[0] * 1e3:.2g}), sign from the "
                f"{'force of gravity along it' if cand.source != 'motion' else 'last move'}")
    if cand.cause in ("straightness", "carriage_angle"):
        curve = travel_curve(v, [p.name for p in params])
        if cand.cause == "straightness":
            return (f"the carriage of axis {j} off its straight line in {cand.direction} by up to "
                    f"{np.ptp(curve) * 1e3:.3g} mm over its travel (a bow and an S: "
                    + ", ".join(f"{c * 1e3:+.3g}" for c in v) + " mm)")
        return (f"the carriage of axis {j} turns in {cand.angle} by up to {np.ptp(curve) * 1e3:.3g} mrad over its "
                "travel (a slope and a bow: " + ", ".join(f"{c * 1e3:+.3g}" for c in v) + " mrad)")
    return ""


def param_values(res: CalibrationResult, names: list[str]) -> dict:
    out = {}
    for name in names:
        p = res.parameters[name]
        out[name] = {"value": p.to_display(p.value),
                     "std": p.to_display(p.std) if math.isfinite(p.std) else None, "unit": p.display_unit}
    return out


def what(cand: Candidate, res: CalibrationResult, cal: Measurements) -> str:
    """The cause's size in words, from the model's values (a cause of one session: its own, ``c2@A``)."""
    P = res.parameters
    names = cand.parameter_names()
    linear = cand.joint is not None and res.model.robot.joints[cand.joint - 1].prismatic
    if linear or cand.cause in ("straightness", "carriage_angle"):
        return linear_axis_words(cand, [P[n] for n in names])
    if cand.cause == "joint_compliance":
        p = P[names[0]]
        k = 1.0 / p.value if p.value > 0 else math.inf
        sk = p.std / p.value ** 2 if p.value > 0 and math.isfinite(p.std) else math.nan
        text = f"stiffness k{cand.joint} = {k:.4g} N m/rad (std {sk:.2g})"
        if cal.get("payload_kg") is not None and np.ptp(cal.get("payload_kg")) > 0:
            text += "; the rows' payloads vary and enter the torques"
        return text
    if cand.cause == "nonlinear_stiffness":
        p = P[names[1]]
        return (f"progressive term {p.value:.3g} rad/(N m)^3 (std {p.std:.2g}): the joint "
                f"{'stiffens' if p.value < 0 else 'softens'} with load")
    if cand.cause == "joint_periodic":
        s_, c_ = (P[n].value for n in cand.parameter_names())
        return (f"amplitude {math.degrees(math.hypot(s_, c_)) * 3600:.2f} arcsec, phase "
                f"{math.degrees(math.atan2(c_, s_)):.1f} deg, {cand.harmonic} cycles per turn of joint {cand.joint}")
    if cand.cause == "encoder_scale":
        return f"scale error {P[names[0]].value * 1e6:.1f} ppm"
    if cand.cause == "backlash":
        return (f"half play {math.degrees(P[cand.parameter_names()[0]].value) * 3600:.2f} arcsec, sign from the "
                f"{'gravity torque' if cand.source != 'motion' else 'last move'}")
    if cand.cause == "thermal_expansion":
        where = "every length" if cand.joint is None else f"the lengths of link {cand.joint}"
        return f"expansion {P[cand.parameter_names()[0]].value * 1e6:.2f} ppm/K of {where}"
    if cand.cause == "joint_coupling":
        p = P[names[0]]
        return (f"joint {cand.joint}'s angle error, {p.value * 1e3:.3g} mrad per rad of joint {cand.source_joint} "
                f"(std {p.std * 1e3:.2g})")
    if cand.cause == "mount_compliance":
        p = P[names[0]]
        M = np.linalg.norm(mount_moments(res.model.robot, cal.q, cal.get("payload_kg")), axis=1).max(initial=0.0)
        return (f"the base tilts {p.value * M * 1e3:.3g} mrad at the largest moment of these poses ({M:.4g} N m; "
                f"compliance {p.value:.3g} rad/(N m), std {p.std:.2g})")
    if cand.cause == "drift":
        v = np.array([P[n].value for n in cand.parameter_names()]) * 1e6
        return (f"the measured points move {np.linalg.norm(v):.3g} um per s (x, y, z: "
                + ", ".join(f"{c:+.3g}" for c in v) + ")")
    if cand.cause == "warmup":
        v = np.array([P[n].value for n in cand.parameter_names()]) * 1000
        return (f"the first poses stand {np.linalg.norm(v):.3g} mm off (x, y, z: " + ", ".join(f"{c:+.3g}" for c in v)
                + f" mm), dying away with a time constant of {cand.time_constant:.3g} s")
    return ""
