"""The statistics of a fit: significance, uncertainty, identifiability, robust-loss outliers, rigid alignment,
coverage, and the rules a named physical cause must pass. Below the data and the calibration problem: they read
arrays and parameters (a prediction's uncertainty, which reads a calibration result, is :mod:`casadical.prediction`)."""
