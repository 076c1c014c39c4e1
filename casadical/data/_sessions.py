"""Measurement sessions: several files (or a ``session`` column) of one robot.

A session is one set-up of the measurement: a tracker placement, a day, a
probe mount. What belongs to a session (where the robot stands in the
tracker frame, a re-mounted probe, a drift of that day) differs from
session to session; what belongs to the robot (its geometry, its joints'
stiffness, its gears) holds in all of them. A calibration of several
sessions fits one robot with a base pose per session
(:class:`casadical.terms._sessions.SessionFrames`), and the diagnosis asks of
every cause whether one value serves every session.

Sessions come from the ``session`` column of a file (docs/formats.md section
2), or one per file when several files are given (``calibrate ROBOT A.csv
B.csv``): :func:`read_sessions` and :func:`combine`.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import DataFileError, DataWarning, listing
from ._measurements import DISTANCE, RXYZ, TOOL, TOUCH, XYZ, Measurements, session_name


def read_sessions(paths: list[str], n_joints: int | None = None, require_positions: bool = False,
                  names: list[str] | None = None, robot=None) -> Measurements:
    """Read one or several measurement files as the sessions of one data set.

    One file is read as it is (its ``session`` column, if any, names its
    sessions); several are combined by :func:`combine`, each file one
    session named after it (its ``session`` column, if any, wins).
    """
    parts = [Measurements.read_csv(p, n_joints=n_joints, require_positions=require_positions, robot=robot)
             for p in paths]
    return parts[0] if len(parts) == 1 else combine(parts, names)


def file_session_names(paths: list[str]) -> list[str]:
    """A session name per file: its name without the extension (``A.csv`` -> ``A``), made unique."""
    out: list[str] = []
    for p in paths:
        base = session_name(Path(p).stem)
        name, k = base, 2
        while name in out:
            name, k = f"{base}-{k}", k + 1
        out.append(name)
    return out


def combine(parts: list[Measurements], names: list[str] | None = None) -> Measurements:
    """Several data sets of one robot as one, each a session (or several, by its ``session`` column).

    Parameters
    ----------
    parts : list of Measurements
        The same joints in each.
    names : list of str, optional
        A session name per part (default: the files' names,
        :func:`file_session_names`); a part with a ``session`` column
        keeps its own names.

    Returns
    -------
    Measurements
        Rows in the parts' order; ``sessions`` and ``sources`` per row; each
        pose's row in the measurement order (``rows``) numbered on after the
        previous part's, so the order within each session is kept. Columns
        that not every part has are dropped (a warning names them): a
        covariate must be known at every pose.

    Raises
    ------
    DataFileError
        The parts have different joints, two parts give one session name, or
        one part's poses are all another's (:func:`casadical.data._checks.check_sessions_apart`;
        some of them: a warning).
    """
    if not parts:
        raise DataFileError("no measurement file given")
    names = names or file_session_names([p.path for p in parts])
    n = parts[0].n_joints
    for p in parts[1:]:
        if p.n_joints != n:
            raise DataFileError(f"has {p.n_joints} joint columns, {parts[0].path} has {n}: the sessions of one "
                                "calibration must be of one robot", file=p.path, row=1)
    from ._checks import check_sessions_apart
    check_sessions_apart(parts)      # a file given twice (or its copy) would count its poses twice
    common = [c for c in parts[0].columns if all(c in p.columns for p in parts[1:])]
    # how a row is measured (a measured point, what it touched, its tool point) is every row's: a file without
    # such a column has it empty (a tracker session beside a session that touches)
    measured = [c for c in dict.fromkeys(c for p in parts for c in p.columns)
                if c in (*XYZ, *RXYZ, *TOUCH, DISTANCE, TOOL) and c not in common]
    common += measured
    dropped = sorted({c for p in parts for c in p.columns} - set(common) - {"session"})
    if dropped:
        warnings.warn(f"{listing(dropped)}: not in every file ({', '.join(p.path for p in parts)}), so not used: "
                      "a covariate must be known at every pose", DataWarning, stacklevel=2)
    labels, seen = [], {}
    for p, name in zip(parts, names):
        own = p.sessions if p.sessions is not None else np.full(len(p), name, dtype=object)
        for s in dict.fromkeys(own.tolist()):
            if s in seen:
                raise DataFileError(f"session {s!r} is also in {seen[s]}: give each file its own session names",
                                    file=p.path)
            seen[s] = p.path
        labels.append(own)
    columns = {}
    for c in common:
        if c == "session":
            continue
        text = c in (*TOUCH, TOOL)
        values = [p.columns[c] if c in p.columns else
                  np.full(len(p), "" if text else np.nan, dtype=object if text else float) for p in parts]
        if any(v.dtype.kind not in "fiu" for v in values):
            values = [v.astype(object) for v in values]
        columns[c] = np.concatenate(values)
    offsets = np.cumsum([0] + [int(p.rows.max()) + 1 for p in parts[:-1]])
    rows = np.concatenate([p.rows + o for p, o in zip(parts, offsets)])
    checked = set.intersection(*(p.checked for p in parts))
    return Measurements(columns, " + ".join(p.path for p in parts), rows, np.concatenate([p.moves for p in parts]),
                        np.concatenate([p.lines for p in parts]), checked, np.concatenate(labels).astype(object),
                        np.concatenate([np.full(len(p), p.path, dtype=object) for p in parts]),
                        tuple({f.name: f for p in parts for f in p.fixtures}.values()))
