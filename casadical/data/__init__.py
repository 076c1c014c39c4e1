"""Measurements and the files around them: the CSV contract, sessions, simulated data with known truth,
plausibility checks of poses, and the validation of a calibration file."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module; imported on first use, so that importing one module of the package does not
#: import the others (PEP 562)
_EXPORTS = {"Measurements": "measurements"}

__all__ = ["Measurements"]

if _typing.TYPE_CHECKING:
    from .measurements import Measurements
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
