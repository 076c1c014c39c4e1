"""Applying a calibration: corrected joint targets, a calibration taken to new poses, the best geometric
model for URDF and DH export, and the controller-ready parameter table."""

import typing as _typing

from .._lazy import lazy

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"COLUMNS": "_parameter_table", "Iso9283": "_iso9283", "MAX_DEG_PER_MM": "_inverse", "Poses": "_iso9283",
            "TargetError": "_inverse", "calibrated_on_orientation": "_inverse", "carry": "_carry",
            "compensate": "_inverse", "geometric_equivalent": "_export_geometry",
            "parameter_table": "_parameter_table", "rigid_fit": "_iso9283"}

__all__ = [
    "COLUMNS", "Iso9283", "MAX_DEG_PER_MM", "Poses", "TargetError", "calibrated_on_orientation", "carry", "compensate",
    "geometric_equivalent", "parameter_table", "rigid_fit",
]

if _typing.TYPE_CHECKING:
    from ._carry import carry
    from ._export_geometry import geometric_equivalent
    from ._inverse import MAX_DEG_PER_MM, TargetError, calibrated_on_orientation, compensate
    from ._iso9283 import Iso9283, Poses, rigid_fit
    from ._parameter_table import COLUMNS, parameter_table
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
