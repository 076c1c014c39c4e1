"""The user's own columns of a measurement file, as what an error may follow.

A measurement file may hold numeric columns casadical does not read as such (docs/formats.md section 2: every
other column is kept). They are of two kinds:

- a **session covariate**: constant within each session and not the same in all of them (a lifting column's
  height, a payload changed between sessions, a track position, the hall's temperature of the day): what a
  cause of the session may follow by a law with few parameters instead of one value per session (the mount's
  compliance growing with the column's height, :class:`casadical.terms._mount_compliance.MountCompliance`);
- a **per-pose covariate**: one that changes within a session (a tilt sensor, an accelerometer, a temperature, a
  motor current): what the structure screen tests what the model leaves against (:mod:`casadical.diagnosis.
  structure`), and a name a terms file may use (docs/formats.md section 10).

Neither is a reading, a measured value, the pose's time or place in its file, or a column ``split`` writes (the
readings, ``x_mm``, ..., ``time_s``, ``source_row``, ``move<j>``, ``session``).
"""

from __future__ import annotations

import re

import numpy as np

from ._measurements import NUMERIC_OPTIONAL, RXYZ, XYZ, Measurements

#: columns that are never covariates of one's own: the pose's readings, its measured values, its time, where it
#: came from (``split`` writes ``source_row`` and ``move<j>``)
_RESERVED = re.compile(r"^(q\d+_(deg|mm)|move\d+|measured_.*)$")
#: the catalogue reads these itself (a payload enters the torques, a temperature a thermal expansion); as a
#: session's value they may still be a session covariate
_READ = ("payload_kg", "temperature_c")


def own_columns(data: Measurements) -> list[str]:
    """The numeric columns of ``data`` that may be covariates (file order): not a reading, a measured value, the
    time, a row's origin, every value finite."""
    skip = set(XYZ) | set(RXYZ) | (set(NUMERIC_OPTIONAL) - set(_READ)) | {"session"}
    out = []
    for name in data.columns:
        v = data.get(name)
        if name in skip or _RESERVED.match(name) or v is None or not np.all(np.isfinite(v)):
            continue
        out.append(name)
    return out


def session_covariates(data: Measurements) -> dict[str, dict[str, float]]:
    """The session covariates of ``data``: each numeric column constant within every session and taking two values
    or more over them, with its value in each session (by session, in their order); none for data of one
    session."""
    names = data.session_names
    if len(names) < 2:
        return {}
    out = {}
    for c in own_columns(data):
        v = np.asarray(data.get(c), float)
        per = {s: v[data.sessions == s] for s in names}
        if all(np.ptp(x) == 0 for x in per.values()) and len({float(x[0]) for x in per.values()}) > 1:
            out[c] = {s: float(x[0]) for s, x in per.items()}
    return out


def pose_covariates(data: Measurements) -> list[str]:
    """The per-pose covariates of ``data``: each numeric column of one's own (:func:`own_columns`) that changes
    within a session (a sensor's; a temperature too), beside the payload, which enters the gravity torques."""
    sessions = data.sessions if data.sessions is not None else np.zeros(len(data))
    out = []
    for c in own_columns(data):
        if c == "payload_kg":
            continue
        v = np.asarray(data.get(c), float)
        if any(np.ptp(v[sessions == s]) > 0 for s in dict.fromkeys(sessions.tolist())):
            out.append(c)
    return out
