"""Robot programs: read, filter with a calibration, write back (URScript, KUKA KRL, ABB RAPID).

:mod:`._program` holds what every language shares (the targets, their numbers in the text, the controllers'
orientation conventions, number formatting); one module per language reads a program into it
(:mod:`._urscript`, :mod:`._krl`, :mod:`._rapid`) and writes a measurement run as a program; :mod:`._filter`
corrects a program's targets with a calibration (``casadical compensate CAL.json PROGRAM --out FILTERED``).
Nothing is imported here: importing one module imports no other.
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"filter_program": "_filter", "frame": "_program", "frame_of": "_krl", "language_of": "_program",
            "matrix_rotvec": "_program", "rotvec_matrix": "_program"}

__all__ = ["filter_program", "frame", "frame_of", "language_of", "matrix_rotvec", "rotvec_matrix"]

if _typing.TYPE_CHECKING:
    from ._filter import filter_program
    from ._krl import frame_of
    from ._program import frame, language_of, matrix_rotvec, rotvec_matrix
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
