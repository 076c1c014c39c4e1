"""Column mappings: which columns of a tracker file become which measurement-CSV columns.

A mapping is a small TOML document (a file, a preset shipped with casadical,
or ``key=value`` pairs given on the command line) read into a typed
:class:`ColumnMap`. Every key is validated; a bad one gives one line naming
where it came from and the key, e.g.
``map.toml, column 'joint_unit': must be "deg" or "rad", got 'degrees'``.

Examples
--------
>>> from casadical.importers import load_column_map
>>> cmap = load_column_map(["ur10-ipa"])
>>> cmap.joint_unit, cmap.position_unit
('rad', 'mm')
>>> load_column_map(["ur10-ipa", "joint_unit=deg"]).joint_unit
'deg'
"""

from __future__ import annotations

import codecs
import difflib
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Sequence

from ..errors import ColumnMapError
from ..runtime._files import read_toml

__all__ = ["ColumnMap", "TimeColumn", "column_map_from_dict", "load_column_map", "presets"]

#: Accepted ``separator`` words and the character each stands for (None: guessed from the header).
SEPARATORS: dict[str, str | None] = {";": ";", ",": ",", "\t": "\t", "\\t": "\t", "tab": "\t",
                                     "|": "|", "auto": None}
#: Joint units and the factor that turns a reading into degrees.
JOINT_UNITS: dict[str, float] = {"deg": 1.0, "rad": 180.0 / math.pi}
#: Length units and the factor that turns a length into millimetres.
LENGTH_UNITS: dict[str, float] = {"mm": 1.0, "m": 1000.0}
#: ``deviation_sign`` words and the sign of the deviation in ``measured = target + sign * deviation``.
DEVIATION_SIGNS: dict[str, float] = {"measured-target": 1.0, "target-measured": -1.0}
OTHERS = ("keep", "drop")

_KEYS = ("separator", "decimal", "encoding", "skip_lines", "joints", "joint_unit", "linear_axes", "linear_unit",
         "position", "position_unit", "target", "target_unit", "deviation", "deviation_unit", "deviation_sign",
         "time", "keep", "keep_if_present", "others")
_LIST_KEYS = ("joints", "position", "target", "deviation")
_TIME_KEYS = ("column", "format")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
#: Output names only the joint and position mapping may produce.
RESERVED = re.compile(r"q\d+_(deg|mm)|[xyz]_mm")
PRESET_DIR = "presets"


@dataclass(frozen=True)
class TimeColumn:
    """A timestamp column, turned into ``time_s`` (seconds since the first row)."""

    column: str
    format: str


