"""Tests of casadical.cli: the commands, their options and one-line errors, the walkthrough of the README and guide."""
