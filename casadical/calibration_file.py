"""Validation of a calibration JSON before it is used (section 4 of docs/formats.md).

A calibration file is read back by :func:`casadical.calibration.load_calibration`
and then predicts positions: a missing key, a value of the wrong type, a NaN
parameter or a parameter of another model must stop there, with one line
naming the file and the key as a JSON path (``parameters[3].value``), not
turn into a traceback or into predictions that are NaN or wrong.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from . import __version__
from .errors import CalibrationFileError, ModelError, RobotFileError, listing
from .files import finite_number
from .model import assemble_terms, parse_spec
from .robot import Robot, robot_from_dict

STATS_KEYS = ("n_poses", "mean_mm", "max_mm", "std_mm", "rms_mm")
#: term settings that may be zero or negative (all other numeric settings must be positive)
SIGNED_SETTINGS = {"t_ref"}


def validate_calibration_document(doc: Any, path: str) -> None:
    """Check a parsed calibration JSON: every key :func:`load_calibration` reads, with its type.

    Parameters
    ----------
    doc : object
        The parsed JSON document.
    path : str
        The file, for messages.

    Raises
    ------
    CalibrationFileError
        Naming the file and the key (``column``, a JSON path): a missing or
        mistyped key, a non-finite number, an unknown term setting or
        parameter, parameters missing or given twice, a ``base0`` whose
        rotation is not a rotation.
    """
    def err(key: str | None, message: str) -> CalibrationFileError:
        return CalibrationFileError(message, file=path, column=key)

    if not isinstance(doc, dict):
        raise err(None, f"must be a JSON object written by 'casadical calibrate', got {_kind(doc)}")
    for key in ("robot", "model", "parameters", "base0"):
        if key not in doc:
            raise err(key, "missing key: not a calibration written by 'casadical calibrate'")
    if not isinstance(doc["robot"], dict):
        raise err("robot", f"must be an object (the robot description), got {_kind(doc['robot'])}")
    try:
        robot = robot_from_dict(doc["robot"], path)
    except RobotFileError as e:
        raise err("robot" + (f".{e.column}" if e.column else ""), e.message) from e
    if not isinstance(doc["model"], str):
        raise err("model", f"must be a model specification string, got {_kind(doc['model'])}")
    terms = _terms(robot, doc["model"], err)
    _check_settings(doc.get("terms", {}), terms, err)
    _check_version(doc.get("casadical_version"), err)
    units = {p.name: p.unit for t in terms for p in t.parameters(robot)}
    _check_parameters(doc["parameters"], list(units), doc["model"], err, units)
    _check_base0(doc["base0"], err)
    _check_stats(doc.get("calibration"), err)
    _check_robust(doc.get("robust"), err)
    _check_coverage(doc.get("coverage"), err)
    notes = doc.get("notes", [])
    if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
        raise err("notes", "must be a list of strings")


def _terms(robot: Robot, spec: str, err) -> list:
    """The model's terms as :class:`~casadical.model.Model` builds them (geometric first), bound to the robot."""
    try:
        return assemble_terms(parse_spec(spec), robot)
    except ModelError as e:
        raise err("model", str(e)) from e


def _check_settings(settings: Any, terms: list, err) -> None:
    if not isinstance(settings, dict):
        raise err("terms", f"must be an object of term settings, got {_kind(settings)}")
    # keyed by each term's specification (older files: by its name)
    by_name = {t.name: t for t in terms} | {t.spec(): t for t in terms}
    for name, values in settings.items():
        key = f"terms.{name}"
        if name not in by_name:
            raise err(key, f"the model has no term {name!r} (terms: {', '.join(t.spec() for t in terms)})")
        if not isinstance(values, dict):
            raise err(key, f"must be an object of settings, got {_kind(values)}")
        known = by_name[name].settings()
        for k, v in values.items():
            if k not in known:
                raise err(f"{key}.{k}", f"unknown setting (known: {', '.join(known)})")
            default = known[k]
            if isinstance(default, str):
                if not isinstance(v, str):
                    raise err(f"{key}.{k}", f"must be a string, got {_kind(v)}")
            elif isinstance(default, (int, float)) and not isinstance(default, bool):
                if not finite_number(v):
                    raise err(f"{key}.{k}", f"must be a finite number, got {v!r}")
                if k not in SIGNED_SETTINGS and not v > 0:
                    raise err(f"{key}.{k}", f"must be positive, got {v!r}")


