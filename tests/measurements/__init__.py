"""Tests of the measurement files (data.py) and their plausibility checks (checks.py)."""
