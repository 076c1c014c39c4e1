"""The statistics of a fit: significance, uncertainty, identifiability, prediction uncertainty,
robust-loss outliers, rigid alignment, coverage, and the rules a named physical cause must pass."""
