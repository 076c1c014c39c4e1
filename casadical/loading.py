"""Loading a robot by name or file type: built-in names, TOML files, URDF files.

It sits above both :mod:`casadical.robot` (the robot description and its
TOML form) and :mod:`casadical.urdf` (which builds on the former), so that
neither imports the other's way back. ``casadical.load_robot`` is this
module's :func:`load_robot`, the one function of that name.
"""

from __future__ import annotations

from pathlib import Path

from .robot import Robot, check_not_urdf_options, robot_file, robot_from_toml


def load_robot(spec: str | Path, tip: str | None = None, base: str | None = None,
               tool: tuple[float, float, float] | None = None) -> Robot:
    """Load a robot from a built-in name, a TOML path or a URDF path (``.urdf``).

    Parameters
    ----------
    spec : str or Path
    tip, base, tool : optional
        For a URDF file only: the chain to read (see
        :func:`casadical.urdf.robot_from_urdf`).

    Raises
    ------
    RobotFileError
        Unknown name, unreadable file, or any invalid field (the message
        names the file, the table and the key; for URDF the line and the
        element, see :func:`casadical.urdf.robot_from_urdf`).
    InputError
        ``tip``, ``base`` or ``tool`` given for a robot that is not a URDF file.
    """
    path = robot_file(spec)
    if path.suffix.lower() == ".urdf":
        from .urdf import robot_from_urdf  # here: a TOML robot needs neither lxml nor the URDF writer

        return robot_from_urdf(path, tip=tip, base=base, tool=tool)
    check_not_urdf_options(spec, tip, base, tool)
    return robot_from_toml(path)