#: plausible sizes of parameter values by SI unit, as for a robot file's keys (casadical.robot): beyond them a
#: value is a unit mistake or a slip of the hand, and overflows the model or an exported URDF
#: (values are in display units: mm and degrees)
_VALUE_RANGES = {"m": (1e5, "a length in mm"), "rad": (36000.0, "an angle in degrees")}


def _check_version(version: Any, err) -> None:
    """A calibration written by a newer casadical may mean what this one cannot read: refused."""
    if version is None:
        return
    if not isinstance(version, str) or not re.match(r"\d+(\.\d+)*", version):
        raise err("casadical_version", f"must be a version string such as \"{__version__}\", got {version!r}")
    if _release(version) > _release(__version__):
        raise err("casadical_version", f"written by casadical {version}, newer than this casadical {__version__}: "
                                       "it may hold what this version would read wrongly; update casadical "
                                       "(pip install -U casadical) to use it")


def _release(version: str) -> tuple[int, ...]:
    """The leading numbers of a version string (``0.10.2rc1`` -> (0, 10, 2)), zeros dropped at the end."""
    parts = [int(x) for x in re.match(r"\d+(?:\.\d+)*", version).group(0).split(".")]
    while parts and parts[-1] == 0:
        parts.pop()
    return tuple(parts)


def _check_parameters(entries: Any, names: list[str], spec: str, err, units: dict[str, str] | None = None) -> None:
    if not isinstance(entries, list):
        raise err("parameters", f"must be a list of parameter objects, got {_kind(entries)}")
    known, seen = set(names), {}
    for i, e in enumerate(entries):
        at = f"parameters[{i}]"
        if not isinstance(e, dict):
            raise err(at, f"must be an object (name, value, std, ...), got {_kind(e)}")
        if not isinstance(e.get("name"), str):
            raise err(f"{at}.name", "missing or not a string")
        if e.get("derived") is not None:   # k<j> = 1/c<j>: written for people, never read back
            if not isinstance(e["derived"], str):
                raise err(f"{at}.derived", f"must be a string, got {_kind(e['derived'])}")
            continue
        name = e["name"]
        if name not in known:
            raise err(f"{at}.name", f"model {spec} has no parameter {name!r}")
        if name in seen:
            raise err(f"{at}.name", f"parameter {name!r} is given twice (also parameters[{seen[name]}])")
        seen[name] = i
        if "value" not in e:
            raise err(f"{at}.value", f"missing value of {name}")
        if not finite_number(e["value"]):
            raise err(f"{at}.value", f"value of {name} must be a finite number, got {e['value']!r}")
        top, what = _VALUE_RANGES.get((units or {}).get(name, ""), (math.inf, ""))
        if abs(e["value"]) > top:
            raise err(f"{at}.value", f"value of {name} is {what} and must lie within +-{top:g}, got {e['value']:g}")
        if e.get("std") is not None and not (finite_number(e["std"]) and e["std"] >= 0):
            raise err(f"{at}.std", f"std of {name} must be null or a finite number >= 0, got {e['std']!r}")
        if "fixed" in e and not isinstance(e["fixed"], bool):
            raise err(f"{at}.fixed", f"must be true or false, got {e['fixed']!r}")
        if e.get("identifiable") is not None and not isinstance(e["identifiable"], bool):
            raise err(f"{at}.identifiable", f"must be true, false or null, got {e['identifiable']!r}")
        if "reason" in e and not isinstance(e["reason"], str):
            raise err(f"{at}.reason", f"must be a string, got {_kind(e['reason'])}")
    missing = [n for n in names if n not in seen]
    if missing:
        raise err("parameters", f"has {len(seen)} of the {len(names)} parameters of model {spec}; missing "
                                f"{listing(missing)}")


