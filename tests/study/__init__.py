"""Tests of casadical.study, Monte Carlo studies."""
