"""Validation of a calibration JSON before it is used (section 4 of docs/formats.md).

A calibration file is read back by :func:`casadical.calibration.load_calibration`
and then predicts positions: a missing key, a value of the wrong type, a NaN
parameter or a parameter of another model must stop there, with one line
naming the file and the key as a JSON path (``parameters[3].value``), not
turn into a traceback or into predictions that are NaN or wrong.
"""

from __future__ import annotations

import inspect
import math
import re
from typing import Any

import numpy as np

from .. import __version__
from ..errors import CalibrationFileError, ModelError, RobotFileError, TermsFileError, listing
from ..model._symbolic import assemble_terms, parse_spec
from ..robot import Robot, robot_from_dict
from ..runtime._files import finite_number
from ..terms import ErrorTerm, SessionLocal
from ..terms._definitions import by_name, definitions_from_list

STATS_KEYS = ("n_poses", "mean_mm", "max_mm", "std_mm", "rms_mm")
#: optional statistics of rows that say what they touched (docs/formats.md section 11)
TOUCH_KEYS = ("consistency_mm", "distance_error_mm")
#: largest count of equations or parameters a file may give (beyond, no float holds it exactly)
MAX_COUNT = 2 ** 53
#: keys of ``statistics`` (the fit's size, noise and information criteria)
FIT_KEYS = ("n_equations", "n_parameters", "dof", "sigma_mm", "log_likelihood", "aic", "bic", "level", "t_critical")
#: term settings that may be zero or negative (all other numeric settings must be positive)
SIGNED_SETTINGS = {"t_ref", "law_lo", "law_hi"}


