"""Import any tracker file into the measurement CSV contract with a column mapping.

The mapping (:class:`~casadical.importers._column_map.ColumnMap`) says which
source columns hold the joint readings and the measured point (directly, or
as target + deviation), in which units, and which other columns to keep. The
reader handles a UTF-8 byte order mark, CRLF line ends, quoted fields, a
decimal comma, lines above the header and empty trailing columns; every bad
cell is one :class:`~casadical.errors.DataFileError` naming the source file,
its line (1-based, blank lines counted) and the source column.

Examples
--------
>>> from casadical.importers import import_file, load_column_map
>>> import_file("raw.csv", "poses.csv", load_column_map(["ur10-ipa"]))  # doctest: +SKIP
"""

from __future__ import annotations

import codecs
import csv
import difflib
import io
import math
import os
import re
import warnings
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from ..data._measurements import NUMERIC_OPTIONAL, XYZ, Measurements, looks_like_radians
from ..errors import ColumnMapError, DataFileError, DataWarning, InputError, listing
from ..runtime._files import EXISTS
from ._column_map import DEVIATION_SIGNS, JOINT_UNITS, LENGTH_UNITS, RESERVED, ColumnMap

__all__ = ["Imported", "Mapped", "import_file", "read_mapped"]

_NUMBER = {
    ".": re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"),
    ",": re.compile(r"[+-]?(?:\d+(?:,\d*)?|,\d+)(?:[eE][+-]?\d+)?"),
}
# What a spreadsheet makes of a 14-digit timestamp: '2,02011E+13'.
_MANGLED_TIMESTAMP = re.compile(r"\d(?:[.,]\d*)?[eE]\+?\d+")
_GUESSED_SEPARATORS = (";", "\t", ",", "|")


@dataclass(frozen=True)
class Mapped:
    """One output column and where it came from.

    Attributes
    ----------
    group : {"joints", "position", "time", "keep", "others"}
    source : str
        Source column(s), e.g. ``"Xt + dX"`` for target + deviation.
    output : str
        Column of the measurement CSV.
    note : str
        Unit conversion or other treatment (empty: copied as it is).
    """

    group: str
    source: str
    output: str
    note: str = ""


@dataclass
class Imported:
    """The result of an import: contract columns and what was mapped to what.

    Attributes
    ----------
    columns : dict of str to ndarray
        Output columns in contract order (joints, positions, ``payload_kg``,
        ``temperature_c``, ``time_s``, kept columns in mapping order, other
        columns in file order); numbers as floats, text as object arrays.
    mapped : list of Mapped
    dropped : list of str
        Source columns not written (``others = "drop"``).
    path : str
        The source file.
    """

    columns: dict[str, np.ndarray]
    mapped: list[Mapped]
    dropped: list[str]
    path: str

    def __len__(self) -> int:
        return len(next(iter(self.columns.values())))

    def measurements(self) -> Measurements:
        """The imported rows as :class:`~casadical.data._measurements.Measurements`."""
        return Measurements(self.columns, self.path)


@dataclass
class _Table:
    """The raw text of a source file: header, data rows and their line numbers."""

    file: str
    header: list[str]
    header_line: int
    rows: list[list[str]]
    lines: list[int]
    separator: str


# --- reading the text -------------------------------------------------------------------


