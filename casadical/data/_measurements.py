"""Measurement files: the CSV contract of docs/formats.md section 2.

One row per pose, in measurement order: ``q1_deg..qN_deg`` (``qK_mm`` for a prismatic joint K), optionally
``x_mm, y_mm, z_mm`` (a file without them is a list of poses to predict or
plan with), and optional ``payload_kg``, ``temperature_c``, ``time_s``.
Where a 6-DoF probe measured the full pose, ``rx_deg, ry_deg, rz_deg`` hold
the probe's orientation in the measurement frame, ``R = Rx(rx) Ry(ry)
Rz(rz)`` (intrinsic XYZ), degrees. Other columns are kept as they are.
"""

from __future__ import annotations

import contextlib
import csv
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import DataFileError, DataWarning
from ..runtime._files import atomic_open

#: a joint's reading: ``qK_deg`` (revolute, degrees) or ``qK_mm`` (prismatic, millimetres)
_Q = re.compile(r"^q([1-9]\d*)_(deg|mm)$")
_Q_LIKE = re.compile(r"^q\d+_(deg|mm)$")
XYZ = ("x_mm", "y_mm", "z_mm")
#: measured orientation of the probe, measurement frame: R = Rx(rx) Ry(ry) Rz(rz) (intrinsic XYZ), degrees
RXYZ = ("rx_deg", "ry_deg", "rz_deg")
NUMERIC_OPTIONAL = ("payload_kg", "temperature_c", "time_s", "source_row")
#: what a touch row touched instead of being measured (docs/formats.md section 11): text columns, and a pivot's
#: measured distance
TOUCH = ("point", "plane")
DISTANCE = "distance_mm"
#: the tool point a row measures, where the tool carries several (reflector nests, balls)
TOOL = "tool"


