"""Causes of one's own: the terms file (TOML), its validation, and the terms a command knows.

A user states a cause the catalogue lacks in a TOML file of ``[[term]]``
tables (docs/formats.md, "Terms file"); :func:`read_terms_file` checks it all
here, in one place, and every fault is one line naming the file, the term, the
key and the token. The same check reads the definitions a calibration JSON
carries (:func:`definitions_from_list`).

A model specification names a user term like any term
(``kinematic+axis_wobble``) where its definition is given: every function that
reads a specification takes the definitions as an argument (``terms=`` of
:func:`~casadical.calibration.calibrate`, :class:`~casadical.diagnosis._settings.DiagnosisSettings`,
:func:`~casadical.result.load_calibration`, ``user_terms=`` of
:func:`casadical.model.parse_spec` and :class:`~casadical.model.Model`); nothing
is kept in module or context state, and the global
:data:`~casadical.terms._base.REGISTRY` never changes.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import TermsFileError
from . import _expression as ex
from ._base import REGISTRY

#: the effects a term may have, with their number of expressions (None: one per joint)
EFFECTS = {"angle": None, "offset": None, "frame": 6, "tool": 3, "base": 6, "point": 3}
_KEYS = {"name", "joint", "joints", "scope", "parameters", *EFFECTS}
_PARAMETER_KEYS = {"scale", "lower", "upper", "unit", "start"}
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
_PARAMETER = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
#: the catalogue's causes (docs/formats.md) and the words of a model specification: not a user term's name
RESERVED = {"geometric", "joint_compliance", "joint_periodic", "encoder_scale", "backlash", "thermal_expansion",
            "joint_coupling", "mount_compliance", "unexplained", "drift", "warmup", "nominal", "base", "kinematic",
            "tool", "sessions", "compliance", "periodic", "thermal", "coupling", "user"}


@dataclass(frozen=True)
class ParameterDefinition:
    """A user term's parameter: typical size (``scale``), physical bounds, unit, start value."""

    name: str
    scale: float
    lower: float
    upper: float
    unit: str = ""
    start: float = 0.0

    def to_dict(self) -> dict:
        return {"scale": self.scale, "lower": self.lower, "upper": self.upper, "unit": self.unit,
                "start": self.start}


@dataclass(frozen=True)
class TermDefinition:
    """One ``[[term]]`` of a terms file, checked.

    ``effects`` maps each effect (``angle``, ``frame``, ...) to its
    expressions, ``texts`` to their source text; ``joints`` is the joint(s)
    named (``joint = 2`` gives ``[2]`` with ``one_joint``).
    """

    name: str
    joints: tuple[int, ...] | None
    one_joint: bool
    effects: dict = field(compare=False)
    texts: dict
    scope: str
    parameters: tuple[ParameterDefinition, ...]
    file: str = field(default="", compare=False)

    @property
    def parameter_names(self) -> list[str]:
        return [p.name for p in self.parameters]

    def names(self) -> set[str]:
        """Every name the term's expressions use."""
        return set().union(*(e.names() for es in self.effects.values() for e in es))

    def columns(self) -> list[str]:
        """The columns of the measurements the term reads (``row``, ``temperature_c``, ...), sorted."""
        return sorted(n for n in self.names() if ex.is_column(n, self.parameter_names))

    def to_dict(self) -> dict:
        """The ``[[term]]`` table again (what a calibration JSON carries)."""
        d: dict = {"name": self.name}
        if self.joints is not None:
            d["joint" if self.one_joint else "joints"] = self.joints[0] if self.one_joint else list(self.joints)
        d.update({k: list(v) for k, v in self.texts.items()})
        d["scope"] = self.scope
        d["parameters"] = {p.name: p.to_dict() for p in self.parameters}
        return d

    def error(self, key: str | None, message: str) -> TermsFileError:
        return TermsFileError(message, file=self.file, term=self.name, key=key)


