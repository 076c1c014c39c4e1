"""Tests of casadical.optim, the population-based optimisers."""
