"""Reader for the UR10 laser-tracker measurements of Landgraf et al. (IPA).

The raw files (``measurements_grid.csv``, ``measurements_joint_configurations.csv``
of the repository christianlandgraf/ipa-robot-accuracy) are ``;`` separated and
use a decimal comma. Joint angles are in radians, tracker positions in mm and
orientations in degrees. This module converts them to the measurement CSV of
the casadical contract (INTERFACE.md section 2): joint readings in degrees,
``x_mm, y_mm, z_mm`` unchanged (tracker frame), ``temperature_c``, ``time_s``
when the timestamps are usable, and every other column kept under a clear name.

Examples
--------
>>> from casadical.importers.ur10 import convert_ur10
>>> convert_ur10("raw/Series_A/measurements_grid.csv", "series_a.csv")  # doctest: +SKIP
11911
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import warnings
from datetime import datetime
from pathlib import Path

import numpy as np

from ..data import Measurements
from ..errors import DataFileError, DataWarning, InputError

__all__ = ["read_ur10", "convert_ur10"]

_RAD2DEG = 180.0 / math.pi

#: The six joint columns of the raw files, base to tip.
JOINT_COLUMNS: tuple[str, ...] = (
    "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
    "wrist_1_joint", "wrist_2_joint", "wrist_3_joint",
)

#: Raw column -> (contract column, factor applied to the raw value).
COLUMN_MAP: dict[str, tuple[str, float]] = {
    **{raw: (f"q{i}_deg", _RAD2DEG) for i, raw in enumerate(JOINT_COLUMNS, 1)},
    "measurement_x": ("x_mm", 1.0),
    "measurement_y": ("y_mm", 1.0),
    "measurement_z": ("z_mm", 1.0),
    "measurement_temperature": ("temperature_c", 1.0),
    "measurement_std_x": ("std_x_mm", 1.0),
    "measurement_std_y": ("std_y_mm", 1.0),
    "measurement_std_z": ("std_z_mm", 1.0),
    "measurement_rx": ("rx_deg", 1.0),
    "measurement_ry": ("ry_deg", 1.0),
    "measurement_rz": ("rz_deg", 1.0),
    "measurement_std_rx": ("std_rx_deg", 1.0),
    "measurement_std_ry": ("std_ry_deg", 1.0),
    "measurement_std_rz": ("std_rz_deg", 1.0),
    "goal x": ("goal_x_m", 1.0),
    "goal y": ("goal_y_m", 1.0),
    "goal z": ("goal_z_m", 1.0),
    "goal roll": ("goal_roll_rad", 1.0),
    "goal pitch": ("goal_pitch_rad", 1.0),
    "goal yaw": ("goal_yaw_rad", 1.0),
}

#: Raw columns without which a file is not a usable measurement file.
REQUIRED_COLUMNS: tuple[str, ...] = JOINT_COLUMNS + (
    "measurement_x", "measurement_y", "measurement_z")

TIMESTAMP_COLUMN = "timestamp"

# Output order: contract columns first, then the covariates, then the rest.
_OUTPUT_ORDER: tuple[str, ...] = (
    tuple(f"q{i}_deg" for i in range(1, 7))
    + ("x_mm", "y_mm", "z_mm", "temperature_c", "time_s",
       "std_x_mm", "std_y_mm", "std_z_mm",
       "rx_deg", "ry_deg", "rz_deg", "std_rx_deg", "std_ry_deg", "std_rz_deg",
       "goal_x_m", "goal_y_m", "goal_z_m",
       "goal_roll_rad", "goal_pitch_rad", "goal_yaw_rad")
)

# Strict number syntax: float() alone would also accept 'nan', 'inf', '1_0'.
_NUMBER_RE = re.compile(r"[+-]?(?:\d+(?:[.,]\d*)?|[.,]\d+)(?:[eE][+-]?\d+)?")
_TIMESTAMP_RE = re.compile(r"\d{14}")
# What a spreadsheet makes of a 14-digit timestamp: '2,02011E+13'.
_MANGLED_TIMESTAMP_RE = re.compile(r"\d(?:[.,]\d*)?[eE]\+?\d+")


def _parse_number(text: str, file: str, row: int, column: str) -> float:
    """Parse one decimal-comma (or decimal-point) number, or raise DataFileError."""
    s = text.strip()
    if not _NUMBER_RE.fullmatch(s):
        what = "empty value" if not s else f"not a number: {text!r}"
        raise DataFileError(f"{what} (expected e.g. '0,365141')",
                            file=file, row=row, column=column)
    value = float(s.replace(",", "."))
    if not math.isfinite(value):  # e.g. '1E+999' overflows
        raise DataFileError(f"number out of range: {text!r}",
                            file=file, row=row, column=column)
    return value


def _clean_name(name: str) -> str:
    """Turn an unknown raw column name into a plain snake_case contract name."""
    return re.sub(r"[^0-9a-z]+", "_", name.strip().lower()).strip("_")


def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]], int]:
    """Read a ``;`` separated file into (header, [(line number, fields)], header line).

    Blank lines are skipped; line numbers are 1-based and count every line.
    """
    file = str(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DataFileError(f"cannot read file: {exc.strerror or exc}", file=file) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise DataFileError("not a UTF-8 text file (binary or wrong encoding)",
                            file=file, row=line) from None

    reader = csv.reader(io.StringIO(text, newline=""), delimiter=";")
    header: list[str] | None = None
    header_line = 1
    rows: list[tuple[int, list[str]]] = []
    try:
        for fields in reader:
            if not any(f.strip() for f in fields):
                continue  # blank lines carry no pose
            if header is None:
                header, header_line = [f.strip() for f in fields], reader.line_num
            else:
                rows.append((reader.line_num, fields))
    except csv.Error as exc:
        raise DataFileError(f"malformed CSV: {exc}", file=file,
                            row=reader.line_num + 1) from None
    if header is None:
        raise DataFileError(
            "empty file: expected a ';' separated header row with the columns "
            + ", ".join(REQUIRED_COLUMNS), file=file, row=1, column=REQUIRED_COLUMNS[0])
    return header, rows, header_line


def _map_header(header: list[str], file: str, header_line: int) -> list[str]:
    """Return the output name of each raw column; check required and duplicate ones."""
    names: list[str] = []
    seen: dict[str, str] = {}
    for raw in header:
        key = raw.lower()
        if key == TIMESTAMP_COLUMN:
            name = "time_s"
        elif key in COLUMN_MAP:
            name = COLUMN_MAP[key][0]
        else:
            name = _clean_name(raw)
            if not name:
                raise DataFileError("column without a name in the header",
                                    file=file, row=header_line, column=raw)
        if name in seen:
            raise DataFileError(f"duplicate column (clashes with {seen[name]!r})",
                                file=file, row=header_line, column=raw)
        seen[name] = raw
        names.append(name)
    present = {h.lower() for h in header}
    for required in REQUIRED_COLUMNS:
        if required not in present:
            hint = ""
            if len(header) == 1 and "," in header[0]:
                hint = " (the header has a single field: is the file ',' separated? "
                hint += "UR10 raw files are ';' separated)"
            raise DataFileError(f"missing column{hint}", file=file,
                                row=header_line, column=required)
    return names


def _parse_timestamps(values: list[str], lines: list[int], file: str,
                      column: str) -> np.ndarray | None:
    """Seconds relative to the first row, or None when every timestamp is mangled.

    Series B's timestamps went through a spreadsheet ('2,02011E+13') and kept
    only year and month; they are dropped with a warning instead of guessed.
    """
    stripped = [v.strip() for v in values]
    if all(not s or _MANGLED_TIMESTAMP_RE.fullmatch(s) for s in stripped):
        warnings.warn(
            f"{file}: column {column!r} holds no usable timestamps "
            f"(e.g. {values[0].strip()!r}, mangled by a spreadsheet); time_s omitted",
            DataWarning, stacklevel=3)
        return None
    times = np.empty(len(values))
    t0: datetime | None = None
    for i, (s, line) in enumerate(zip(stripped, lines)):
        try:
            if not _TIMESTAMP_RE.fullmatch(s):
                raise ValueError
            t = datetime.strptime(s, "%Y%m%d%H%M%S")
        except ValueError:
            raise DataFileError(f"timestamp {s!r} is not YYYYmmddHHMMSS",
                                file=file, row=line, column=column) from None
        t0 = t if t0 is None else t0
        times[i] = (t - t0).total_seconds()
    return times


def _time_order(columns: dict[str, np.ndarray], lines: list[int], file: str,
                sort_by_time: bool) -> dict[str, np.ndarray]:
    """Put rows in time order (or warn that they are not) and start time_s at 0."""
    times = columns["time_s"]
    # A row is late when an earlier row of the file has a later timestamp.
    late = np.flatnonzero(times < np.maximum.accumulate(times))
    if late.size == 0:
        return columns
    first = lines[late[0]]
    if not sort_by_time:
        warnings.warn(f"{file}: {late.size} row(s) out of time order (first: row "
                      f"{first}); file order kept", DataWarning, stacklevel=3)
        return columns
    warnings.warn(f"{file}: {late.size} row(s) out of time order (first: row "
                  f"{first}); rows sorted by timestamp", DataWarning, stacklevel=3)
    order = np.argsort(times, kind="stable")
    sorted_columns = {k: v[order] for k, v in columns.items()}
    sorted_columns["time_s"] = sorted_columns["time_s"] - sorted_columns["time_s"][0]
    return sorted_columns


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
        Ordered column name -> float array, one entry per data row:
        ``q1_deg .. q6_deg`` (radians converted to degrees), ``x_mm, y_mm, z_mm``
        (tracker frame, unchanged), then when present ``temperature_c``,
        ``time_s`` (seconds since the first row; omitted when the timestamps
        are mangled, as in series B), ``std_x_mm ..``, ``rx_deg ..``,
        ``std_rx_deg ..``, ``goal_x_m ..`` (m) and ``goal_roll_rad ..`` (rad).
        Unknown numeric columns are kept under a snake_case version of their name.

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
    path = Path(path)
    file = str(path)
    header, rows, header_line = _read_rows(path)
    names = _map_header(header, file, header_line)
    if not rows:
        raise DataFileError("no data rows after the header", file=file, row=header_line + 1)

    n_cols = len(header)
    for line, fields in rows:
        if len(fields) != n_cols:
            if len(fields) < n_cols:
                column = header[len(fields)]
                detail = f"the row ends before column {column!r}"
            else:
                column = header[-1]
                detail = f"extra field(s) after the last column {column!r}"
            raise DataFileError(
                f"{len(fields)} fields but the header has {n_cols} ({detail}; "
                "fields are ';' separated, ',' is the decimal mark)",
                file=file, row=line, column=column)

    lines = [line for line, _ in rows]
    columns: dict[str, np.ndarray] = {}
    for j, (raw, name) in enumerate(zip(header, names)):
        if raw.lower() == TIMESTAMP_COLUMN:
            times = _parse_timestamps([f[j] for _, f in rows], lines, file, raw)
            if times is not None:
                columns[name] = times
            continue
        factor = COLUMN_MAP.get(raw.lower(), (name, 1.0))[1]
        values = np.array([_parse_number(f[j], file, line, raw) for line, f in rows])
        # Multiply only when needed so that unconverted columns stay bit-exact.
        columns[name] = values * factor if factor != 1.0 else values

    if "time_s" in columns:
        columns = _time_order(columns, lines, file, sort_by_time)

    ordered = {k: columns[k] for k in _OUTPUT_ORDER if k in columns}
    ordered.update((k, v) for k, v in columns.items() if k not in ordered)
    return ordered


def convert_ur10(src: str | os.PathLike[str], dst: str | os.PathLike[str],
                 overwrite: bool = False, sort_by_time: bool = True) -> int:
    """Convert a raw UR10 measurement file to a contract measurement CSV.

    Parameters
    ----------
    src : str or path-like
        Raw file, see :func:`read_ur10`.
    dst : str or path-like
        Contract CSV to write (:meth:`casadical.data.Measurements.write_csv`).
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
    # Fail before the (slow) read when the output is refused anyway.
    if not overwrite and Path(dst).exists():
        raise InputError("exists already; choose another name or pass --force to replace it",
                         file=str(dst))
    columns = read_ur10(src, sort_by_time=sort_by_time)
    Measurements(columns, str(src)).write_csv(dst, overwrite=overwrite)
    return len(next(iter(columns.values())))
