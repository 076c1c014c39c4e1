"""Diagnosis: what the model gets wrong, why, and what each extension gains."""

from .candidates import Candidate
from .run import DiagnosisReport, DiagnosisSettings, Finding, Step, diagnose

__all__ = ["Candidate", "DiagnosisReport", "DiagnosisSettings", "Finding", "Step", "diagnose"]
