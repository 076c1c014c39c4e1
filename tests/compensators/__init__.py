"""Tests of casadical.compensators (RBF network, MLP, the Gaussian process) and the accuracy layer (accuracy.py)."""
