"""Readers that convert third-party measurement files to the casadical CSV contract.

:mod:`._mapped` imports any delimited tracker file with a column mapping
(:mod:`._column_map`: a TOML file, a preset in ``presets/`` or ``key=value``
pairs); :mod:`._ur10` is the ``ur10-ipa`` preset under its historical names.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"ColumnMap": "_column_map", "load_column_map": "_column_map", "presets": "_column_map",
            "Imported": "_mapped", "import_file": "_mapped", "read_mapped": "_mapped",
            "convert_iso_cubes": "_iso_cubes", "convert_ur10": "_ur10", "mapping_file": "_column_map",
            "read_ur10": "_ur10"}

__all__ = [
    "ColumnMap", "Imported", "convert_iso_cubes", "convert_ur10", "import_file", "load_column_map", "mapping_file",
    "presets", "read_mapped", "read_ur10",
]

if _typing.TYPE_CHECKING:
    from ._column_map import ColumnMap, load_column_map, mapping_file, presets
    from ._iso_cubes import convert_iso_cubes
    from ._mapped import Imported, import_file, read_mapped
    from ._ur10 import convert_ur10, read_ur10
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
