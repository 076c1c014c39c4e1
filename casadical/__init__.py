"""casadical: calibration of industrial robot arms with CasADi and IPOPT."""

from .errors import CasadicalError
from .model import Model, parse_spec
from .parameters import Parameter, Parameters
from .robot import Robot, load_robot

__version__ = "0.1.0"

__all__ = ["CasadicalError", "Model", "Parameter", "Parameters", "Robot", "load_robot",
           "parse_spec", "__version__"]
