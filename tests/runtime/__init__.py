"""Tests of how commands run: the compiled-code cache, threads, signals and outputs, start-up imports."""
