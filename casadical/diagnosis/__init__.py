"""Diagnosis: what the model gets wrong, why, and what each extension gains."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"Candidate": "candidates", "STAGES": "pipeline", "diagnose": "pipeline", "DiagnosisReport": "report",
            "Finding": "report", "Step": "report", "DiagnosisSettings": "settings"}

__all__ = ["STAGES", "Candidate", "DiagnosisReport", "DiagnosisSettings", "Finding", "Step", "diagnose"]

if _typing.TYPE_CHECKING:
    from .candidates import Candidate
    from .pipeline import STAGES, diagnose
    from .report import DiagnosisReport, Finding, Step
    from .settings import DiagnosisSettings
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
