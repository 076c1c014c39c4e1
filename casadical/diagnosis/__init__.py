"""Diagnosis: what the model gets wrong, why, and what each extension gains."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"Candidate": "_candidates", "STAGES": "_pipeline", "diagnose": "_pipeline", "DiagnosisReport": "_report",
            "Finding": "_report", "Step": "_report", "DiagnosisSettings": "_settings", "Catalogue": "_catalogue",
            "DiagnosisRun": "_state", "Held": "_worst", "Linearized": "_validation", "SHRINKS": "_compensator",
            "Screen": "_screening", "Split": "_transfer", "across_gravity": "_structure", "by_kind": "_validation",
            "check_data": "_prepare", "compose_terms": "_candidates", "describe_pair": "_structure",
            "fit_geometry": "_pipeline", "fit_nominal": "_pipeline", "joint_levers": "_validation",
            "judge": "_compensator", "linear_cv": "_validation", "nested_test": "_statistics",
            "not_tried": "_catalogue", "paired_gain": "_statistics", "periodic_columns": "_screening",
            "periodogram": "_periodogram", "random_scheme": "_validation", "repeated_sigma": "_noise",
            "schemes": "_validation", "session_scheme": "_validation", "set_aside_share": "_statistics",
            "solve_identified": "_validation", "weighted": "_structure"}

__all__ = [
    "Candidate", "Catalogue", "DiagnosisReport", "DiagnosisRun", "DiagnosisSettings", "Finding", "Held", "Linearized",
    "SHRINKS", "STAGES", "Screen", "Split", "Step", "across_gravity", "by_kind", "check_data", "compose_terms",
    "describe_pair", "diagnose", "fit_geometry", "fit_nominal", "joint_levers", "judge", "linear_cv", "nested_test",
    "not_tried", "paired_gain", "periodic_columns", "periodogram", "random_scheme", "repeated_sigma", "schemes",
    "session_scheme", "set_aside_share", "solve_identified", "weighted",
]

if _typing.TYPE_CHECKING:
    from ._candidates import Candidate, compose_terms
    from ._catalogue import Catalogue, not_tried
    from ._compensator import SHRINKS, judge
    from ._noise import repeated_sigma
    from ._periodogram import periodogram
    from ._pipeline import STAGES, diagnose, fit_geometry, fit_nominal
    from ._prepare import check_data
    from ._report import DiagnosisReport, Finding, Step
    from ._screening import Screen, periodic_columns
    from ._settings import DiagnosisSettings
    from ._state import DiagnosisRun
    from ._statistics import nested_test, paired_gain, set_aside_share
    from ._structure import across_gravity, describe_pair, weighted
    from ._transfer import Split
    from ._validation import (
        Linearized,
        by_kind,
        joint_levers,
        linear_cv,
        random_scheme,
        schemes,
        session_scheme,
        solve_identified,
    )
    from ._worst import Held
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