def _decode(path: Path, cmap: ColumnMap) -> str:
    file = str(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DataFileError(f"cannot read file: {exc.strerror or exc}", file=file) from exc
    utf8 = codecs.lookup(cmap.encoding).name == "utf-8"
    try:
        text = data.decode("utf-8-sig" if utf8 else cmap.encoding)
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise DataFileError(f"not a {cmap.encoding} text file (binary, or set encoding in the mapping, "
                            "e.g. encoding = \"cp1252\")", file=file, row=line) from exc
    return text.removeprefix("\ufeff")


def _guess_separator(line: str, cmap: ColumnMap, file: str, row: int) -> str:
    counts = {s: line.count(s) for s in _GUESSED_SEPARATORS}
    best = max(counts.values())
    if best == 0:
        return ";" if cmap.decimal == "," else ","  # a single column: the mapping says what is missing
    tied = [s for s, c in counts.items() if c == best]
    if len(tied) > 1:
        raise DataFileError("cannot tell the field separator from the header (as many "
                            f"{' as '.join(map(repr, tied))}); set separator in the mapping",
                            file=file, row=row)
    return tied[0]


def _read_table(path: Path, cmap: ColumnMap) -> _Table | None:
    """Header and data rows (blank lines skipped); None for a file without a header."""
    file = str(path)
    buf = io.StringIO(_decode(path, cmap), newline="")
    for skipped in range(cmap.skip_lines):
        if not buf.readline():       # the end of the file: no work for the rest of a huge skip_lines
            raise ColumnMapError(f"skips {cmap.skip_lines:,} lines but {file} has {skipped:,}; count the lines before "
                                 "the header row", file=cmap.origin("skip_lines"), column="skip_lines")
    start, offset = buf.tell(), cmap.skip_lines
    first, first_row = "", offset
    for first_row, line in enumerate(iter(buf.readline, ""), start=offset + 1):
        if line.strip():
            first = line
            break
    buf.seek(start)
    separator = cmap.separator or _guess_separator(first, cmap, file, first_row)
    reader = csv.reader(buf, delimiter=separator)
    header: list[str] | None = None
    header_line = 0
    rows: list[list[str]] = []
    lines: list[int] = []
    try:
        for fields in reader:
            if not any(f.strip() for f in fields):
                continue  # blank lines carry no pose
            if header is None:
                header, header_line = [f.strip() for f in fields], offset + reader.line_num
            else:
                rows.append(fields)
                lines.append(offset + reader.line_num)
    except csv.Error as exc:
        # the reader has counted the line at fault (an oversized field, a NUL, a quote open at the end)
        raise DataFileError(f"malformed CSV: {exc}", file=file, row=offset + reader.line_num) from exc
    if header is None:
        return None
    while header and not header[-1]:
        header.pop()  # empty trailing columns
    return _Table(file, header, header_line, rows, lines, separator)


def _check_field_counts(t: _Table, cmap: ColumnMap) -> None:
    n = len(t.header)
    for line, fields in zip(t.lines, t.rows):
        if len(fields) < n:
            detail, column = f"the row ends before column {t.header[len(fields)]!r}", t.header[len(fields)]
        elif len(fields) > n and any(f.strip() for f in fields[n:]):
            detail, column = f"extra field(s) after the last column {t.header[-1]!r}", t.header[-1]
        else:
            continue
        raise DataFileError(f"{len(fields)} fields but the header has {n} ({detail}; fields are "
                            f"{t.separator!r} separated, {cmap.decimal!r} is the decimal mark)",
                            file=t.file, row=line, column=column)


# --- cells --------------------------------------------------------------------------------


def _numbers(t: _Table, j: int, decimal: str) -> np.ndarray:
    """Column ``j`` as floats, or DataFileError naming the first bad cell."""
    pattern, column = _NUMBER[decimal], t.header[j]
    out = np.empty(len(t.rows))
    for i, fields in enumerate(t.rows):
        s = fields[j].strip()
        if not pattern.fullmatch(s):
            raise DataFileError(_not_a_number(s, decimal), file=t.file, row=t.lines[i], column=column)
        value = float(s.replace(",", ".")) if decimal == "," else float(s)
        if not math.isfinite(value):  # e.g. '1E+999' overflows
            raise DataFileError(f"number out of range: {s!r}", file=t.file, row=t.lines[i], column=column)
        out[i] = value
    return out


def _not_a_number(s: str, decimal: str) -> str:
    if not s:
        return "empty value"
    other = "," if decimal == "." else "."
    if "," in s and "." in s:
        hint = " (thousands separators are not supported)"
    elif _NUMBER[other].fullmatch(s):
        hint = f" (decimal mark {other!r}? the mapping says decimal = {decimal!r})"
    else:
        hint = ""
    return f"not a number: {s!r}{hint}"


def _numbers_or_text(t: _Table, j: int, decimal: str, output: str) -> np.ndarray:
    """Column ``j`` as floats when every cell is a number, else its text as it is.

    Contract columns (``payload_kg``, ``temperature_c``, ``time_s``) must be numbers.
    """
    if output in NUMERIC_OPTIONAL:
        return _numbers(t, j, decimal)
    try:
        return _numbers(t, j, decimal)
    except DataFileError:
        return np.array([f[j].strip() for f in t.rows], dtype=object)


def _timestamps(t: _Table, j: int, fmt: str) -> np.ndarray | None:
    """Seconds since the first row, or None (with a warning) when every timestamp is mangled.

    Timestamps that went through a spreadsheet ('2,02011E+13') keep only year
    and month; they are dropped instead of guessed.
    """
    column = t.header[j]
    cells = [f[j].strip() for f in t.rows]
    if all(not s or _MANGLED_TIMESTAMP.fullmatch(s) for s in cells):
        warnings.warn(f"{t.file}: column {column!r} holds no usable timestamps (e.g. {cells[0]!r}, "
                      "mangled by a spreadsheet); time_s omitted", DataWarning, stacklevel=4)
        return None
    times = np.empty(len(cells))
    t0: datetime | None = None
    for i, s in enumerate(cells):
        try:
            stamp = datetime.strptime(s, fmt)
        except ValueError:
            raise DataFileError(f"timestamp {s!r} does not match the format {fmt!r}",
                                file=t.file, row=t.lines[i], column=column) from None
        t0 = stamp if t0 is None else t0
        times[i] = (stamp - t0).total_seconds()
    return times


def _time_order(columns: dict[str, np.ndarray], lines: list[int], file: str,
                sort_by_time: bool) -> dict[str, np.ndarray]:
    """Put rows in time order (or warn that they are not) and start time_s at 0."""
    times = columns["time_s"]
    # A row is late when an earlier row of the file has a later timestamp.
    late = np.flatnonzero(times < np.maximum.accumulate(times))
    if late.size == 0:
        return columns
    what = f"{file}: {late.size} row(s) out of time order (first: row {lines[late[0]]}); "
    if not sort_by_time:
        warnings.warn(what + "file order kept", DataWarning, stacklevel=4)
        return columns
    warnings.warn(what + "rows sorted by timestamp", DataWarning, stacklevel=4)
    order = np.argsort(times, kind="stable")
    ordered = {k: v[order] for k, v in columns.items()}
    ordered["time_s"] = ordered["time_s"] - ordered["time_s"][0]
    return ordered


def joint_columns(cmap: ColumnMap) -> list[str]:
    """The output columns of the joint readings: ``qK_deg``, ``qK_mm`` for a linear axis."""
    return [f"q{i}_{'mm' if i in cmap.linear_axes else 'deg'}" for i in range(1, len(cmap.joints) + 1)]


def _check_joint_unit(readings: list[tuple[int, np.ndarray]], cmap: ColumnMap, t: _Table, multiturn: bool) -> None:
    """Readings in degrees declared as radians are an error (converted, a turn of a few degrees would become
    hundreds, which calibrate refuses as beyond the joint's limits), unless ``multiturn`` (a joint that turns
    more than once); readings that look like radians declared as degrees are a warning (calibrate warns of
    them too, and goes on)."""
    unit = cmap.joint_unit
    top, j = max((float(np.max(np.abs(v))), j) for j, v in readings)
    if unit == "rad" and top > 2.02 * math.pi and not multiturn:
        raise ColumnMapError(f"joint readings of {t.file} reach {top:g} (column {t.header[j]!r}) with joint_unit = "
                             f'"rad": more than a turn (2 pi), these look like degrees: set joint_unit = "deg", or '
                             "pass --allow-multiturn if a joint turns more than once", file=cmap.origin("joint_unit"),
                             column="joint_unit")
    if unit == "deg" and looks_like_radians(np.column_stack([v for _, v in readings]), tol=0.0):
        warnings.warn(f"{t.file}: every joint reading is within +-6.3: these look like radians, but the mapping says "
                      'joint_unit = "deg"', DataWarning, stacklevel=4)


# --- the mapping ---------------------------------------------------------------------------


def _clean_name(name: str) -> str:
    """A plain snake_case output name for a source column."""
    return re.sub(r"[^0-9a-z]+", "_", name.strip().lower()).strip("_")


class _Header:
    """Find mapped columns in the header, case-insensitively when there is no exact match."""

    def __init__(self, t: _Table, cmap: ColumnMap):
        self.t, self.cmap = t, cmap
        self.used: set[int] = set()
        self.measured: dict[int, str] = {}  # columns of joints and positions: each used once

    def measure(self, name: str) -> int:
        j = self.find(name)
        if j in self.measured:
            raise DataFileError(f"named twice by the mapping ({self.measured[j]} and "
                                f"{self.cmap.key_of(name)})", file=self.t.file,
                                row=self.t.header_line, column=self.t.header[j])
        self.measured[j] = self.cmap.key_of(name)
        return j

    def find(self, name: str, required: bool = True) -> int | None:
        h = self.t.header
        hits = [i for i, c in enumerate(h) if c == name] or [
            i for i, c in enumerate(h) if c.lower() == name.lower()]
        if len(hits) > 1:
            raise DataFileError(f"{len(hits)} columns of this name (fields "
                                f"{', '.join(str(i + 1) for i in hits)}): the mapping cannot tell them "
                                "apart", file=self.t.file, row=self.t.header_line, column=name)
        if not hits:
            if not required:
                return None
            raise DataFileError(f"missing column, named by mapping key {self.cmap.key_of(name)}"
                                f"{self._hint(name)}",
                                file=self.t.file, row=self.t.header_line, column=name)
        self.used.add(hits[0])
        return hits[0]

    def _hint(self, name: str) -> str:
        h = self.t.header
        if len(h) == 1:
            for s in _GUESSED_SEPARATORS:
                if s in h[0] and s != self.t.separator:
                    return f" (the header has a single field: is the file {s!r} separated? set separator)"
        close = difflib.get_close_matches(name, h, n=1)
        if close:
            return f" (did you mean {close[0]!r}?)"
        return f" (the header has: {listing(h)})"


def read_mapped(path: str | os.PathLike[str], column_map: ColumnMap,
                sort_by_time: bool = True, multiturn: bool = False) -> Imported:
    """Read a tracker file into contract columns as ``column_map`` says.

    Parameters
    ----------
    path : str or path-like
        The source file (text with a header row).
    column_map : ColumnMap
        See :func:`casadical.importers._column_map.load_column_map`.
    sort_by_time : bool, default True
        With a ``time`` column, put rows that are out of time order in time
        order (stable sort, with a warning), because the contract's row
        order is time order. With False the file order is kept.
    multiturn : bool, default False
        Accept readings beyond a turn (2 pi) with ``joint_unit = "rad"``
        (a joint that turns more than once); else they are an error.

    Returns
    -------
    Imported
        ``q1_deg ..`` (degrees), ``x_mm, y_mm, z_mm`` (mm, the source's
        frame), ``time_s`` (seconds since the first row), the kept and the
        other columns.

    Raises
    ------
    DataFileError
        Empty file, missing, ambiguous or clashing column, wrong number of
        fields, non-numeric value or bad timestamp; ``file``, ``row`` (1-based
        line) and ``column`` (the source column) say where.
    ColumnMapError
        A unit the data contradict: points kilometres apart, joint readings
        beyond a turn in radians (unless ``multiturn``).

    Warns
    -----
    DataWarning
        Unusable timestamps (``time_s`` omitted), rows out of time order,
        joint readings in degrees that look like radians.
    """
    cmap, path = column_map, Path(path)
    file = str(path)
    t = _read_table(path, cmap)
    if t is None:
        raise DataFileError("empty file: expected a header row with the columns "
                            + ", ".join(cmap.joints), file=file, row=cmap.skip_lines + 1,
                            column=cmap.joints[0])
    h = _Header(t, cmap)
    joint_idx = [h.measure(c) for c in cmap.joints]
    position_idx = {k: [h.measure(c) for c in getattr(cmap, k)]
                    for k in ("position", "target", "deviation") if getattr(cmap, k)}
    time_idx = h.find(cmap.time.column) if cmap.time else None
    kept = [(j, dst) for table, required in ((cmap.keep, True), (cmap.keep_if_present, False))
            for src, dst in table.items() if (j := h.find(src, required)) is not None]
    if not t.rows:
        raise DataFileError("no data rows after the header", file=file, row=t.header_line + 1)
    _check_field_counts(t, cmap)

    columns: dict[str, np.ndarray] = {}
    mapped: list[Mapped] = []
    readings = [(j, _numbers(t, j, cmap.decimal)) for j in joint_idx]
    revolute = [r for i, r in enumerate(readings, 1) if i not in cmap.linear_axes]
    if revolute:
        _check_joint_unit(revolute, cmap, t, multiturn)
    names = joint_columns(cmap)
    for i, ((j, values), name) in enumerate(zip(readings, names), 1):
        linear = i in cmap.linear_axes
        factor = LENGTH_UNITS[cmap.linear_unit] if linear else JOINT_UNITS[cmap.joint_unit]
        # multiply only when needed so that unconverted columns stay bit-exact
        columns[name] = values * factor if factor != 1.0 else values
        mapped.append(Mapped("joints", t.header[j], name,
                             (f"{cmap.linear_unit} -> mm" if cmap.linear_unit != "mm" else "mm") if linear else
                             "rad -> deg" if factor != 1.0 else "deg"))
    columns.update(_positions(t, cmap, position_idx, mapped))
    _check_position_unit(columns, cmap, t)
    if time_idx is not None:
        times = _timestamps(t, time_idx, cmap.time.format)
        if times is not None:
            columns["time_s"] = times
            mapped.append(Mapped("time", t.header[time_idx], "time_s",
                                 f"{cmap.time.format} -> s since the first row"))
    for j, dst in kept:
        columns[dst] = _numbers_or_text(t, j, cmap.decimal, dst)
        mapped.append(Mapped("keep", t.header[j], dst))

    dropped: list[str] = []
    for j, raw in enumerate(t.header):
        if j in h.used:
            continue
        if cmap.others == "drop":
            dropped.append(raw or f"(field {j + 1})")
            continue
        name = _clean_name(raw)
        if not name or name in columns or RESERVED.fullmatch(name):
            why = ("has no name" if not name else f"would be written as {name!r}, which "
                   + ("the mapping already makes" if name in columns else "is a contract column"))
            raise DataFileError(f"column {why}: keep it under another name (keep.\"{raw}\" = \"...\") "
                                "or set others = \"drop\" in the mapping",
                                file=file, row=t.header_line, column=raw or f"field {j + 1}")
        columns[name] = _numbers_or_text(t, j, cmap.decimal, name)
        mapped.append(Mapped("others", raw, name))

    if "time_s" in columns and time_idx is not None:
        columns = _time_order(columns, t.lines, file, sort_by_time)
    first = joint_columns(cmap) + list(XYZ) + list(NUMERIC_OPTIONAL)
    ordered = {k: columns[k] for k in first if k in columns}
    ordered.update((k, v) for k, v in columns.items() if k not in ordered)
    return Imported(ordered, mapped, dropped, file)


def _positions(t: _Table, cmap: ColumnMap, idx: dict[str, list[int]],
               mapped: list[Mapped]) -> dict[str, np.ndarray]:
    """``x_mm, y_mm, z_mm`` from position columns, or from target and deviation."""
    out: dict[str, np.ndarray] = {}
    if "position" in idx:
        factor = LENGTH_UNITS[cmap.position_unit]
        for j, c in zip(idx["position"], XYZ):
            values = _numbers(t, j, cmap.decimal)
            out[c] = values * factor if factor != 1.0 else values
            mapped.append(Mapped("position", t.header[j], c,
                                 "mm" if factor == 1.0 else f"{cmap.position_unit} -> mm"))
    elif "target" in idx:
        ft, fd = LENGTH_UNITS[cmap.target_unit], LENGTH_UNITS[cmap.deviation_unit]
        sign = DEVIATION_SIGNS[cmap.deviation_sign]
        note = (f"target {cmap.target_unit}, deviation {cmap.deviation_unit} -> mm; "
                f"deviation = {cmap.deviation_sign.replace('-', ' - ')}")
        for jt, jd, c in zip(idx["target"], idx["deviation"], XYZ):
            target = _numbers(t, jt, cmap.decimal) * ft
            deviation = _numbers(t, jd, cmap.decimal) * fd
            out[c] = target + deviation if sign > 0 else target - deviation
            op = "+" if sign > 0 else "-"
            mapped.append(Mapped("position", f"{t.header[jt]} {op} {t.header[jd]}", c, note))
    return out


#: measured points of one robot spread (RMS distance from their centre) less than this (mm): the largest
#: arms reach 4 m, laser trackers measure over 80 m at most
MAX_SPREAD_MM = 1e5


def _check_position_unit(columns: dict[str, np.ndarray], cmap: ColumnMap, t: _Table) -> None:
    """Positions in mm declared as metres: points kilometres apart are no robot's, whatever the tracker."""
    if not all(c in columns for c in XYZ) or len(t.rows) < 3:
        return
    from ..data._checks import spread

    s = spread(np.column_stack([columns[c] for c in XYZ]))
    if s <= MAX_SPREAD_MM:
        return
    key = "position_unit" if cmap.position else "target_unit"
    unit = getattr(cmap, key)
    hint = (f'these look like millimetres: set {key} = "mm"' if unit == "m" and s / 1000 <= MAX_SPREAD_MM
            else "check the position columns and their unit")
    raise ColumnMapError(f"the measured points of {t.file} spread {s / 1e6:.4g} km around their centre with "
                         f'{key} = "{unit}"; one robot\'s points spread a few metres at most: {hint}',
                         file=cmap.origin(key), column=key)


def import_file(src: str | os.PathLike[str], dst: str | os.PathLike[str], column_map: ColumnMap,
                overwrite: bool = False, sort_by_time: bool = True, multiturn: bool = False) -> Imported:
    """Convert a tracker file to a measurement CSV (:meth:`Measurements.write_csv`, atomic).

    Parameters
    ----------
    src, dst : str or path-like
        Source file and the contract CSV to write.
    column_map : ColumnMap
    overwrite : bool, default False
        Replace ``dst`` if it exists.
    sort_by_time, multiturn : bool
        See :func:`read_mapped`.

    Returns
    -------
    Imported
        What was written and what was mapped to what.

    Raises
    ------
    DataFileError
        ``src`` is malformed (see :func:`read_mapped`).
    InputError
        ``dst`` exists and ``overwrite`` is false, or cannot be written.
    """
    # fail before the (slow) read when the output is refused anyway
    if not overwrite and Path(dst).exists():
        raise InputError(EXISTS, file=str(dst))
    imported = read_mapped(src, column_map, sort_by_time=sort_by_time, multiturn=multiturn)
    imported.measurements().write_csv(dst, overwrite=overwrite)
    return imported