def _check_base0(base0: Any, err) -> None:
    if not isinstance(base0, list) or len(base0) != 12 or not all(finite_number(x) for x in base0):
        raise err("base0", "must be a list of 12 finite numbers (rotation row-major, translation in m)")
    R = np.array(base0[:9], dtype=float).reshape(3, 3)
    # a rotation's entries lie in [-1, 1]: checked first, so a huge number cannot overflow the product
    if np.abs(R).max() > 1 + 1e-6 or np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) <= 0:
        raise err("base0", "its first 9 numbers are not a rotation matrix (row-major)")


def _check_stats(stats: Any, err) -> None:
    if stats is None:
        return
    if not isinstance(stats, dict):
        raise err("calibration", f"must be an object ({', '.join(STATS_KEYS)}) or null, got {_kind(stats)}")
    for k in stats:
        if k not in STATS_KEYS:
            raise err(f"calibration.{k}", f"unknown key (known: {', '.join(STATS_KEYS)})")
    for k in STATS_KEYS:
        v = stats.get(k)
        ok = (isinstance(v, int) and not isinstance(v, bool) and v >= 0) if k == "n_poses" \
            else (finite_number(v) and v >= 0)
        if not ok:
            raise err(f"calibration.{k}", f"must be a {'whole' if k == 'n_poses' else 'finite'} number >= 0, "
                                          f"got {v!r}")


def _check_robust(robust: Any, err) -> None:
    if robust is None:
        return
    if not isinstance(robust, dict):
        raise err("robust", f"must be an object (loss, c, sigma_mm, downweighted) or null, got {_kind(robust)}")
    loss = robust.get("loss", "none")
    if loss not in ("none", "pseudo-huber"):
        raise err("robust.loss", f"must be 'pseudo-huber' or 'none', got {loss!r}")
    if loss != "none":
        for k in ("c", "sigma_mm"):
            if not (finite_number(robust.get(k)) and robust[k] > 0):
                raise err(f"robust.{k}", f"must be a finite number > 0, got {robust.get(k)!r}")
    down = robust.get("downweighted", [])
    if not isinstance(down, list) or not all(isinstance(d, dict) for d in down):
        raise err("robust.downweighted", "must be a list of objects (line, residual_mm, weight)")


def _check_coverage(coverage: Any, err) -> None:
    """The joint ranges and poses a calibration saw (optional): finite numbers, one per joint."""
    if not coverage:
        return
    if not isinstance(coverage, dict):
        raise err("coverage", f"must be an object, got {_kind(coverage)}")
    for key in ("q_min_deg", "q_max_deg", "poses_deg", "spacing_deg"):
        if key not in coverage:
            raise err(f"coverage.{key}", "missing key")
    n = None
    for key in ("q_min_deg", "q_max_deg"):
        v = coverage[key]
        if not isinstance(v, list) or not all(finite_number(x) for x in v) or (n is not None and len(v) != n):
            raise err(f"coverage.{key}", "must be a list of finite numbers, one per joint")
        n = len(v)
    poses = coverage["poses_deg"]
    if not isinstance(poses, list) or not poses:
        raise err("coverage.poses_deg", f"must be a non-empty list of poses, got {_kind(poses)}")
    for i, pose in enumerate(poses):
        if not isinstance(pose, list) or len(pose) != n or not all(finite_number(x) for x in pose):
            raise err(f"coverage.poses_deg[{i}]", f"must be a list of {n} finite numbers (degrees)")
    if not finite_number(coverage["spacing_deg"]):
        raise err("coverage.spacing_deg", f"must be a finite number, got {coverage['spacing_deg']!r}")


def _kind(x: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(x), f"the number {x!r}" if isinstance(x, (int, float)) else type(x).__name__)
