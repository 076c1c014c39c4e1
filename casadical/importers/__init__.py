"""Readers that convert third-party measurement files to the casadical CSV contract.

:mod:`.mapped` imports any delimited tracker file with a column mapping
(:mod:`.column_map`: a TOML file, a preset in ``presets/`` or ``key=value``
pairs); :mod:`.ur10` is the ``ur10-ipa`` preset under its historical names.
"""

from .column_map import ColumnMap, load_column_map, presets
from .mapped import Imported, import_file, read_mapped

__all__ = ["ColumnMap", "Imported", "import_file", "load_column_map", "presets", "read_mapped"]