@dataclass
class Measurements:
    """Measured (or to-be-predicted) poses.

    Attributes
    ----------
    columns : dict of str to ndarray
        Every column in file order; numeric columns as float arrays, other
        columns as arrays of strings.
    path : str
        Where the data came from (for error messages).
    rows : ndarray of int
        Each pose's row in the original measurement order (0-based; from the
        column ``source_row``, 1-based, when the file has it, as ``split``
        writes it).
    moves : ndarray, shape (N, n_joints)
        Sign of each joint's last move before the pose, in the original order
        (the columns ``move1..moveN`` when the file has them, as ``split``
        writes them).
    lines : ndarray of int
        Each pose's line in its file (the header is line 1), for messages
        and reports; ``rows + 2`` for data made in memory.
    checked : set
        Plausibility checks this data passed (or was allowed to skip) by
        :func:`casadical.data._checks.check_poses`; subsets keep it.
    sessions : ndarray of str or None
        Each pose's measurement session (tracker placement, day, probe
        mount): from the ``session`` column, or given by
        :func:`casadical.data._sessions.combine` (one session per file). None:
        the data are one session.
    sources : ndarray of str or None
        Each pose's file, where the data come from several
        (:func:`casadical.data._sessions.combine`); None: all from ``path``.
    fixtures : tuple of Fixture
        The fixtures whose points the rows touch (``--fixture FILE``, :mod:`casadical.rows._fixture`).
    """

    columns: dict[str, np.ndarray]
    path: str = "<memory>"
    rows: np.ndarray | None = None
    moves: np.ndarray | None = None
    lines: np.ndarray | None = None
    checked: set = field(default_factory=set, repr=False, compare=False)
    sessions: np.ndarray | None = None
    sources: np.ndarray | None = None
    fixtures: tuple = ()
    _n_joints: int = field(init=False)
    _q_columns: list = field(init=False, repr=False)

    def __post_init__(self) -> None:
        qs = sorted((int(m.group(1)), c) for c in self.columns if (m := _Q.match(c)))
        self._n_joints = len(qs)
        self._q_columns = [c for _, c in qs]
        # row order is time order: keep each pose's original position and the direction of
        # its joints' last move, so subsets (splits, cross-validation folds) keep them
        if self.rows is None:
            source = self.get("source_row")
            self.rows = source.astype(int) - 1 if source is not None else np.arange(len(self))
        if self.lines is None:
            self.lines = self.rows + 2
        payload = self.columns.get("payload_kg")
        if payload is not None and payload.dtype.kind in "fiu":    # read from a file or made in memory
            _check_payload(payload, self.lines, self.path)
        if self.sessions is None and "session" in self.columns:
            self.sessions = np.array([session_name(x) for x in self.columns["session"]], dtype=object)
        if self.moves is None:
            given = [self.get(f"move{j}") for j in range(1, self._n_joints + 1)]
            if self._n_joints and all(m is not None for m in given):
                # written by 'split': the moves of the original sequence, which a subset cannot recompute
                self.moves = np.column_stack(given).astype(float)
            else:
                self.moves = last_moves(self.q) if self._n_joints else np.zeros((len(self), 0))

    # --- views ------------------------------------------------------------------

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    @property
    def n_joints(self) -> int:
        return self._n_joints

    @property
    def q_columns(self) -> list[str]:
        """The reading columns, joint by joint: ``qK_deg`` (revolute) or ``qK_mm`` (prismatic)."""
        return list(self._q_columns)

    @property
    def prismatic(self) -> tuple[bool, ...]:
        """Per joint: its readings are a linear axis' (a ``qK_mm`` column)."""
        return tuple(c.endswith("_mm") for c in self._q_columns)

    @property
    def q_deg(self) -> np.ndarray:
        """Joint readings as in the file, shape (N, n): degrees (millimetres in a prismatic joint's column)."""
        return np.column_stack([self.columns[c] for c in self._q_columns])

    @property
    def q(self) -> np.ndarray:
        """Joint readings in SI units, shape (N, n): radians (metres for a prismatic joint)."""
        q = self.q_deg
        linear = self.prismatic
        if not any(linear):
            return np.radians(q)
        return np.where(np.array(linear), q / 1000.0, np.radians(q))

    @property
    def has_positions(self) -> bool:
        return all(c in self.columns for c in XYZ)

    @property
    def xyz(self) -> np.ndarray:
        """Measured positions in metres, shape (N, 3)."""
        if not self.has_positions:
            raise DataFileError("has no measured positions (columns x_mm, y_mm, z_mm)", file=self.path)
        return np.column_stack([self.columns[c] for c in XYZ]) / 1000.0

    @property
    def touches(self) -> bool:
        """Some rows say what the tool point touched (``point``, ``plane``) instead of where it was."""
        return any(self._text(c).any() for c in TOUCH)

    @property
    def measured(self) -> bool:
        """Every row is a measurement: a measured point, or what the tool point touched."""
        if not self.touches:
            return self.has_positions
        return bool(self.touching.all() or (self.has_positions and np.isfinite(self.xyz[~self.touching]).all()))

    @property
    def touching(self) -> np.ndarray:
        """The rows that say what they touched (bool, N)."""
        return np.logical_or.reduce([self._text(c) for c in TOUCH] + [np.zeros(len(self), bool)])

    def _text(self, column: str) -> np.ndarray:
        col = self.columns.get(column)
        if col is None:
            return np.zeros(len(self), bool)
        return np.array([v is not None and str(v).strip() != "" and not (isinstance(v, float) and math.isnan(v))
                         for v in col], dtype=bool)

    @property
    def layout(self):
        """The rows grouped by kind and by what they touch (:func:`casadical.rows.layout`), made once."""
        hit = getattr(self, "_layout", None)
        if hit is None:
            from ..rows import layout
            hit = self._layout = layout(self)
        return hit

    def with_fixtures(self, fixtures) -> "Measurements":
        """The same rows, touching the points of ``fixtures`` (checked against the rows: :func:`check_fixtures`)."""
        out = self.with_columns(self.columns)
        out.fixtures = tuple(fixtures)
        check_fixtures(out)
        return out

    @property
    def has_orientation(self) -> bool:
        """True when the poses have a measured orientation (``rx_deg, ry_deg, rz_deg``)."""
        return all(self.get(c) is not None for c in RXYZ)

    @property
    def rotations(self) -> np.ndarray:
        """Measured orientations of the probe in the measurement frame, shape (N, 3, 3).

        ``R = Rx(rx) Ry(ry) Rz(rz)`` (intrinsic XYZ) of the columns ``rx_deg,
        ry_deg, rz_deg``.

        Raises
        ------
        DataFileError
            The data have none, or only some, of the three columns (naming the first missing one).
        """
        missing = [c for c in RXYZ if self.get(c) is None]
        if missing:
            what = "has only some of" if len(missing) < 3 else "has no measured orientation:"
            raise DataFileError(f"{what} rx_deg, ry_deg, rz_deg", file=self.path, column=missing[0])
        angles = np.column_stack([self.columns[c] for c in RXYZ])
        # kept with the angles they came from (a diagnosis asks for the validation poses' rotations with every
        # model it judges: 17 ms each at 10,000 poses); a column changed since gives them anew
        hit = getattr(self, "_rotations", None)
        if hit is None or not np.array_equal(hit[0], angles):
            hit = self._rotations = (angles, rotation_matrices(angles))
        return hit[1].copy()    # the caller's own (a copy costs a hundredth of the rotations)

    def line(self, i: int) -> int:
        """Line of pose ``i`` in its file (header = line 1), for error messages."""
        return int(self.lines[i])

    def file(self, i: int) -> str:
        """The file pose ``i`` comes from."""
        return self.path if self.sources is None else str(self.sources[i])

    @property
    def session_names(self) -> list[str]:
        """The sessions of the data in order of first appearance ([] for data of one session)."""
        if self.sessions is None:
            return []
        return list(dict.fromkeys(self.sessions.tolist()))

    def get(self, name: str) -> np.ndarray | None:
        """A numeric column, or None if absent."""
        col = self.columns.get(name)
        if col is None or col.dtype.kind not in "fiu":
            return None
        return col

    def subset(self, index) -> "Measurements":
        """Rows ``index`` (mask or integer array), order kept as given."""
        return Measurements({k: v[index] for k, v in self.columns.items()}, self.path,
                            self.rows[index], self.moves[index], self.lines[index], set(self.checked),
                            None if self.sessions is None else self.sessions[index],
                            None if self.sources is None else self.sources[index], self.fixtures)

    def with_columns(self, columns: dict[str, np.ndarray]) -> "Measurements":
        """The same poses (rows, moves, lines, sessions, sources, checks) with other columns."""
        return Measurements(columns, self.path, self.rows, self.moves, self.lines, set(self.checked),
                            self.sessions, self.sources, self.fixtures)

    def with_row_times(self, spacing_s: float) -> "Measurements":
        """A copy whose ``time_s`` is each pose's row in the measurement order times ``spacing_s``.

        For files without times whose rows are known to be in time order at
        a regular spacing (``--row-spacing-s``); casadical never takes row
        numbers for times otherwise.

        Raises
        ------
        DataFileError
            The file has a ``time_s`` column already, or the spacing is not
            a positive number.
        """
        if not (math.isfinite(spacing_s) and spacing_s > 0):
            raise DataFileError(f"the row spacing must be a positive number of seconds, got {spacing_s!r}",
                                file=self.path)
        if "time_s" in self.columns:
            raise DataFileError("has a time_s column already: a row spacing would replace the measured times; "
                                "drop --row-spacing-s", file=self.path, row=1, column="time_s")
        return self.with_columns({**self.columns, "time_s": self.rows * float(spacing_s)})

    def with_positions(self, xyz_m: np.ndarray, prefix_existing: str = "measured_") -> "Measurements":
        """A copy whose ``x_mm, y_mm, z_mm`` are ``xyz_m``; existing ones are renamed."""
        cols: dict[str, np.ndarray] = {}
        for k, v in self.columns.items():
            cols[prefix_existing + k if k in XYZ else k] = v
        for i, c in enumerate(XYZ):
            cols[c] = np.asarray(xyz_m)[:, i] * 1000.0
        out = self.with_columns(cols)
        out.checked = set()
        return out

    def with_orientations(self, R: np.ndarray, prefix_existing: str = "measured_") -> "Measurements":
        """A copy whose ``rx_deg, ry_deg, rz_deg`` hold the rotations ``R`` (N, 3, 3); existing ones are renamed."""
        cols: dict[str, np.ndarray] = {}
        for k, v in self.columns.items():
            cols[prefix_existing + k if k in RXYZ else k] = v
        angles = rotation_angles(R)
        for i, c in enumerate(RXYZ):
            cols[c] = angles[:, i]
        return Measurements(cols, self.path, self.rows, self.moves, self.lines)

    # --- I/O --------------------------------------------------------------------

    @classmethod
    def read_csv(cls, path: str | Path, n_joints: int | None = None,
                 require_positions: bool = False, robot=None) -> "Measurements":
        """Read and validate a measurement file.

        Parameters
        ----------
        path : str or Path
        n_joints : int, optional
            The robot's joint count: the file must have exactly
            ``q1_deg..q<n_joints>_deg``.
        require_positions : bool
            The file must contain measured positions.
        robot : Robot, optional
            The robot the readings are of: its joint count (as ``n_joints``), and each joint's column must be
            in its unit (``qK_mm`` for a prismatic joint, ``qK_deg`` for a revolute one).

        Raises
        ------
        DataFileError
            Naming file, row (1-based line; the header is row 1) and column.
        """
        path = str(path)
        if robot is not None:
            n_joints = robot.n
        # the rows are converted in chunks: the numbers of a 200,000-row file stay in memory, not its text
        with _csv_rows(path) as rows:
            header, numeric = _check_header(next(rows, None), path, n_joints, require_positions)
            if robot is not None:
                check_reading_units(header, robot, path)
            blank = ({h for h in header if h in XYZ or h in RXYZ} if any(h in TOUCH for h in header) else set()) \
                | ({DISTANCE} if DISTANCE in header else set())
            columns, lines = _read_body(rows, header, numeric | blank, path, blank)
        text = [h for h in header if columns[h] is None]
        if text:  # columns of words: read again for their exact text
            with _csv_rows(path) as rows:
                columns.update(_text_columns(rows, header, text))
        data = cls(columns, path, lines=np.array(lines))
        if any(h in TOUCH for h in header) or DISTANCE in header:
            check_touch_rows(data)
        if n_joints is None:  # with a robot, casadical.data._checks judges the units (an error, not a warning)
            _check_units(data)
        return data

    def write_csv(self, path: str | Path, overwrite: bool = False) -> None:
        """Write the contract CSV atomically; refuses to replace a file unless ``overwrite``.

        Floats are written with :func:`repr`, the shortest text that reads
        back to the same double: nothing is lost in a round trip.
        """
        header = list(self.columns)
        with atomic_open(path, "w", overwrite=overwrite, newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(header)
            cols = [self.columns[h].tolist() for h in header]
            w.writerows([_fmt(v) for v in row] for row in zip(*cols))

    @classmethod
    def from_arrays(cls, q_rad: np.ndarray, xyz_m: np.ndarray | None = None, prismatic=(),
                    **extra: np.ndarray) -> "Measurements":
        """Build from arrays (radians, metres); ``extra`` columns are added as given. ``prismatic``: per joint, a
        linear axis (its reading in metres, written to a ``qK_mm`` column); empty: none."""
        q_rad = np.atleast_2d(q_rad)
        linear = [bool(prismatic) and bool(prismatic[i]) for i in range(q_rad.shape[1])]
        cols = {(f"q{i + 1}_mm" if linear[i] else f"q{i + 1}_deg"):
                (q_rad[:, i] * 1000.0 if linear[i] else np.degrees(q_rad[:, i])) for i in range(q_rad.shape[1])}
        if xyz_m is not None:
            for i, c in enumerate(XYZ):
                cols[c] = np.asarray(xyz_m)[:, i] * 1000.0
        for k, v in extra.items():
            cols[k] = np.asarray(v)
        return cls(cols)


#: the columns read by name (besides q1_deg ..): a header that is one of them in other letter case is an error
_KNOWN = frozenset(XYZ) | frozenset(RXYZ) | frozenset(NUMERIC_OPTIONAL) | {"session", DISTANCE, TOOL, *TOUCH}


def _other_separator(header: list[str], path: str) -> str:
    """For a header without joint columns: the separator it seems to use instead of commas, and the import that
    converts the file (empty if it seems to use none)."""
    if len(header) != 1:
        return ""
    for sep, name in ((";", ";"), ("\t", "tab"), ("|", "|")):
        fields = [f.strip() for f in header[0].split(sep)]
        if len(fields) > 1:
            break
    else:
        return ""
    joints = [f for f in fields if _Q.match(f)]
    how = f"casadical import {path} --map 'separator={name}'"
    if joints:
        how += f" --map joints={','.join(joints)} --map joint_unit=deg"
        if all(c in fields for c in XYZ):
            how += f" --map position={','.join(XYZ)} --map position_unit=mm"
    else:
        how += " --map joints=... (docs/formats.md, section 5)"
    return (f"; its header is one field, {_short(header[0])!r}: the file seems separated by {name!r}, the "
            f"measurement CSV by commas; convert it with {how} --out NEW.csv (and --map 'decimal=,' if its numbers "
            "have decimal commas)")


def _short(text: str, n: int = 40) -> str:
    return text if len(text) <= n else text[:n] + "..."


def _misspelt(header: list[str], missing: str, present: list[str], path: str) -> None:
    """An unknown column that looks like the missing one of a triple (``x_mn`` for ``x_mm``) is the one named; one
    that holds a name of the triple whole (``std_z_mm``, ``std_y_mm``: other columns about them) is not a
    misspelling."""
    import difflib

    unknown = [h for h in header
               if h not in _KNOWN and not _Q.match(h) and not any(c in h for c in (missing, *present))]
    near = difflib.get_close_matches(missing, unknown, n=1, cutoff=0.6)
    if near:
        raise DataFileError(f"is not a column casadical knows; is it {missing!r}? ({', '.join(present)} are there, "
                            f"{missing} is not)", file=path, row=1, column=near[0])


def _check_header(first: list[str] | None, path: str, n_joints: int | None, require_positions: bool
                  ) -> tuple[list[str], set[str]]:
    """The header row checked (see :meth:`Measurements.read_csv`); its names and the numeric columns."""
    if not first or not any(h.strip() for h in first):
        raise DataFileError("is empty: expected a header row (q1_deg, ..., x_mm, y_mm, z_mm)",
                            file=path, row=1)
    header = [h.strip() for h in first]
    seen: dict[str, int] = {}
    for i, h in enumerate(header):
        if not h:
            raise DataFileError(f"header field {i + 1} is empty", file=path, row=1)
        if _Q_LIKE.match(h) and not _Q.match(h):
            raise DataFileError("joint columns are numbered from 1 without leading zeros: "
                                "q1_deg, q2_deg, ...", file=path, row=1, column=h)
        if h in seen:
            raise DataFileError(f"duplicated header name (fields {seen[h] + 1} and {i + 1})",
                                file=path, row=1, column=h)
        seen[h] = i
        if h != h.lower() and (h.lower() in _KNOWN or _Q.match(h.lower())):
            # an extra column is kept and not read: 'Payload_kg' would be a payload silently left out
            raise DataFileError(f"column names are lower case: write {h.lower()!r}", file=path, row=1, column=h)
    qs = sorted(int(m.group(1)) for h in header if (m := _Q.match(h)))
    twice = sorted({k for k in qs if qs.count(k) > 1})
    if twice:
        raise DataFileError(f"joint {twice[0]} has two reading columns (q{twice[0]}_deg and q{twice[0]}_mm): a "
                            "revolute joint's is in degrees, a prismatic one's in millimetres", file=path, row=1,
                            column=f"q{twice[0]}_mm")
    if not qs:
        raise DataFileError("has no joint columns: expected q1_deg, q2_deg, ..." + _other_separator(header, path),
                            file=path, row=1)
    if qs != list(range(1, len(qs) + 1)):
        present = set(qs)
        first = next(k for k in range(1, len(qs) + 2) if k not in present)
        raise DataFileError(f"joint columns are not consecutive: missing q{first}_deg",
                            file=path, row=1, column=f"q{first}_deg")
    if n_joints is not None and len(qs) != n_joints:
        col = f"q{n_joints + 1}_deg" if len(qs) > n_joints else f"q{len(qs) + 1}_deg"
        raise DataFileError(f"has {len(qs)} joint columns but the robot has {n_joints} joints",
                            file=path, row=1, column=col)
    present = [c for c in XYZ if c in seen]
    if present and len(present) < 3:
        missing = [c for c in XYZ if c not in seen][0]
        _misspelt(header, missing, present, path)
        raise DataFileError("has only some of x_mm, y_mm, z_mm", file=path, row=1, column=missing)
    turned = [c for c in RXYZ if c in seen]
    if turned and len(turned) < 3:
        missing = [c for c in RXYZ if c not in seen][0]
        _misspelt(header, missing, turned, path)
        raise DataFileError("has only some of rx_deg, ry_deg, rz_deg (the measured orientation)", file=path, row=1,
                            column=missing)
    if require_positions and not present and not any(h in TOUCH for h in header):
        raise DataFileError("has no measured positions: columns x_mm, y_mm, z_mm (or what the tool point touched: "
                            "point, plane; docs/formats.md section 11) are required here", file=path, row=1,
                            column="x_mm")
    numeric = ({h for h in header if _Q.match(h)} | set(present) | set(turned)
               | {c for c in NUMERIC_OPTIONAL if c in seen})
    return header, numeric


@contextlib.contextmanager
def _csv_rows(path: str) -> Iterator[Iterator[list[str]]]:
    """The rows of a CSV file; a file that cannot be read is a DataFileError naming it."""
    reader = None
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            yield reader
    except FileNotFoundError:
        raise DataFileError("no such file", file=path) from None
    except csv.Error as e:     # an oversized field, a NUL: the reader has counted the line at fault
        raise DataFileError(f"malformed CSV: {e}", file=path, row=reader.line_num if reader else None) from e
    except (OSError, UnicodeDecodeError) as e:
        raise DataFileError(f"cannot read: {e}", file=path) from e


#: rows converted at a time by read_csv
READ_CHUNK = 8192


def _read_body(reader, header: list[str], numeric: set[str], path: str, blank: set[str] = frozenset()
               ) -> tuple[dict, list[int]]:
    """Columns of the data rows, converted chunk by chunk; None for a column that is not all numbers; an empty
    cell of a column of ``blank`` is NaN (a touch row's position)."""
    parts: dict[str, list | None] = {h: [] for h in header}
    lines: list[int] = []
    chunk: list[list[str]] = []

    def convert() -> None:
        rows = lines[len(lines) - len(chunk):]
        for h, values in zip(header, zip(*chunk)):
            values = [x.strip() for x in values]
            whole = _whole_numbers(values) if h not in numeric or h == "source_row" else None
            if whole is not None and parts[h] is not None:    # kept whole: written back as they were, 856 not 856.0
                parts[h].append(whole)
            elif h in numeric:
                parts[h].append(_numeric(values, h, path, rows, h in blank))
            elif parts[h] is not None:
                try:
                    parts[h].append(np.array([float(x) for x in values]))
                except ValueError:
                    parts[h] = None
        chunk.clear()

    end = reader.line_num            # the header's last line
    for r in reader:
        line, end = end + 1, reader.line_num   # the record's first line (a quoted field may span lines)
        if not any(x.strip() for x in r):
            continue
        if len(r) != len(header):
            raise DataFileError(f"has {len(r)} fields, the header has {len(header)}", file=path, row=line)
        chunk.append(r)
        lines.append(line)
        if len(chunk) == READ_CHUNK:
            convert()
    if not lines:
        raise DataFileError("has a header but no data rows", file=path, row=2)
    convert()
    return {h: None if p is None else np.concatenate(p) for h, p in parts.items()}, lines


_WHOLE = re.compile(r"[+-]?\d{1,15}")


def _whole_numbers(values: list[str]) -> np.ndarray | None:
    """The cells as integers if every one is written as a whole number (a row number, a count), else None."""
    if not all(_WHOLE.fullmatch(x) for x in values):
        return None
    return np.array([int(x) for x in values], dtype=np.int64)


def _text_columns(reader, header: list[str], names: list[str]) -> dict[str, np.ndarray]:
    """The stripped text of columns ``names`` over the data rows."""
    idx = [header.index(h) for h in names]
    out: dict[str, list[str]] = {h: [] for h in names}
    next(reader, None)
    for r in reader:
        if any(x.strip() for x in r):
            for h, i in zip(names, idx):
                out[h].append(r[i].strip())
    return {h: np.array(v, dtype=object) for h, v in out.items()}


#: the largest payload (kg) a file may give (as for a robot file's masses): beyond it a unit mistake
MAX_PAYLOAD_KG = 1e5


def _check_payload(payload: np.ndarray | None, lines: list[int], path: str) -> None:
    """A payload is a mass: >= 0 (a negative one would lift the arm), and within :data:`MAX_PAYLOAD_KG`."""
    if payload is None:
        return
    bad = np.flatnonzero((payload < 0) | (payload > MAX_PAYLOAD_KG))
    if len(bad):
        i = int(bad[0])
        more = f" ({len(bad)} rows in all)" if len(bad) > 1 else ""
        raise DataFileError(f"payload {payload[i]:g} kg is not a mass from 0 to {MAX_PAYLOAD_KG:g} kg{more}",
                            file=path, row=lines[i], column="payload_kg")


def _numeric(values: list[str], column: str, path: str, lines: list[int], blank: bool = False) -> np.ndarray:
    out = np.empty(len(values))
    for i, x in enumerate(values):
        if blank and x == "":
            out[i] = np.nan
            continue
        try:
            v = float(x)
        except ValueError:
            what = "is empty" if x == "" else f"is not a number: {x!r}"
            hint = " (decimal comma? use a point)" if re.fullmatch(r"-?\d+,\d+", x) else ""
            raise DataFileError(f"value {what}{hint}", file=path, row=lines[i], column=column) from None
        if not math.isfinite(v):
            raise DataFileError(f"value is {x!r}: every value must be finite", file=path,
                                row=lines[i], column=column)
        out[i] = v
    return out


#: the fewest rows of a session that fix a touched point or plane (docs/formats.md section 11)
MIN_TOUCH_ROWS = 4


def check_touch_rows(data: Measurements) -> None:
    """The rows of a file with ``point``, ``plane`` or ``distance_mm`` as docs/formats.md section 11 says: a touch
    row has no measured position, every other row has one, a distance goes with a point, a point or plane is
    touched by enough rows of its session (one line naming the file, row and column)."""
    point, plane, touching = data._text("point"), data._text("plane"), data.touching
    both = np.flatnonzero(point & plane)
    if len(both):
        raise DataFileError("a row touches a point and a plane: give one", file=data.path, row=data.line(both[0]),
                            column="plane")
    distance = data.get(DISTANCE)
    if distance is not None:
        has = np.isfinite(distance)
        bad = np.flatnonzero(has & ~point)
        if len(bad):
            raise DataFileError("distance_mm without a point: a distance is measured from a pivot, named in point",
                                file=data.path, row=data.line(bad[0]), column=DISTANCE)
        bad = np.flatnonzero(has & (distance <= 0))
        if len(bad):
            raise DataFileError(f"distance {distance[bad[0]]:g} mm is not a length", file=data.path,
                                row=data.line(bad[0]), column=DISTANCE)
    if data.has_positions:
        xyz = np.column_stack([data.columns[c] for c in XYZ])
        measured = np.isfinite(xyz).any(axis=1)
        bad = np.flatnonzero(touching & measured)
        if len(bad):
            raise DataFileError("a row with point or plane has measured positions too: a row measures where the "
                                "tool point was or says what it touched, not both", file=data.path,
                                row=data.line(bad[0]), column="point" if point[bad[0]] else "plane")
        part = np.flatnonzero(~touching & ~np.isfinite(xyz).all(axis=1))
        if len(part):
            i = int(part[0])
            col = XYZ[int(np.flatnonzero(~np.isfinite(xyz[i]))[0])]
            raise DataFileError("value is empty: a row that touches nothing (no point, no plane) is measured",
                                file=data.path, row=data.line(i), column=col)
    elif (~touching).any():
        i = int(np.flatnonzero(~touching)[0])
        raise DataFileError("a row touches nothing (point and plane empty) and the file has no x_mm, y_mm, z_mm",
                            file=data.path, row=data.line(i), column="point")
    sessions = data.sessions if data.sessions is not None else np.full(len(data), "", dtype=object)
    for column, mask in (("point", point), ("plane", plane)):
        names = data.columns[column] if column in data.columns else None
        if names is None:
            continue
        names = np.array([str(v).strip() for v in names], dtype=object)
        for s in dict.fromkeys(sessions.tolist()):
            for name in dict.fromkeys(names[mask & (sessions == s)].tolist()):
                rows = np.flatnonzero(mask & (sessions == s) & (names == name))
                if len(rows) < MIN_TOUCH_ROWS:
                    where = f" of session {s}" if s else ""
                    raise DataFileError(f"{column} {name!r} is touched by {len(rows)} row(s){where}: too few to fix "
                                        f"it (at least {MIN_TOUCH_ROWS})", file=data.path,
                                        row=data.line(rows[0]), column=column)


def check_fixtures(data: Measurements) -> None:
    """A fixture's points against the rows: a point the rows touch with a distance is a pivot, not a fixture's;
    a fixture point that no row touches is a warning."""
    point = data.columns.get("point")
    touched = set() if point is None else {str(v).strip() for v in point}
    for f in data.fixtures:
        unused = [p for p in f.points if p not in touched]
        if unused:
            warnings.warn(f"{f.file}: fixture {f.name}'s point(s) {', '.join(unused)} are touched by no row of "
                          f"{data.path}", DataWarning, stacklevel=3)


#: fewer rows than this never look like radians
MIN_ROWS_RADIANS = 5


def last_moves(q: np.ndarray) -> np.ndarray:
    """Sign of each joint's last move before each row, in row order, shape of ``q``.

    A joint that does not move between two rows keeps the direction of its
    earlier move (it rests on the same flank of its play); 0 until its first
    move.
    """
    out = np.zeros_like(q, dtype=float)
    for i in range(1, len(q)):
        step = np.sign(q[i] - q[i - 1])
        out[i] = np.where(step != 0, step, out[i - 1])
    return out


def looks_like_radians(q_deg: np.ndarray, tol: float = 1e-9) -> bool:
    """Joint readings (rows x joints) that look like radians: every one within +-2 pi (+ ``tol``), not all
    zero, over :data:`MIN_ROWS_RADIANS` rows or more (readings in degrees span tens of degrees)."""
    top = float(np.max(np.abs(q_deg))) if np.size(q_deg) else 0.0
    return len(q_deg) >= MIN_ROWS_RADIANS and 0 < top <= 2 * math.pi + tol


def check_reading_units(header: list[str], robot, path: str) -> None:
    """Each joint's reading column in its joint's unit: ``qK_mm`` for a prismatic joint (a linear axis),
    ``qK_deg`` for a revolute one (one line naming file, row 1 and the column)."""
    for h in header:
        m = _Q.match(h)
        if not m or int(m.group(1)) > robot.n:
            continue
        k, unit = int(m.group(1)), m.group(2)
        joint = robot.joints[k - 1]
        if unit != joint.unit:
            what = ("prismatic (a linear axis): its readings are millimetres, column" if joint.prismatic
                    else "revolute: its readings are degrees, column")
            raise DataFileError(f"joint {k} of {robot.name} is {what} q{k}_{joint.unit}", file=path, row=1,
                                column=h)


def _check_units(data: Measurements) -> None:
    angles = [j for j, linear in enumerate(data.prismatic) if not linear]
    if angles and looks_like_radians(data.q_deg[:, angles]):
        warnings.warn(f"{data.path}: every joint reading is within +-6.3: "
                      "these look like radians, but _deg columns must hold degrees", DataWarning,
                      stacklevel=3)


def session_index(data: Measurements) -> dict[str, np.ndarray]:
    """The poses of each session (a single unnamed session: ``{"": all poses}``)."""
    if data.sessions is None:
        return {"": np.arange(len(data))}
    return {s: np.flatnonzero(data.sessions == s) for s in data.session_names}


_NOT_IN_NAME = re.compile(r"[^A-Za-z0-9_.-]+")


def session_name(value) -> str:
    """A session's name as model specifications and reports use it: letters, digits, ``_ . -`` (anything
    else becomes ``_``; a whole number read as 2.0 is ``2``)."""
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        value = int(value)
    return _NOT_IN_NAME.sub("_", str(value).strip()) or "_"

def rotation_matrices(angles_deg: np.ndarray) -> np.ndarray:
    """Rotations ``Rx(rx) Ry(ry) Rz(rz)`` (intrinsic XYZ) of angles (deg, shape (N, 3)), shape (N, 3, 3)."""
    from scipy.spatial.transform import Rotation  # here: scipy's import costs every command's start-up
    return Rotation.from_euler("XYZ", np.asarray(angles_deg, float).reshape(-1, 3), degrees=True).as_matrix()


def rotation_angles(R: np.ndarray) -> np.ndarray:
    """The angles (deg, shape (N, 3)) ``rx, ry, rz`` with ``R = Rx(rx) Ry(ry) Rz(rz)`` (intrinsic XYZ)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(np.asarray(R, float).reshape(-1, 3, 3)).as_euler("XYZ", degrees=True)


def _fmt(x) -> str:
    return repr(float(x)) if isinstance(x, (float, np.floating)) else str(x)
