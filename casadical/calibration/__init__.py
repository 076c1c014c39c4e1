"""Calibration: measured poses in, a calibrated model with honest uncertainties out.

>>> from casadical import load_robot, calibrate
>>> from casadical.data import Measurements
>>> robot = load_robot("ur10")
>>> data = Measurements.read_csv("problems/datasets/ur10-ipa/series_b.csv", n_joints=6)
>>> result = calibrate(robot, data.subset(slice(0, 300)), "kinematic")   # doctest: +SKIP
>>> print(result.summary())                                              # doctest: +SKIP

Given a calibration instead of a robot, only what the model specification
names is estimated again and every other value is kept: ``base`` re-fits the
base pose alone (a new tracker set-up), ``kinematic`` the geometry (a new
measurement series), ``kinematic+compliance`` the geometry and compliances.

The parameters minimise a robust loss by default (pseudo-Huber, noise scale
from the data, :class:`casadical.problem.RobustLoss`): a bad tracker shot is
down-weighted and reported by its file line instead of pulling the model.

Data with a measured orientation (``rx_deg, ry_deg, rz_deg``: a 6-DoF probe)
are calibrated on the full pose unless ``position_only``: the model gains
the probe's mounting rotation (term ``tool_orientation``, always estimated
like the base pose) and each pose's loss takes its position and orientation
residuals weighted by their noise scales, both estimated from the data.

The package is :func:`calibrate` as a pipeline of named stages
(:mod:`._pipeline`, :data:`~._pipeline.STAGES`), a module per stage:

- :mod:`._prepare` ``prepare_data``: the poses against the robot, the loss, full pose or positions;
- :mod:`._spec` ``read_model_spec``: the terms a specification asks for;
- :mod:`._build` ``build_model``: the model for these data and its free parameters
  (:mod:`._for_data`: covariate references, a base pose per session; :mod:`._further`:
  a calibration taken further);
- :mod:`._start` ``start_pose``: base pose and probe mounting in closed form, the poses' plausibility;
- :mod:`._identify` ``analyse_identifiability``: enough poses, what they cannot identify;
- :mod:`._solve` ``solve_parameters``: the robust solve, and what the fit tells apart;
- :mod:`._precision` ``estimate_precision``: standard errors, correlations, significance;
- :mod:`._outcome` ``note_set_aside``, ``assemble_result``: the poses set aside, the result;
- :mod:`._physics_notes` ``note_physics``: terms that are not physics as fitted;
- :mod:`._rbf_compensator` ``add_rbf_compensator``, :mod:`._gp_compensator` ``add_gp_compensator``: the
  compensators, learnt after the model.

:mod:`._state` holds what a calibration carries from stage to stage.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module (the result's names from casadical.result), imported on first use: a command
#: that reads a calibration (predict) imports the per-session GP compensator, not the pipeline that fits one
_EXPORTS = {"STAGES": "_pipeline", "calibrate": "_pipeline", "CalibrationResult": ".result", "ErrorStats": ".result",
            "load_calibration": ".result", "CalibrationRun": "_state", "DOWNWEIGHT_REPORT": "_outcome",
            "GPCompensatorFolds": "_per_session", "GravityCheck": "_gravity", "Options": "_state", "STD_TOL": "_solve",
            "TOLERANCE_DEG": "_gravity", "check_gravity": "_gravity", "fit_gp_compensator": "_per_session",
            "generic_identifiable": "_identify", "gp_compensator_coverage": "_per_session",
            "gp_compensator_data": "_per_session", "gp_compensator_held_out": "_per_session",
            "mean_mounting": "_start", "merge_terms": "_further", "model_for": "_for_data", "unseen": "_unobservable",
            "warn_gravity": "_gravity", "whole_robot": "_unobservable", "with_gp_compensator": "_per_session"}

__all__ = [
    "CalibrationResult", "CalibrationRun", "DOWNWEIGHT_REPORT", "ErrorStats", "GPCompensatorFolds", "GravityCheck",
    "Options", "STAGES", "STD_TOL", "TOLERANCE_DEG", "calibrate", "check_gravity", "fit_gp_compensator",
    "generic_identifiable", "gp_compensator_coverage", "gp_compensator_data", "gp_compensator_held_out",
    "load_calibration", "mean_mounting", "merge_terms", "model_for", "unseen", "warn_gravity", "whole_robot",
    "with_gp_compensator",
]

if _typing.TYPE_CHECKING:
    from ._for_data import model_for
    from ._further import merge_terms
    from ._gravity import TOLERANCE_DEG, GravityCheck, check_gravity, warn_gravity
    from ._identify import generic_identifiable
    from ._outcome import DOWNWEIGHT_REPORT
    from ._per_session import (
        GPCompensatorFolds,
        fit_gp_compensator,
        gp_compensator_coverage,
        gp_compensator_data,
        gp_compensator_held_out,
        with_gp_compensator,
    )
    from ._pipeline import STAGES, calibrate
    from ._solve import STD_TOL
    from ._start import mean_mounting
    from ._state import CalibrationRun, Options
    from ._unobservable import unseen, whole_robot
    from .result import CalibrationResult, ErrorStats, load_calibration
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
