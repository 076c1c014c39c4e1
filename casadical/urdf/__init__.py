"""URDF in and out.

:func:`robot_from_urdf` reads the serial chain of a URDF file as a
:class:`~casadical.robot.Robot` in modified DH (Craig), with Hayati's beta
on (nearly) parallel axes; :func:`robot_to_urdf` writes a calibrated (or
nominal) geometry as URDF text whose tool-point link has the forward
kinematics of casadical's geometric model. The XML is parsed by lxml (read as yourdfpy
reads it, which the tests compare with, without importing it: it loads trimesh and scipy).
"""

from .read import PARALLEL_TOL_DEG, robot_from_urdf
from .write import NOT_IN_URDF, robot_to_urdf

__all__ = ["NOT_IN_URDF", "PARALLEL_TOL_DEG", "robot_from_urdf", "robot_to_urdf"]
