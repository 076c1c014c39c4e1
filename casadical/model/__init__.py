"""The calibration model: kinematics and named parameters (what the error terms build on), the symbolic
model the terms are assembled into (:mod:`.symbolic`), the superset every candidate model is a mask of,
and the compiled functions kept on disk."""

import typing as _typing
from importlib import import_module as _import_module
from importlib.util import find_spec as _find_spec

#: public name -> its module; imported on first use, so that importing one module of the package does not
#: import the others (PEP 562)
_EXPORTS = {"Model": "symbolic", "parse_spec": "symbolic"}

__all__ = ["Model", "parse_spec"]

if _typing.TYPE_CHECKING:
    from .symbolic import Model, parse_spec
else:
    def __getattr__(name: str):
        """A public name, or a submodule."""
        module = _EXPORTS.get(name)
        if module is not None:
            value = getattr(_import_module(f".{module}", __name__), name)
        elif not name.startswith("_") and _find_spec(f"{__name__}.{name}") is not None:
            value = _import_module(f".{name}", __name__)
        else:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        globals()[name] = value
        return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
