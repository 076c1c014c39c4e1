"""URDF in and out.

:func:`robot_from_urdf` reads the serial chain of a URDF file as a
:class:`~casadical.robot.Robot` in modified DH (Craig), with Hayati's beta
on (nearly) parallel axes; :func:`robot_to_urdf` writes a calibrated (or
nominal) geometry as URDF text whose tool-point link has the forward
kinematics of casadical's geometric model. The XML is parsed by lxml (read as yourdfpy
reads it, which the tests compare with, without importing it: it loads trimesh and scipy).
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"PARALLEL_TOL_DEG": "_read", "robot_from_urdf": "_read", "NOT_IN_URDF": "_write", "robot_to_urdf": "_write"}

__all__ = ["NOT_IN_URDF", "PARALLEL_TOL_DEG", "robot_from_urdf", "robot_to_urdf"]

if _typing.TYPE_CHECKING:
    from ._read import PARALLEL_TOL_DEG, robot_from_urdf
    from ._write import NOT_IN_URDF, robot_to_urdf
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
