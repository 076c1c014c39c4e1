"""Readers that convert third-party measurement files to the casadical CSV contract."""
