"""Reader for the UR10 laser-tracker measurements of Landgraf et al. (IPA).

The raw files (``measurements_grid.csv``, ``measurements_joint_configurations.csv``
of the repository christianlandgraf/ipa-robot-accuracy) are ``;`` separated and
use a decimal comma. Joint angles are in radians, tracker positions in mm and
orientations in degrees. They are read by the general importer
(:mod:`casadical.importers._mapped`) with the ``ur10-ipa`` preset
(``casadical/importers/presets/ur10-ipa.toml``): joint readings in degrees,
``x_mm, y_mm, z_mm`` unchanged (tracker frame), ``temperature_c``, ``time_s``
when the timestamps are usable, and every other column kept under a clear name.

Examples
--------
>>> from casadical.importers import convert_ur10
>>> convert_ur10("raw/Series_A/measurements_grid.csv", "series_a.csv")  # doctest: +SKIP
11911
"""

from __future__ import annotations

import os

import numpy as np

from ._column_map import load_column_map
from ._mapped import import_file, read_mapped

__all__ = ["read_ur10", "convert_ur10"]

PRESET = "ur10-ipa"


def read_ur10(path: str | os.PathLike[str], sort_by_time: bool = True
              ) -> dict[str, np.ndarray]:
    """Read a raw UR10 measurement file (IPA format) into contract columns.

    Parameters
    ----------
    path : str or path-like
        A ``;`` separated, decimal-comma file with a header row such as
        ``Series_A/measurements_grid.csv``.
    sort_by_time : bool, default True
        When the timestamps are usable and some rows are out of time order
        (series A: 10 of them), reorder the rows by timestamp (stable sort),
        because the contract's row order is time order. With False the file
        order is kept and ``time_s`` may decrease or be negative.

    Returns
    -------
    dict of str to numpy.ndarray
        Ordered column name -> array, one entry per data row:
        ``q1_deg .. q6_deg`` (radians converted to degrees), ``x_mm, y_mm, z_mm``
        (tracker frame, unchanged), then when present ``temperature_c``,
        ``time_s`` (seconds since the first row; omitted when the timestamps
        are mangled, as in series B), ``std_x_mm ..``, ``rx_deg ..``,
        ``std_rx_deg ..``, ``goal_x_m ..`` (m) and ``goal_roll_rad ..`` (rad).
        Unknown columns are kept under a snake_case version of their name.

    Raises
    ------
    DataFileError
        Empty file, missing or duplicate column, wrong number of fields,
        non-numeric value or bad timestamp; ``file``, ``row`` (1-based line
        number, header = 1) and ``column`` (raw name) say where.

    Warns
    -----
    DataWarning
        When the timestamps are unusable and ``time_s`` is omitted, or when
        rows are out of time order (sorted, or kept as they are).
    """
    return read_mapped(path, load_column_map([PRESET]), sort_by_time=sort_by_time).columns


def convert_ur10(src: str | os.PathLike[str], dst: str | os.PathLike[str],
                 overwrite: bool = False, sort_by_time: bool = True) -> int:
    """Convert a raw UR10 measurement file to a contract measurement CSV.

    Parameters
    ----------
    src : str or path-like
        Raw file, see :func:`read_ur10`.
    dst : str or path-like
        Contract CSV to write (:meth:`casadical.data._measurements.Measurements.write_csv`).
    overwrite : bool, default False
        Replace ``dst`` if it exists.
    sort_by_time : bool, default True
        Reorder rows by timestamp when they are out of time order, see
        :func:`read_ur10`.

    Returns
    -------
    int
        Number of data rows written.

    Raises
    ------
    DataFileError
        ``src`` is malformed.
    InputError
        ``dst`` exists and ``overwrite`` is false, or cannot be written.
    """
    return len(import_file(src, dst, load_column_map([PRESET]), overwrite=overwrite,
                           sort_by_time=sort_by_time))
