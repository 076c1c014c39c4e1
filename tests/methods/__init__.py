"""Tests of casadical.methods, the seed papers' calibration methods."""
