"""Tests of casadical.importers: column maps and the UR10 dataset converter."""