def validate_calibration_document(doc: Any, path: str, terms=()) -> None:
    """Check a parsed calibration JSON: every key :func:`load_calibration` reads, with its type.

    Parameters
    ----------
    doc : object
        The parsed JSON document.
    path : str
        The file, for messages.
    terms : iterable of TermDefinition
        Definitions of user terms its model may name that it does not carry (its own take precedence).

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
    users = {**by_name(terms), **by_name(user_definitions(doc, path))}
    terms = _terms(robot, doc["model"], err, users)
    _check_settings(doc.get("terms", {}), terms, err, robot.n)
    try:
        terms = assemble_terms(restored_terms(doc["model"], doc.get("terms", {}), robot.n, users), robot)
    except ModelError as e:
        raise err("terms", str(e)) from e
    _check_version(doc.get("casadical_version"), err)
    units = {p.name: p.unit for t in terms for p in t.parameters(robot)}
    _check_parameters(doc["parameters"], list(units), doc["model"], err, units)
    _check_base0(doc["base0"], err)
    _check_stats(doc.get("calibration"), err)
    _check_touches(doc, list(units), err)
    _check_fit_statistics(doc.get("statistics"), err)
    _check_validation(doc.get("validation"), err)
    _check_robust(doc.get("robust"), err)
    _check_interval_factor(doc.get("uncertainty"), err)
    _check_coverage(doc.get("coverage"), err)
    _check_sessions(doc.get("sessions"), err)
    _check_orientation(doc.get("orientation"), any(t.name == "tool_orientation" for t in terms), err)
    notes = doc.get("notes", [])
    if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
        raise err("notes", "must be a list of strings")


def user_definitions(doc: Any, path: str) -> list:
    """The definitions of the user terms a calibration JSON carries (``user_terms``, checked as a terms file's)."""
    if not isinstance(doc, dict) or "user_terms" not in doc:
        return []
    try:
        return definitions_from_list(doc["user_terms"], path, "user_terms")
    except TermsFileError as e:
        raise CalibrationFileError(str(e).removeprefix(f"{path}, "), file=path, column="user_terms") from e


def _terms(robot: Robot, spec: str, err, user_terms=()) -> list:
    """The model's terms as :class:`~casadical.model._symbolic.Model` builds them (geometric first), bound to the
    robot (``user_terms``: the definitions the file carries)."""
    try:
        return assemble_terms(parse_spec(spec, user_terms), robot)
    except ModelError as e:
        raise err("model", str(e)) from e


def restored_terms(spec: str, settings: dict, n_joints: int, user_terms=()) -> list[ErrorTerm]:
    """The terms of a calibration's model specification with the settings it saved (by each term's
    specification; older files: by its name, or :func:`legacy_spec`); ``user_terms``: the definitions the file
    carries."""
    return [restore_term(t, settings.get(t.spec(), settings.get(t.name, settings.get(legacy_spec(t, n_joints), {}))))
            for t in parse_spec(spec, user_terms)]


def restore_term(term: ErrorTerm, settings: dict) -> ErrorTerm:
    """``term`` (from a model specification) rebuilt with the settings a calibration saved."""
    if isinstance(term, SessionLocal):
        return SessionLocal(restore_term(term.inner, settings), term.session_name)
    allowed = inspect.signature(type(term).__init__).parameters
    settings = {**getattr(type(term), "LEGACY", {}), **settings}   # what files older than a setting meant
    kwargs = {k: v for k, v in settings.items() if k in allowed and k not in ("joints", "harmonics")}
    if not kwargs:
        return term
    return type(term)(joints=term.joints, **kwargs)   # a term with settings besides its joints takes joints


def legacy_spec(term, n_joints: int) -> str:
    """The key older files gave a term's settings: a drift or a thermal expansion of the whole arm was written
    with every joint (``drift[1,2,3,4,5,6]``)."""
    return f"{term.name}[{','.join(str(j) for j in range(1, n_joints + 1))}]"


def _check_settings(settings: Any, terms: list, err, n: int) -> None:
    if not isinstance(settings, dict):
        raise err("terms", f"must be an object of term settings, got {_kind(settings)}")
    # keyed by each term's specification (older files: by its name)
    by_name = {t.name: t for t in terms} | {t.spec(): t for t in terms} | {legacy_spec(t, n): t for t in terms}
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
            if isinstance(default, bool):
                if not isinstance(v, bool):
                    raise err(f"{key}.{k}", f"must be true or false, got {v!r}")
            elif isinstance(default, str):
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
        _check_test(e, at, name, err)
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


def _check_stats(stats: Any, err, key: str = "calibration", extra: tuple[str, ...] = ()) -> None:
    if stats is None:
        return
    known = extra + STATS_KEYS + TOUCH_KEYS
    if not isinstance(stats, dict):
        raise err(key, f"must be an object ({', '.join(known)}) or null, got {_kind(stats)}")
    for k in stats:
        if k not in known:
            raise err(f"{key}.{k}", f"unknown key (known: {', '.join(known)})")
    for k in STATS_KEYS:
        v = stats.get(k)
        ok = (isinstance(v, int) and not isinstance(v, bool) and v >= 0) if k == "n_poses" \
            else (finite_number(v) and v >= 0)
        if not ok:
            raise err(f"{key}.{k}", f"must be a {'whole' if k == 'n_poses' else 'finite'} number >= 0, "
                                    f"got {v!r}")
    for k in TOUCH_KEYS:
        if k in stats and not (finite_number(stats[k]) and stats[k] >= 0):
            raise err(f"{key}.{k}", f"must be a finite number >= 0, got {stats[k]!r}")


def _check_touches(doc: dict, names: list[str], err) -> None:
    """What a calibration from touches says it could not see: ``frame`` ("base") and ``unobservable``."""
    if "frame" in doc and doc["frame"] != "base":
        raise err("frame", f"must be \"base\" (a calibration from touches alone) or absent, got {doc['frame']!r}")
    unob = doc.get("unobservable", [])
    if not isinstance(unob, list):
        raise err("unobservable", f"must be a list, got {_kind(unob)}")
    for k, u in enumerate(unob):
        key = f"unobservable[{k}]"
        if not (isinstance(u, dict) and set(u) == {"what", "why", "parameters"} and isinstance(u["what"], str)
                and isinstance(u["why"], str) and isinstance(u["parameters"], list)):
            raise err(key, "must be an object with what, why (text) and parameters (a list of names)")
        unknown = [n for n in u["parameters"] if n not in names]
        if unknown:
            raise err(f"{key}.parameters", f"{unknown[0]!r} is not a parameter of the model")


def _check_validation(validation: Any, err) -> None:
    """Errors on held-out poses (``calibrate --validate``): the file and the error statistics."""
    _check_stats(validation, err, "validation", ("file",))
    if validation is not None and not isinstance(validation.get("file", ""), str):
        raise err("validation.file", f"must be a string (the validation file), got {_kind(validation['file'])}")


def _check_fit_statistics(stats: Any, err) -> None:
    """The fit's size, noise and information criteria (files before them have none; null for a fitted network)."""
    if stats is None:
        return
    if not isinstance(stats, dict):
        raise err("statistics", f"must be an object ({', '.join(FIT_KEYS)}) or null, got {_kind(stats)}")
    for k in stats:
        if k not in FIT_KEYS:
            raise err(f"statistics.{k}", f"unknown key (known: {', '.join(FIT_KEYS)})")
    for k in FIT_KEYS:
        if k not in stats:
            raise err(f"statistics.{k}", "missing key")
        v = stats[k]
        if k in ("n_equations", "n_parameters", "dof"):
            low = 1 if k != "n_parameters" else 0
            if not (isinstance(v, int) and not isinstance(v, bool) and low <= v <= MAX_COUNT):
                raise err(f"statistics.{k}", f"must be a whole number from {low} to {MAX_COUNT:.0e}, got {v!r}")
        elif not finite_number(v):
            raise err(f"statistics.{k}", f"must be a finite number, got {v!r}")
        elif k in ("sigma_mm", "t_critical") and not 0 < v < 1e6 or k == "level" and not 0 < v < 1:
            raise err(f"statistics.{k}", f"must be {'in (0, 1)' if k == 'level' else 'in (0, 1e6)'}, got {v!r}")
    if stats["dof"] != stats["n_equations"] - stats["n_parameters"]:
        raise err("statistics.dof", f"must be n_equations - n_parameters = "
                                    f"{stats['n_equations'] - stats['n_parameters']}, got {stats['dof']!r}")


def _check_test(e: dict, at: str, name: str, err) -> None:
    """A parameter's t, p, significance, interval and relative std: each null or of its type."""
    for k in ("t", "p", "relative_std"):
        v = e.get(k)
        if v is not None and not (finite_number(v) and (k == "t" or v >= 0) and (k != "p" or v <= 1)):
            want = {"t": "a finite number", "p": "a number in [0, 1]", "relative_std": "a finite number >= 0"}[k]
            raise err(f"{at}.{k}", f"{k} of {name} must be null or {want}, got {v!r}")
    if e.get("significant") is not None and not isinstance(e["significant"], bool):
        raise err(f"{at}.significant", f"must be true, false or null, got {e['significant']!r}")
    ci = e.get("ci95")
    if ci is not None and not (isinstance(ci, list) and len(ci) == 2
                               and all(x is None or finite_number(x) for x in ci)):
        raise err(f"{at}.ci95", f"confidence interval of {name} must be null or [low, high] (numbers or null), "
                                f"got {ci!r}")


def _check_interval_factor(unc: Any, err) -> None:
    """``uncertainty.interval_k`` (a diagnosis's final model): the 95 % interval's factor, a finite number > 0."""
    if isinstance(unc, dict) and "interval_k" in unc and not (finite_number(unc["interval_k"])
                                                              and unc["interval_k"] > 0):
        raise err("uncertainty.interval_k", "must be a finite number > 0 (the factor of the 95 % interval "
                  f"of a measured point, 2.796 or more), got {unc['interval_k']!r}")


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


def _check_sessions(sessions: Any, err) -> None:
    """The sessions of a calibration of several (optional): their names and errors."""
    if sessions is None:
        return
    if not isinstance(sessions, list):
        raise err("sessions", f"must be a list of session objects, got {_kind(sessions)}")
    for i, s in enumerate(sessions):
        if not isinstance(s, dict) or not isinstance(s.get("name"), str):
            raise err(f"sessions[{i}].name", "missing or not a string")
        if s.get("calibration") is not None:
            _check_stats(s["calibration"], lambda key, message: err(f"sessions[{i}].{key}", message))

def _check_orientation(orientation: Any, has_term: bool, err) -> None:
    """A full-pose calibration's probe mounting (required with the term tool_orientation, and only then)."""
    if orientation is None:
        if has_term:
            raise err("orientation", "missing key: the model has the probe orientation (tool_orientation)")
        return
    if not has_term:
        raise err("orientation", "the model has no probe orientation (tool_orientation); remove this key")
    if not isinstance(orientation, dict):
        raise err("orientation", f"must be an object (tool0, ...), got {_kind(orientation)}")
    tool0 = orientation.get("tool0")
    if not isinstance(tool0, list) or len(tool0) != 9 or not all(finite_number(x) for x in tool0):
        raise err("orientation.tool0", "must be a list of 9 finite numbers (a rotation, row-major)")
    R = np.array(tool0, dtype=float).reshape(3, 3)
    if np.abs(R).max() > 1 + 1e-6 or np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) <= 0:
        raise err("orientation.tool0", "is not a rotation matrix (row-major)")
    for k in ("sigma_mm", "sigma_deg"):
        v = orientation.get(k)
        if v is not None and not (finite_number(v) and v > 0):
            raise err(f"orientation.{k}", f"must be null or a finite number > 0, got {v!r}")
    if (orientation.get("sigma_mm") is None) != (orientation.get("sigma_deg") is None):
        raise err("orientation.sigma_deg", "sigma_mm and sigma_deg must be given together")
    if "full_pose" in orientation and not isinstance(orientation["full_pose"], bool):
        raise err("orientation.full_pose", f"must be true or false, got {orientation['full_pose']!r}")
    for which in ("calibration", "validation"):
        stats = orientation.get(which)
        if stats is None:
            continue
        keys = ("n_poses", "mean_deg", "max_deg", "std_deg", "rms_deg")
        if not isinstance(stats, dict) or set(stats) != set(keys):
            raise err(f"orientation.{which}", f"must be null or an object of {', '.join(keys)}")
        for k in keys:
            v = stats[k]
            ok = (isinstance(v, int) and not isinstance(v, bool) and v >= 0) if k == "n_poses" \
                else (finite_number(v) and v >= 0)
            if not ok:
                raise err(f"orientation.{which}.{k}", f"must be a finite number >= 0, got {v!r}")


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
