"""Tests of the robot file (robot.py), kinematics, the model, the simulator and the superset of models."""
