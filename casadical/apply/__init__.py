"""Applying a calibration: corrected joint targets, a calibration taken to new poses, the best geometric
model for URDF and DH export, and the controller-ready parameter table."""
