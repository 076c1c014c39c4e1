"""Diagnosis: what the model gets wrong, why, and what each extension gains."""

from .candidates import Candidate
from .report import DiagnosisReport, Finding, Step
from .run import diagnose
from .settings import DiagnosisSettings

__all__ = ["Candidate", "DiagnosisReport", "DiagnosisSettings", "Finding", "Step", "diagnose"]
