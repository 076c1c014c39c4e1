"""Tests of casadical.calibration and what a calibration holds: solvers, problem, result files, significance,
uncertainty, sessions, transfer, coverage, compensation of targets (inverse.py)."""
