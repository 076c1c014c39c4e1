"""Stage ``note_physics``: the terms that, as fitted, are not the physical cause their names say.

:mod:`casadical.stats._physics` judges each fitted cause: told apart from the
geometry, meaningful over the data (bounds and significance have notes of
their own); and says when a compliant joint sags so far that the model's
first order (torques of the undeflected arm) leaves more than the noise.
"""

from __future__ import annotations

from ..data._measurements import Measurements
from ..errors import PhysicsWarning
from ..result import CalibrationResult
from ..stats._physics import sag_note, term_causes, violations
from ._state import CalibrationRun


def physics_notes(result: CalibrationResult, data: Measurements) -> list[str]:
    """Notes on the terms that, as fitted, are not the physical cause their names say
    (:mod:`casadical.stats._physics`: told apart from the geometry, meaningful over the data; bounds and significance
    have notes of their own), and on a compliance whose first order leaves more than the noise
    (:func:`~casadical.stats._physics.sag_note`)."""
    out = []
    for cause in term_causes(result):
        free = [n for n in cause.parameters if not result.parameters[n].fixed]   # the fixed: said by the analysis
        for v in violations(result, data, free) if free else ():
            if v.rule in ("geometry", "physics"):
                out.append(f"{cause.label}: not physics as fitted: {v.text}")
    sag = sag_note(result, data)
    return out + ([sag] if sag else [])


def note_physics(run: CalibrationRun) -> None:
    """Adds (and warns) a note per term that, as fitted, is not physics."""
    for note in physics_notes(run.result, run.data):
        run.note(note, PhysicsWarning)
