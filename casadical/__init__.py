"""casadical: calibration of industrial robot arms with CasADi and IPOPT."""

__version__ = "0.1.0"

from .calibration import CalibrationResult, calibrate, load_calibration
from .data import Measurements
from .errors import CasadicalError
from .model import Model, parse_spec
from .parameters import Parameter, Parameters
from .robot import Robot, load_robot


__all__ = ["CalibrationResult", "CasadicalError", "Measurements", "calibrate", "load_calibration", "Model", "Parameter", "Parameters", "Robot", "load_robot",
           "parse_spec", "__version__"]