@dataclass(frozen=True)
class ColumnMap:
    """How the columns of a tracker file become the measurement CSV contract.

    Attributes
    ----------
    joints : tuple of str
        Source columns of the joint readings, base to tip (-> ``q1_deg ..``; ``qK_mm`` for a linear axis).
    joint_unit : {"deg", "rad"}
        Of the revolute joints.
    linear_axes : tuple of int
        The joints (1-based) that are linear axes (a track, a lifting column): their readings are positions.
    linear_unit : {"mm", "m"}, optional
        Of the linear axes' readings (required with them).
    position : tuple of 3 str, optional
        Source columns of the measured point (-> ``x_mm, y_mm, z_mm``).
    position_unit : {"mm", "m"}, optional
    target, deviation : tuple of 3 str, optional
        Instead of ``position``: the nominal (target) point and its deviation;
        ``measured = target + deviation`` (``deviation_sign`` =
        ``"measured-target"``) or ``target - deviation`` (``"target-measured"``).
    target_unit, deviation_unit : {"mm", "m"}, optional
    deviation_sign : {"measured-target", "target-measured"}, optional
    separator : str or None
        Field separator; None guesses it from the header line.
    decimal : {".", ","}
        Decimal mark of the numbers (no thousands separators).
    encoding : str
        Text encoding of the file (a UTF-8 byte order mark is skipped).
    skip_lines : int
        Lines above the header to ignore.
    time : TimeColumn, optional
        Timestamp column and its :func:`datetime.strptime` format.
    keep : dict of str to str
        Further source columns to keep, by source name -> output name; they
        must exist. Values are copied without unit conversion.
    keep_if_present : dict of str to str
        The same for columns that only some files of a format have.
    others : {"keep", "drop"}
        What happens to the columns the mapping does not name: kept under a
        snake_case version of their name, or dropped.
    source : str
        Where the mapping came from (for messages).
    """

    joints: tuple[str, ...]
    joint_unit: str
    linear_axes: tuple[int, ...] = ()
    linear_unit: str | None = None
    position: tuple[str, ...] | None = None
    position_unit: str | None = None
    target: tuple[str, ...] | None = None
    target_unit: str | None = None
    deviation: tuple[str, ...] | None = None
    deviation_unit: str | None = None
    deviation_sign: str | None = None
    separator: str | None = None
    decimal: str = "."
    encoding: str = "utf-8"
    skip_lines: int = 0
    time: TimeColumn | None = None
    keep: dict[str, str] = field(default_factory=dict)
    keep_if_present: dict[str, str] = field(default_factory=dict)
    others: str = "keep"
    source: str = "<dict>"
    #: top-level keys given as ``--map key=value`` (errors about them name ``--map``, not the file)
    overridden: frozenset = frozenset()

    def origin(self, key: str) -> str:
        """Where ``key`` was set: ``--map`` or the mapping's file (for error messages)."""
        return "--map" if key in self.overridden else self.source

    def key_of(self, column: str) -> str:
        """The mapping key that names source ``column`` (for error messages)."""
        for key in _LIST_KEYS:
            names = getattr(self, key) or ()
            if column in names:
                return f"{key}[{names.index(column) + 1}]"
        if self.time is not None and column == self.time.column:
            return "time.column"
        for key in ("keep", "keep_if_present"):
            if column in getattr(self, key):
                return f"{key}.{column}"
        return "?"


class _Reader:
    """Typed look-ups that raise :class:`ColumnMapError` naming the key and where it came from."""

    def __init__(self, doc: dict[str, Any], file: str, overrides: dict[str, Any] | None):
        self.doc = doc
        self.file = file
        self.overrides = overrides or {}

    def error(self, message: str, *path: str) -> ColumnMapError:
        node: Any = self.overrides
        for p in path:
            node = node.get(p) if isinstance(node, dict) else None
        origin = "--map" if node is not None else self.file
        return ColumnMapError(message, file=origin, column=".".join(path))

    def word(self, key: str, choices, required: bool = False, default: str | None = None) -> str | None:
        if key not in self.doc:
            if required:
                raise self.error(f"missing required key: say {_either(choices)}", key)
            return default
        value = self.doc[key]
        if value not in choices:
            raise self.error(f"must be {_either(choices)}, got {value!r}", key)
        return value

    def names(self, key: str, length: int | None = None) -> tuple[str, ...] | None:
        if key not in self.doc:
            return None
        value = self.doc[key]
        what = f"a list of {length} column names" if length else "a list of column names"
        if not isinstance(value, list) or not value or any(not isinstance(v, str) or not v.strip()
                                                            for v in value):
            raise self.error(f"must be {what}, got {value!r}", key)
        if length and len(value) != length:
            raise self.error(f"must be {what}, got {len(value)}: {value!r}", key)
        names = tuple(v.strip() for v in value)
        for i, v in enumerate(names):
            if v in names[:i]:
                raise self.error(f"names column {v!r} twice", key)
        return names

    def table(self, key: str) -> dict[str, str]:
        value = self.doc.get(key, {})
        if not isinstance(value, dict):
            raise self.error('must be a table of "source column" = "output column"', key)
        out: dict[str, str] = {}
        for src, dst in value.items():
            if not isinstance(dst, str) or not _NAME.fullmatch(dst):
                raise self.error("output column must be a name of letters, digits and '_' "
                                 f"(e.g. \"temperature_c\"), got {dst!r}", key, src)
            if RESERVED.fullmatch(dst):
                raise self.error(f"{dst!r} is made by the joints and position keys only; "
                                 "choose another output name", key, src)
            out[src.strip()] = dst
        return out


def _either(choices) -> str:
    words = [repr(c).replace("'", '"') for c in choices]
    return " or ".join(words) if len(words) <= 2 else ", ".join(words[:-1]) + " or " + words[-1]


