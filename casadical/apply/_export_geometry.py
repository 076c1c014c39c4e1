"""The best geometric model of a calibration: what a URDF or a DH table can carry of it.

A URDF and a controller's DH table hold geometry only. A calibration whose
model has more (joint compliance, a progressive spring, gear errors,
encoder scale, backlash, thermal expansion) fitted its geometry *together
with* those terms, so its geometry alone is not the best geometry: on the
UR10 data the diagnosed model's own link parameters, written to a URDF,
predict held-out poses to 0.94 mm where a plain kinematic calibration's
URDF gives 0.41 mm.

:func:`geometric_equivalent` refits the geometry alone to reproduce the
full physical model (the causes of the robot: terms of the measurement
session, such as a drift or the GP compensator, are left out) over
the calibrated workspace: the calibration's own poses, at a stated
payload (a file written by an earlier version holds none: then poses
drawn within the joint limits, said in a warning). What the geometry cannot reproduce is reported as its departure
from the full model (mean and largest, mm); ``compensate`` with the full
model gives the rest.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..data._measurements import Measurements
from ..data._simulate import sample_poses
from ..errors import CasadicalWarning, InputError
from ..model._symbolic import Model
from ..result import CalibrationResult, ErrorStats
from ..terms._geometric import Geometric
from ..terms._tool_orientation import ToolOrientation
from ..terms._tool_points import ToolPoints

#: terms that belong to the geometry (what an export carries) or to a session (what it never does); a tool of
#: several points is the geometry's too (the export's tool point is the robot file's [tool], the rows' without a name)
GEOMETRIC = (Geometric.name, ToolOrientation.name, ToolPoints.name)
#: poses drawn within the joint limits to refit on when a calibration holds none of its own (older files)
DRAWN_POSES = 500


@dataclass
class GeometricEquivalent:
    """A calibration's best geometric model.

    Attributes
    ----------
    result : CalibrationResult
        Geometry only (model ``kinematic``), in the calibration's
        measurement frame (its first session's, with several).
    departure : ErrorStats or None
        How far its tool points are from the full physical model's over the
        poses it was fitted on (None: the calibration is geometry only, and
        is its own equivalent).
    left_out : list of str
        The terms of the calibration the geometry stands in for (physical)
        and those it never holds (of the session).
    payload_kg : float
        The payload the full model was evaluated at.
    n_poses : int
    payload_matters : bool
        The full model's tool points depend on the payload (a compliance, a
        progressive spring): the payload chooses the geometry.
    drawn : bool
        The poses were drawn within the joint limits (the calibration holds
        none of its own: a file of an earlier version).
    """

    result: CalibrationResult
    departure: ErrorStats | None
    left_out: list[str]
    session_terms: list[str]
    payload_kg: float
    n_poses: int
    payload_matters: bool = False
    drawn: bool = False

    def text(self) -> str:
        """What was exported, in words (for the command line and the files' headers)."""
        if self.departure is None:
            return "the calibration's geometry" + (f" (without {', '.join(self.session_terms)}, of its measurement "
                                                   "session)" if self.session_terms else "")
        d = self.departure
        poses = (f"{self.n_poses} poses drawn within the joint limits" if self.drawn
                 else f"its {self.n_poses} calibration poses")
        return (f"the geometry refitted to reproduce the full model ({', '.join(self.left_out)}) over "
                f"{poses} at a payload of {self.payload_kg:g} kg: it departs from the full "
                f"model by {d.mean_mm:.4f} mm on average, {d.max_mm:.4f} mm at most; the full model (compensate) "
                "gives the rest" + (f"; {', '.join(self.session_terms)} (of the measurement session) left out"
                                    if self.session_terms else ""))


def physical_terms(cal: CalibrationResult) -> tuple[list, list]:
    """The calibration's terms beyond the geometry: the robot's (physical) and its session's."""
    physical = [t for t in cal.model.terms if t.name not in GEOMETRIC and not t.session]
    session = [t for t in cal.model.terms if t.session]
    return physical, session


def geometric_equivalent(cal: CalibrationResult, payload_kg: float | None = None,
                         poses_deg: np.ndarray | None = None) -> GeometricEquivalent:
    """The geometry that best reproduces ``cal``'s physical model over its calibration poses.

    Parameters
    ----------
    cal : CalibrationResult
    payload_kg : float, optional
        The payload of the poses (default: the robot file's).
    poses_deg : ndarray (N, n), optional
        The poses (degrees) to reproduce the model over (default: the
        calibration's own, from its coverage; for a file of an earlier
        version, which holds none, :data:`DRAWN_POSES` poses drawn within
        the joint limits, with a warning).

    Raises
    ------
    InputError
        A negative payload.
    """
    from ..calibration import calibrate

    robot = cal.model.robot
    physical, session = physical_terms(cal)
    payload = robot.payload_mass if payload_kg is None else float(payload_kg)
    if not payload >= 0:
        raise InputError(f"the payload must be a mass >= 0 kg, got {payload_kg!r}")
    specs = [t.spec() for t in physical]
    if not physical:
        return GeometricEquivalent(cal, None, [], [t.spec() for t in session if t.name != "sessions"], payload, 0)
    drawn = poses_deg is None and cal.coverage is None
    if drawn:
        poses_deg = robot.to_file_units(sample_poses(robot, DRAWN_POSES, np.random.default_rng(0)))
        warnings.warn(f"the calibration holds no calibration poses (a file of an earlier casadical): its geometry is "
                      f"refitted over {DRAWN_POSES} poses drawn within the joint limits (5 deg inside them, the tool "
                      "above the robot's base), not over the workspace it was calibrated in; --as-fitted exports the "
                      "geometry as it was fitted, or calibrate again to record the poses", CasadicalWarning,
                      stacklevel=2)
    elif poses_deg is None:
        poses_deg = cal.coverage.poses_deg
    q = robot.from_file_units(np.asarray(poses_deg, float))      # deg, mm for a prismatic joint
    full = Model(robot, [t for t in cal.model.terms if not t.session], jit=cal.model.jit)
    values = np.array([cal.parameters[n].value for n in full.parameters.names])
    cov = full.default_covariates(len(q))
    if "payload_kg" in full.covariate_names:
        cov[:, full.covariate_names.index("payload_kg")] = payload
    xyz = full.predict(q, values, cov, cal.base0)
    unloaded = cov.copy()
    if "payload_kg" in full.covariate_names:
        unloaded[:, full.covariate_names.index("payload_kg")] = 0.0 if payload > 0 else 100.0
    matters = bool(np.abs(full.predict(q, values, unloaded, cal.base0) - xyz).max() > 1e-9)
    target = Measurements.from_arrays(q, xyz, prismatic=robot.prismatic, payload_kg=np.full(len(q), payload))
    if cal.has_orientation:   # a full-pose calibration: the geometry reproduces the probe's orientation too
        target = target.with_orientations(full.probe_rotation(q, values, cov, cal.base0) @ cal.tool0)
    target.path = "the full model's tool points"
    # the geometry's own (not a session's tool, nor a named tool point's: the target rows are the robot's tool point)
    start = {p.name: p.value for p in cal.parameters if p.term == Geometric.name and p.group != "base"
             and "@" not in p.name and ":" not in p.name}
    # the loss of a calibration of measured poses (robust, noise scales from the residuals): the geometry weighs
    # the model's departures as a kinematic calibration weighs the data's (the calibration's own, smaller noise
    # scales would make it a least-absolute fit of the departures, 1 % worse on held-out poses)
    geo = calibrate(robot, target, "kinematic" if cal.model.geometric_free else "nominal", "lm", start=start,
                    warn=False, allow_outside_limits=True, robust=cal.loss.kind)
    departure = ErrorStats.of(np.linalg.norm(geo.predict(target) - xyz, axis=1))
    return GeometricEquivalent(geo, departure, specs, [t.spec() for t in session if t.name != "sessions"], payload,
                               len(q), matters, drawn)