def read_terms_file(path: str | Path) -> list[TermDefinition]:
    """The terms of a terms file, checked (docs/formats.md, "Terms file").

    Raises
    ------
    TermsFileError
        One line naming the file, the term, the key and the token.
    """
    from ..runtime._files import read_toml
    label = Path(path).name if Path(path).parent == Path(".") else str(path)
    doc = read_toml(path, TermsFileError, label)
    extra = sorted(set(doc) - {"term"})
    if extra:
        raise TermsFileError(f"unknown key {extra[0]!r}: a terms file holds [[term]] tables", file=label,
                             key=extra[0])
    tables = doc.get("term")
    if not isinstance(tables, list) or not tables:
        raise TermsFileError("holds no [[term]] table (see the terms file in docs/formats.md)", file=label)
    return definitions_from_list(tables, label)


def definitions_from_list(tables, file: str, key: str = "term") -> list[TermDefinition]:
    """The checked definitions of a list of term tables (a terms file's, or a calibration JSON's ``key``)."""
    if not isinstance(tables, list):
        raise TermsFileError(f"must be a list of term tables, got {type(tables).__name__}", file=file, key=key)
    out: list[TermDefinition] = []
    for i, table in enumerate(tables):
        d = _definition(table, file, f"{key}[{i}]")
        if any(o.name == d.name for o in out):
            raise TermsFileError("a second term of this name", file=file, term=d.name, key="name")
        out.append(d)
    return out


def _number(value, what: str, key: str, err) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise err(f"{key}.{what}", f"{what} must be a finite number, got {value!r}")
    return float(value)


def _definition(table, file: str, where: str) -> TermDefinition:
    if not isinstance(table, dict):
        raise TermsFileError(f"must be a table ([[term]]), got {type(table).__name__}", file=file, key=where)
    name = table.get("name")
    if not isinstance(name, str):
        raise TermsFileError("a term needs a name (a string such as \"axis_wobble\")", file=file,
                             key=f"{where}.name")

    def err(key, message):
        return TermsFileError(message, file=file, term=name, key=key)

    if any(c in name for c in "+[]@, "):
        bad = next(c for c in name if c in "+[]@, ")
        raise err("name", f"{bad!r} cannot be in a term's name: a model specification joins its terms with + and "
                  "gives joints in [ ] and sessions after @")
    if not _NAME.match(name):
        raise err("name", "a term's name is lower-case letters, digits and _, starting with a letter "
                  "([a-z][a-z0-9_]*)")
    if name in RESERVED or name in REGISTRY:
        raise err("name", f"{name!r} is a cause or term of the catalogue: give the term a name of its own")
    unknown = sorted(set(table) - _KEYS)
    if unknown:
        raise err(unknown[0], f"unknown key {unknown[0]!r} (keys: name, joint, joints, {', '.join(EFFECTS)}, scope, "
                  "parameters)")
    scope = table.get("scope", "robot")
    if scope not in ("robot", "session"):
        raise err("scope", f"scope must be \"robot\" or \"session\", got {scope!r}")
    joints, one = _joints(table, err)
    params = _parameters(table.get("parameters", {}), err)
    pnames = [p.name for p in params]
    effects, texts = {}, {}
    for effect, size in EFFECTS.items():
        if effect not in table:
            continue
        raw = table[effect]
        items = raw if isinstance(raw, list) else [raw]
        if effect in ("angle", "offset"):
            if joints is None:
                raise err(effect, f"an {effect} effect acts on a joint: give joint = J or joints = [J, ...]")
            if len(items) != len(joints):
                raise err(effect, f"needs one expression per joint ({len(joints)}), got {len(items)}")
        elif effect == "frame":
            if joints is None or not one:
                raise err(effect, "a frame effect moves one joint's link frame: give joint = J (not joints)")
        if size is not None and (not isinstance(raw, list) or len(items) != size):
            what = "[dx, dy, dz, rx, ry, rz]" if size == 6 else "[dx, dy, dz]"
            raise err(effect, f"must be a list of {size} expressions {what}, got "
                      + (f"{len(items)}" if isinstance(raw, list) else f"a {type(raw).__name__}"))
        exprs = []
        for k, text in enumerate(items):
            key = f"{effect}[{k}]" if isinstance(raw, list) else effect
            try:
                exprs.append(ex.parse(text, pnames, point=effect == "point"))
            except ex.ExpressionError as e:
                raise err(key, f"{e.token!r}: {e.message}" if not e.message.startswith(repr(e.token))
                          else e.message) from None
        effects[effect] = tuple(exprs)
        texts[effect] = tuple(str(t) if isinstance(t, str) else repr(float(t)) for t in items)
    if not effects:
        raise err(None, f"states no effect: give one or more of {', '.join(EFFECTS)}")
    if joints is not None and not ({"angle", "offset", "frame"} & set(effects)):
        raise err("joints" if not one else "joint", "names a joint but has no effect on one (angle, offset, frame)")
    used = set().union(*(e.names() for es in effects.values() for e in es))
    idle = [p for p in pnames if p not in used]
    if idle:
        raise err(f"parameters.{idle[0]}", f"parameter {idle[0]!r} is used by no expression of the term")
    return TermDefinition(name, joints, one, effects, texts, scope, params, file)


