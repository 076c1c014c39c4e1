"""The IPA UR10 series D (``Series_D/measurements_iso_cubes.csv``): poses on ISO 9283 test cubes, as the measurement
CSV with the columns ``casadical iso9283`` reads.

The raw file is read as series A and B are (:func:`casadical.importers._ur10.read_ur10`, the ``ur10-ipa`` preset).
Its commanded poses (``goal_x_m ..``, robot base frame) come in blocks of nine: a cube's centre, then its eight
corners, each ``h`` from the centre along x, y and z (h 0.2, 0.125 or 0.05 m). Each block is a cube; its poses are
named ``P1`` (the centre) to ``P9`` (the corners, in the order measured). ISO 9283's own P2..P5 lie on a diagonal
plane of the cube, 10 % of the diagonal in from four of its corners: these corners are not those points, and
the report names them as the file does. A row in no block (the last two: a pose above the cubes and one of
another orientation) is kept with ``cube`` 0. Each pose is commanded and measured once: ``cycle`` is 1.
"""

from __future__ import annotations

import os

import numpy as np

from ..data._measurements import Measurements
from ._ur10 import read_ur10

#: a corner's offset from the centre: the same along x, y and z within this (m)
CORNER_TOL = 1e-3


def cubes_of(goal_xyz_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: the cube (1, 2, ...; 0 for a row in no cube) and the pose name (``P1`` the centre, ``P2..P9``
    the corners), from the commanded positions (m)."""
    g = np.asarray(goal_xyz_m, float)
    cube = np.zeros(len(g), int)
    pose = np.array([""] * len(g), dtype=object)
    i, k = 0, 0
    while i < len(g):
        d = np.abs(g[i + 1:i + 9] - g[i])
        if len(d) == 8 and np.all(np.abs(d - d[0, 0]) < CORNER_TOL) and d[0, 0] > 10 * CORNER_TOL:
            k += 1
            cube[i:i + 9] = k
            pose[i:i + 9] = [f"P{m}" for m in range(1, 10)]
            i += 9
        else:
            pose[i] = f"S{i + 1}"          # a single pose in no cube, named by its row
            i += 1
    return cube, pose


def convert_iso_cubes(src: str | os.PathLike[str], dst: str | os.PathLike[str], overwrite: bool = False) -> int:
    """Convert series D's raw file to the measurement CSV with ``cycle``, ``cube`` and ``pose`` columns (after
    the ``ur10-ipa`` preset's columns); the number of rows written."""
    cols = read_ur10(src)
    cube, pose = cubes_of(np.column_stack([cols[f"goal_{k}_m"] for k in "xyz"]))
    cols["cycle"] = np.ones(len(cube), int)
    cols["cube"] = cube
    cols["pose"] = pose
    Measurements(cols).write_csv(dst, overwrite=overwrite)
    return len(cube)
