"""Tests of casadical.diagnosis, the physics rules (physics.py) and the set-aside structure tests (set_aside.py)."""
