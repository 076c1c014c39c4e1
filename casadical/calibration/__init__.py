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
(:mod:`.pipeline`, :data:`~.pipeline.STAGES`), a module per stage:

- :mod:`.prepare` ``prepare_data``: the poses against the robot, the loss, full pose or positions;
- :mod:`.spec` ``read_model_spec``: the terms a specification asks for;
- :mod:`.build` ``build_model``: the model for these data and its free parameters
  (:mod:`.for_data`: covariate references, a base pose per session; :mod:`.further`:
  a calibration taken further);
- :mod:`.start` ``start_pose``: base pose and probe mounting in closed form, the poses' plausibility;
- :mod:`.identify` ``analyse_identifiability``: enough poses, what they cannot identify;
- :mod:`.solve` ``solve_parameters``: the robust solve, and what the fit tells apart;
- :mod:`.precision` ``estimate_precision``: standard errors, correlations, significance;
- :mod:`.outcome` ``note_set_aside``, ``assemble_result``: the poses set aside, the result;
- :mod:`.physics_notes` ``note_physics``: terms that are not physics as fitted;
- :mod:`.rbf_compensator` ``add_rbf_compensator``, :mod:`.gp_compensator` ``add_gp_compensator``: the
  compensators, learnt after the model.

:mod:`.state` holds what a calibration carries from stage to stage.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module (the result's names from casadical.result), imported on first use: a command
#: that reads a calibration (predict) imports the per-session GP compensator, not the pipeline that fits one
_EXPORTS = {"STAGES": "pipeline", "calibrate": "pipeline", "CalibrationResult": ".result",
            "ErrorStats": ".result", "load_calibration": ".result"}

__all__ = ["STAGES", "CalibrationResult", "ErrorStats", "calibrate", "load_calibration"]

if _typing.TYPE_CHECKING:
    from ..result import CalibrationResult, ErrorStats, load_calibration
    from .pipeline import STAGES, calibrate
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
