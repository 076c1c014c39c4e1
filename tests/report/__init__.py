"""Tests of casadical.html, the HTML reports."""
