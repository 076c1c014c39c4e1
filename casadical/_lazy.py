"""A package's public names imported on first use (PEP 562), so that importing one module imports no other."""

from importlib import import_module
from importlib.util import find_spec
from typing import Callable


def lazy(package: str, namespace: dict, exports: dict[str, str]) -> tuple[Callable, Callable]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` (its ``globals()`` as ``namespace``): a public name of
    ``exports`` (name -> its module, relative to the package) or a submodule (``_name``: the modules of a subpackage
    are private), imported on first use and kept."""

    def __getattr__(name: str):
        module = exports.get(name)
        if module is not None:
            value = getattr(import_module(f".{module}", package), name)
        elif not name.startswith("__") and find_spec(f"{package}.{name}") is not None:   # (private ones too)
            value = import_module(f".{name}", package)
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    # a public name its module shares (``planning.observability``) is bound now: importing the module later (by
    # any path) would set the package's attribute to the module, and ``__getattr__`` would never be asked
    for name, module in exports.items():
        if name == module:
            namespace[name] = getattr(import_module(f".{module}", package), name)

    return __getattr__, __dir__