def _joints(table: dict, err) -> tuple[tuple[int, ...] | None, bool]:
    if "joint" in table and "joints" in table:
        raise err("joints", "give joint = J or joints = [J, ...], not both")
    if "joint" in table:
        j = table["joint"]
        if isinstance(j, bool) or not isinstance(j, int) or j < 1:
            raise err("joint", f"a joint is a whole number from 1, got {j!r}")
        return (j,), True
    if "joints" in table:
        js = table["joints"]
        if not isinstance(js, list) or not js or any(isinstance(j, bool) or not isinstance(j, int) or j < 1
                                                     for j in js):
            raise err("joints", f"joints is a list of whole numbers from 1, got {js!r}")
        if len(set(js)) != len(js):
            raise err("joints", f"a joint is named twice in {js}")
        return tuple(js), False
    return None, False


def _parameters(table, err) -> tuple[ParameterDefinition, ...]:
    if not isinstance(table, dict):
        raise err("parameters", "parameters are tables [term.parameters.NAME] with scale, lower, upper")
    out = []
    for pname, spec in table.items():
        key = f"parameters.{pname}"
        if not _PARAMETER.match(pname) or pname in ex.FUNCTIONS or pname in ex.CONSTANTS \
                or pname in ex.MOMENT_NAMES or pname in ex.POINT_NAMES or pname in ex.KNOWN_COLUMNS \
                or ex.joint_name(pname) or ex.is_reading(pname):
            raise err(key, f"{pname!r} cannot name a parameter (letters, digits and _, starting with a letter, and "
                      "not a name expressions already have: q1, tau1, mx, px, row, pi, sin, ...)")
        if not isinstance(spec, dict):
            raise err(key, "a parameter is a table with scale, lower, upper (and unit, start)")
        unknown = sorted(set(spec) - _PARAMETER_KEYS)
        if unknown:
            raise err(f"{key}.{unknown[0]}", f"unknown key {unknown[0]!r} (keys: scale, lower, upper, unit, start)")
        for k in ("scale", "lower", "upper"):
            if k not in spec:
                raise err(f"{key}.{k}", f"a parameter needs {k} (its typical size and physical bounds: scale, "
                          "lower, upper)")

        scale, lower, upper, start = (_number(spec.get(k, default), k, key, err) for k, default in
                                      (("scale", None), ("lower", None), ("upper", None), ("start", 0.0)))
        if scale <= 0:
            raise err(f"{key}.scale", f"scale must be positive, got {scale!r}")
        if not lower < upper:
            raise err(f"{key}.upper", f"upper ({upper!r}) must be greater than lower ({lower!r})")
        if not lower <= start <= upper:
            raise err(f"{key}.start", f"start {start!r} lies outside the bounds [{lower!r}, {upper!r}]"
                      + (" (the default start is 0: give start)" if "start" not in spec else ""))
        unit = spec.get("unit", "")
        if not isinstance(unit, str):
            raise err(f"{key}.unit", f"unit must be a string, got {unit!r}")
        out.append(ParameterDefinition(pname, scale, lower, upper, unit, start))
    return tuple(out)


# --- the terms a command is given ---------------------------------------------------------------------------


def by_name(definitions) -> dict[str, TermDefinition]:
    """``definitions`` (an iterable of :class:`TermDefinition`, or a dict of them by name) by name."""
    if isinstance(definitions, dict):
        return dict(definitions)
    return {d.name: d for d in definitions or ()}
