"""Readers that convert third-party measurement files to the casadical CSV contract.

:mod:`.mapped` imports any delimited tracker file with a column mapping
(:mod:`.column_map`: a TOML file, a preset in ``presets/`` or ``key=value``
pairs); :mod:`.ur10` is the ``ur10-ipa`` preset under its historical names.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"ColumnMap": "column_map", "load_column_map": "column_map", "presets": "column_map", "Imported": "mapped",
            "import_file": "mapped", "read_mapped": "mapped"}

__all__ = ["ColumnMap", "Imported", "import_file", "load_column_map", "presets", "read_mapped"]

if _typing.TYPE_CHECKING:
    from .column_map import ColumnMap, load_column_map, presets
    from .mapped import Imported, import_file, read_mapped
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
