"""Tests of casadical.urdf, reading and writing URDF."""
