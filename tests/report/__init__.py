"""Tests of casadical.report, the HTML reports."""
