"""Diagnosis: what the model gets wrong, why, and what each extension gains."""

from .candidates import Candidate
from .pipeline import STAGES, diagnose
from .report import DiagnosisReport, Finding, Step
from .settings import DiagnosisSettings

__all__ = ["STAGES", "Candidate", "DiagnosisReport", "DiagnosisSettings", "Finding", "Step", "diagnose"]
