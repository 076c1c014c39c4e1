"""An independent truth for the tests: measured-like data of a robot, made without casadical.

casadical's simulator (:mod:`casadical.data._simulate`) evaluates the very terms
the calibration and the diagnosis fit, so a wrong sign, phase, unit or
convention in a term would be shared by the data and the fit. This package
writes the robot and each effect again from its physical definition, in
plain numpy with its own transforms, and writes the measurement CSV of
docs/formats.md; the tests read that CSV as a user's file. casadical never
imports it (tests/test_import_graph.py), and it imports nothing of casadical.

    arm = Arm.from_dict(ARM4)                      # or Arm.from_toml(text)
    robot = TrueRobot.draw(arm, Effects(stiffness={2: 5e5}), rng)
    q = sample(robot, 80, rng)
    shots = measure(robot, q, rng, session=Session(base_xyz=(1.5, -0.5, 0.3)))
    shots.write_csv("cal.csv")

The conventions are stated in :mod:`truth.robot` (the arm and its drives)
and :mod:`truth.campaign` (sessions, orientation, noise, the file). Besides
the causes of casadical's diagnosis catalogue the truth makes effects
outside it: a joint's error from another joint's reading (``coupling``,
``cross_error``), a tipping axis (``axis_tilt``), a base tilting on a
compliant mount (``mount_compliance``, per session too, or growing with a
session's covariate: ``mount_law`` over ``Session.columns``), a floor
tilting from pose to pose with a tilt sensor's columns
(``Session.floor_tilt``, ``tilt_noise``; ``unrelated``: a column that
follows nothing) and the tracker's own errors (``Session.angle_error``,
``Session.distance_scale``).


:mod:`truth.touch` makes the rows of what the tool touches (docs/formats.md):
the true robot's tool point put in sockets, on planes, at a draw-wire's
distance from a pivot, a tool of several points, fixtures placed per session.
"""

from .arm import Arm, FourBar, Link
from .campaign import Session, Shots, measure, sample
from .robot import Effects, Geometry, State, TrueRobot, four_bar, last_moves

__all__ = ["Arm", "Effects", "FourBar", "Geometry", "Link", "Session", "Shots", "State", "TrueRobot",
           "four_bar", "last_moves", "measure", "sample"]
