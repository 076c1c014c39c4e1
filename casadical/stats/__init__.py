"""The statistics of a fit: significance, uncertainty, identifiability, robust-loss outliers, rigid alignment,
coverage, and the rules a named physical cause must pass. Below the data and the calibration problem: they read
arrays and parameters (a prediction's uncertainty, which reads a calibration result, is :mod:`casadical.prediction`)."""

import typing as _typing

from .._lazy import lazy

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"Cause": "_physics", "Coverage": "_coverage", "FitStatistics": "_significance",
            "Identifiability": "_identifiability", "LEVEL": "_significance", "ParameterTest": "_significance",
            "SetAsideStructure": "_outliers", "Uncertainty": "_uncertainty", "align": "_alignment",
            "analyse": "_identifiability", "betainc": "_significance", "direction_test": "_outliers",
            "estimate": "_uncertainty", "first_order_sag": "_physics", "from_normal": "_uncertainty",
            "hypergeom_tail": "_outliers", "inside_bounds": "_physics", "of_fit": "_outliers", "of_model": "_outliers",
            "order_test": "_outliers", "parameter_table_text": "_significance", "parameter_tests": "_significance",
            "sag_note": "_physics", "session_test": "_outliers", "set_aside_structure": "_outliers",
            "sign_changes": "_physics", "significance_notes": "_significance", "stiffness_interval": "_significance",
            "t_critical": "_significance", "t_two_sided_p": "_significance", "term_causes": "_physics",
            "triangular_factor": "_identifiability", "value_violations": "_physics", "violations": "_physics",
            "warn_not_significant": "_significance", "warn_problems": "_uncertainty"}

__all__ = [
    "Cause", "Coverage", "FitStatistics", "Identifiability", "LEVEL", "ParameterTest", "SetAsideStructure",
    "Uncertainty", "align", "analyse", "betainc", "direction_test", "estimate", "first_order_sag", "from_normal",
    "hypergeom_tail", "inside_bounds", "of_fit", "of_model", "order_test", "parameter_table_text", "parameter_tests",
    "sag_note", "session_test", "set_aside_structure", "sign_changes", "significance_notes", "stiffness_interval",
    "t_critical", "t_two_sided_p", "term_causes", "triangular_factor", "value_violations", "violations",
    "warn_not_significant", "warn_problems",
]

if _typing.TYPE_CHECKING:
    from ._alignment import align
    from ._coverage import Coverage
    from ._identifiability import Identifiability, analyse, triangular_factor
    from ._outliers import (
        SetAsideStructure,
        direction_test,
        hypergeom_tail,
        of_fit,
        of_model,
        order_test,
        session_test,
        set_aside_structure,
    )
    from ._physics import (
        Cause,
        first_order_sag,
        inside_bounds,
        sag_note,
        sign_changes,
        term_causes,
        value_violations,
        violations,
    )
    from ._significance import (
        LEVEL,
        FitStatistics,
        ParameterTest,
        betainc,
        parameter_table_text,
        parameter_tests,
        significance_notes,
        stiffness_interval,
        t_critical,
        t_two_sided_p,
        warn_not_significant,
    )
    from ._uncertainty import Uncertainty, estimate, from_normal, warn_problems
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
