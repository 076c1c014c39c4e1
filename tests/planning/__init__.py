"""Tests of casadical.planning: observability, D-optimal designs, next poses."""