def column_map_from_dict(doc: dict[str, Any], file: str = "<dict>",
                         overrides: dict[str, Any] | None = None) -> ColumnMap:
    """Validate a parsed mapping document and build a :class:`ColumnMap`.

    Parameters
    ----------
    doc : dict
        The mapping (TOML as a dict), overrides already merged in.
    file : str
        Where ``doc`` came from (named in error messages).
    overrides : dict, optional
        The part of ``doc`` given as ``--map key=value`` (errors in it name ``--map``).

    Raises
    ------
    ColumnMapError
        Unknown key, missing or invalid value; ``file`` and ``column`` (the
        key, e.g. ``keep.Temp``) say where.
    """
    r = _Reader(doc, file, overrides)
    for key in doc:
        if key not in _KEYS:
            close = difflib.get_close_matches(key, _KEYS, n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise r.error(f"unknown key ({hint}keys: {', '.join(_KEYS)})", key)
    joints = r.names("joints")
    if joints is None:
        raise r.error("missing required key: the joint columns, base to tip", "joints")
    joint_unit = r.word("joint_unit", tuple(JOINT_UNITS), required=True)
    linear = doc.get("linear_axes", [])
    if isinstance(linear, int) and not isinstance(linear, bool):
        linear = [linear]
    if not isinstance(linear, list) or any(isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= len(joints)
                                           for k in linear) or len(set(linear)) != len(linear):
        raise r.error(f"must be a list of different joint numbers 1..{len(joints)} (the joints that are linear "
                      f"axes, as in the robot file), got {linear!r}", "linear_axes")
    linear_unit = None
    if linear:
        linear_unit = r.word("linear_unit", tuple(LENGTH_UNITS), required=True)
    elif "linear_unit" in doc:
        raise r.error("linear_unit without linear_axes", "linear_unit")

    position = r.names("position", 3)
    target, deviation = r.names("target", 3), r.names("deviation", 3)
    if position is not None and (target is not None or deviation is not None):
        raise r.error("give either position or target + deviation, not both",
                      "target" if target is not None else "deviation")
    if (target is None) != (deviation is None):
        missing = "deviation" if target is not None else "target"
        raise r.error("target and deviation go together: the measured point is target +- deviation",
                      missing)
    units = {}
    for key, columns in (("position", position), ("target", target), ("deviation", deviation)):
        unit_key = f"{key}_unit"
        if columns is None:
            if unit_key in doc:
                raise r.error(f"{unit_key} without {key}", unit_key)
            continue
        units[key] = r.word(unit_key, tuple(LENGTH_UNITS), required=True)
    sign = None
    if target is not None:
        sign = r.word("deviation_sign", tuple(DEVIATION_SIGNS), required=True)
    elif "deviation_sign" in doc:
        raise r.error("deviation_sign without target and deviation", "deviation_sign")

    separator = r.word("separator", tuple(SEPARATORS), default="auto")
    decimal = r.word("decimal", (".", ","), default=".")
    encoding = doc.get("encoding", "utf-8")
    try:
        if not isinstance(encoding, str):
            raise LookupError
        codecs.lookup(encoding)
    except LookupError:
        raise r.error(f"unknown text encoding {encoding!r} (e.g. \"utf-8\", \"cp1252\")",
                      "encoding") from None
    skip = doc.get("skip_lines", 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise r.error(f"must be a whole number >= 0, got {skip!r}", "skip_lines")

    time = None
    if "time" in doc:
        t = doc["time"]
        if not isinstance(t, dict):
            raise r.error('must be a table: time = {column = "...", format = "%Y-%m-%d %H:%M:%S"}', "time")
        for key in t:
            if key not in _TIME_KEYS:
                raise r.error(f"unknown key (keys: {', '.join(_TIME_KEYS)})", "time", key)
        for key in _TIME_KEYS:
            if not isinstance(t.get(key), str) or not t[key].strip():
                raise r.error("missing or empty: " + ("the timestamp column" if key == "column" else
                              "a strptime format such as \"%Y%m%d%H%M%S\""), "time", key)
        if "%" not in t["format"]:
            raise r.error(f"not a strptime format (no % directive): {t['format']!r}", "time", "format")
        time = TimeColumn(t["column"].strip(), t["format"])

    keep, keep_if_present = r.table("keep"), r.table("keep_if_present")
    seen: dict[str, str] = {"time_s": "time.column"} if time else {}
    for key, table in (("keep", keep), ("keep_if_present", keep_if_present)):
        for src, dst in table.items():
            if dst in seen:
                raise r.error(f"output column {dst!r} is also made by {seen[dst]}", key, src)
            seen[dst] = f"{key}.{src}"
    others = r.word("others", OTHERS, default="keep")
    return ColumnMap(
        joints=joints, joint_unit=joint_unit, linear_axes=tuple(sorted(linear)), linear_unit=linear_unit,
        position=position, position_unit=units.get("position"), target=target, target_unit=units.get("target"),
        deviation=deviation, deviation_unit=units.get("deviation"), deviation_sign=sign,
        separator=SEPARATORS[separator], decimal=decimal, encoding=encoding, skip_lines=skip,
        time=time, keep=keep, keep_if_present=keep_if_present, others=others, source=file,
        overridden=frozenset(overrides or ()))


# --- loading: files, presets and key=value overrides ---------------------------------------


def presets() -> dict[str, Path]:
    """The mapping presets shipped with casadical: name -> TOML file."""
    folder = resources.files(__package__) / PRESET_DIR
    return {Path(p.name).stem: Path(str(p)) for p in folder.iterdir() if p.name.endswith(".toml")}


def _override(spec: str) -> dict[str, Any]:
    """One ``--map key=value``: the value as TOML, else as a plain string (lists: comma separated)."""
    key, _, value = spec.partition("=")
    key = key.strip()
    try:
        return tomllib.loads(f"{key} = {value}")
    except tomllib.TOMLDecodeError:
        pass
    if key in _LIST_KEYS:
        text = json.dumps([v.strip() for v in value.split(",")])
    else:
        text = json.dumps(value)  # a JSON string is a TOML basic string
    try:
        return tomllib.loads(f"{key} = {text}")
    except tomllib.TOMLDecodeError:
        raise ColumnMapError(f"cannot read {spec!r}: the key must be a TOML key (quote names with "
                             "spaces: keep.\"Goal x\"=goal_x)", file="--map", column=key) from None


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def mapping_file(spec: str) -> Path | None:
    """The file a ``--map`` value names (a TOML path or a preset), None for ``key=value``."""
    if Path(spec).is_file():
        return Path(spec)
    if "=" in spec:
        return None
    found = presets()
    if spec in found:
        return found[spec]
    raise ColumnMapError(f"no such mapping file, and not a preset (presets: {', '.join(sorted(found))}; "
                         "or give key=value pairs)", file=spec)


def load_column_map(specs: Sequence[str]) -> ColumnMap:
    """Build a mapping from ``--map`` values: at most one TOML file or preset, then ``key=value`` pairs.

    Parameters
    ----------
    specs : sequence of str
        Each a mapping TOML path, a preset name (see :func:`presets`) or a
        ``key=value`` pair whose value is TOML (``joints=["a", "b"]``) or a
        plain word (``joint_unit=rad``; lists comma separated: ``joints=a,b``).
        Pairs override the file's keys (tables key by key: ``keep.T=temperature_c``).

    Raises
    ------
    ColumnMapError
        No such file or preset, two files, invalid TOML or an invalid mapping.
    """
    base: dict[str, Any] = {}
    file: str | None = None
    overrides: dict[str, Any] = {}
    for spec in specs:
        path = mapping_file(spec)
        if path is None:
            overrides = _merge(overrides, _override(spec))
        elif file is not None:
            raise ColumnMapError(f"a second mapping file or preset; give one, then key=value pairs "
                                 f"(first: {file})", file=spec)
        else:
            file = str(path)
            base = read_toml(path, ColumnMapError, file)
    if not specs:
        raise ColumnMapError("no mapping: give a mapping TOML file, a preset or key=value pairs",
                             file="--map")
    return column_map_from_dict(_merge(base, overrides), file or "--map", overrides)
