"""casadical: calibration of industrial robot arms with CasADi and IPOPT."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: public name -> its module; imported on first use, so that commands which need no model (``split``,
#: ``--help``) start without CasADi (PEP 562)
_EXPORTS = {"CalibrationResult": "calibration", "calibrate": "calibration", "load_calibration": "calibration",
            "Measurements": "data", "CasadicalError": "errors", "Model": "model", "parse_spec": "model",
            "Parameter": "parameters", "Parameters": "parameters", "Robot": "robot", "load_robot": "robot"}

__all__ = ["CalibrationResult", "CasadicalError", "Measurements", "calibrate", "load_calibration", "Model", "Parameter",
           "Parameters", "Robot", "load_robot", "parse_spec", "__version__"]

if TYPE_CHECKING:
    from .calibration import CalibrationResult, calibrate, load_calibration
    from .data import Measurements
    from .errors import CasadicalError
    from .model import Model, parse_spec
    from .parameters import Parameter, Parameters
    from .robot import Robot, load_robot


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'casadical' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
