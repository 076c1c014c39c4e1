"""The calibration model: kinematics and named parameters (what the error terms build on), the symbolic
model the terms are assembled into (:mod:`.symbolic`), the superset every candidate model is a mask of,
and the compiled functions kept on disk."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module; imported on first use, so that importing one module of the package does not
#: import the others (PEP 562)
_EXPORTS = {"Model": "symbolic", "parse_spec": "symbolic"}

__all__ = ["Model", "parse_spec"]

if _typing.TYPE_CHECKING:
    from .symbolic import Model, parse_spec
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
