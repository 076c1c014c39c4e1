"""casadical: calibration of industrial robot arms with CasADi and IPOPT."""

import typing as _typing

from ._lazy import lazy

__version__ = "0.1.0"

#: public name -> its module; imported on first use, so that commands which need no model (``split``,
#: ``--help``) start without CasADi (PEP 562)
_EXPORTS = {"CalibrationResult": "result", "calibrate": "calibration", "load_calibration": "result",
            "Measurements": "data._measurements", "CasadicalError": "errors", "Model": "model._symbolic",
            "parse_spec": "model._symbolic", "Parameter": "parameters", "Parameters": "parameters",
            "Robot": "robot", "load_robot": "loading"}

__all__ = ["CalibrationResult", "CasadicalError", "Measurements", "calibrate", "load_calibration", "Model", "Parameter",
           "Parameters", "Robot", "load_robot", "parse_spec", "__version__"]

if _typing.TYPE_CHECKING:
    from .calibration import calibrate
    from .data._measurements import Measurements
    from .errors import CasadicalError
    from .loading import load_robot
    from .model._symbolic import Model, parse_spec
    from .parameters import Parameter, Parameters
    from .result import CalibrationResult, load_calibration
    from .robot import Robot
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
