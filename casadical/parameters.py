"""Named model parameters with units, bounds and fixed flags (lmfit style).

Values are stored in SI units (m, rad, rad/(N m), ...). Angles are shown in
degrees wherever a person reads them (summaries, JSON).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Iterable, Iterator

import numpy as np

from ._format import number
from .errors import CasadicalError

#: Units whose values are displayed in another unit: SI unit -> (display unit, factor).
DISPLAY = {
    "rad": ("deg", 180.0 / math.pi),
    "m": ("mm", 1000.0),
}
#: Display units that reports and text tables show in yet another unit (the JSON keeps the display unit): a
#: relative scale (unit "1", 0.000123) is read in ppm (123).
READING = {"1": ("ppm", 1e6)}


@dataclass
class Parameter:
    """One model parameter.

    Parameters
    ----------
    name : str
        Unique name, e.g. ``a3``, ``beta3``, ``c2`` (compliance of joint 2).
    nominal : float
        Nominal value, SI units.
    unit : str
        SI unit: ``m``, ``rad``, ``rad/(N*m)``, ``1``, ``1/K``.
    scale : float
        Typical size of a deviation from nominal; the solvers and the
        identifiability analysis work on ``(value - nominal) / scale``.
    term : str
        Name of the error term that owns the parameter.
    joint : int or None
        1-based joint the parameter belongs to, if any.
    group : str
        Finer grouping within a term (``base``, ``link``, ``tool``, ``loop``).
    lower, upper : float
        Bounds on the value (SI).
    fixed : bool
        Held at ``value`` by every solver.
    value : float or None
        Current value; the nominal value if None.
    """

    name: str
    nominal: float
    unit: str
    scale: float
    term: str
    joint: int | None = None
    group: str = ""
    lower: float = -math.inf
    upper: float = math.inf
    fixed: bool = False
    value: float | None = None
    std: float = math.nan
    identifiable: bool | None = None
    reason: str = ""

    def __post_init__(self) -> None:
        if self.value is None:
            self.value = float(self.nominal)
        if not self.scale > 0:
            raise CasadicalError(f"parameter {self.name}: scale must be positive, got {self.scale}")

    @property
    def display_unit(self) -> str:
        """Unit in which a person reads this parameter."""
        return DISPLAY.get(self.unit, (self.unit, 1.0))[0]

    def to_display(self, v: float) -> float:
        """Convert an SI value (or std) of this parameter to display units."""
        return v * DISPLAY.get(self.unit, (self.unit, 1.0))[1]

    def from_display(self, v: float) -> float:
        """Convert a value in display units to SI."""
        return v / DISPLAY.get(self.unit, (self.unit, 1.0))[1]

    @property
    def reading_unit(self) -> str:
        """Unit of reports and text tables: the display unit, or a relative scale in ppm (:data:`READING`)."""
        return READING.get(self.display_unit, (self.display_unit, 1.0))[0]

    def to_reading(self, v: float) -> float:
        """Convert an SI value (or std) to :attr:`reading_unit`."""
        return self.to_display(v) * READING.get(self.display_unit, (None, 1.0))[1]


@dataclass
class Parameters:
    """An ordered set of :class:`Parameter` objects.

    Index by name (``params["a3"]``) or iterate in model order. Array views
    (``values``, ``free``, ...) follow the same order as the model's parameter
    vector.
    """

    items: list[Parameter] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._index = {}
        for i, p in enumerate(self.items):
            if p.name in self._index:
                raise CasadicalError(f"duplicated parameter name {p.name!r}")
            self._index[p.name] = i

    def __len__(self) -> int:
        return len(self.items)

    def __iter__(self) -> Iterator[Parameter]:
        return iter(self.items)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __getitem__(self, name: str) -> Parameter:
        try:
            return self.items[self._index[name]]
        except KeyError:
            close = [n for n in self._index if n.startswith(str(name)[:2])][:6]
            hint = f"; did you mean one of {close}?" if close else ""
            raise KeyError(f"no parameter named {name!r}{hint}") from None

    def index(self, name: str) -> int:
        """Position of ``name`` in the parameter vector."""
        return self._index[name]

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.items]

    @property
    def values(self) -> np.ndarray:
        return np.array([p.value for p in self.items], dtype=float)

    @values.setter
    def values(self, v: Iterable[float]) -> None:
        v = np.asarray(v, dtype=float)
        if v.shape != (len(self.items),):
            raise CasadicalError(f"expected {len(self.items)} values, got shape {v.shape}")
        for p, x in zip(self.items, v):
            p.value = float(x)

    @property
    def nominal(self) -> np.ndarray:
        return np.array([p.nominal for p in self.items], dtype=float)

    @property
    def scales(self) -> np.ndarray:
        return np.array([p.scale for p in self.items], dtype=float)

    @property
    def free(self) -> np.ndarray:
        """Boolean mask of the parameters a solver may move."""
        return np.array([not p.fixed for p in self.items], dtype=bool)

    @property
    def lower(self) -> np.ndarray:
        return np.array([p.lower for p in self.items], dtype=float)

    @property
    def upper(self) -> np.ndarray:
        return np.array([p.upper for p in self.items], dtype=float)

    @property
    def stds(self) -> np.ndarray:
        return np.array([p.std for p in self.items], dtype=float)

    def copy(self) -> "Parameters":
        return Parameters([replace(p) for p in self.items])

    def select(self, term: str | None = None, joint: int | None = None) -> list[Parameter]:
        """Parameters of one error term and/or one joint."""
        return [p for p in self.items
                if (term is None or p.term == term) and (joint is None or p.joint == joint)]

    def fix(self, names: Iterable[str], reason: str = "") -> None:
        """Fix the named parameters at their current values."""
        for n in names:
            self[n].fixed = True
            if reason:
                self[n].reason = reason

    def table(self, show_fixed: bool = True) -> str:
        """Plain-text table: name, nominal, value, deviation, std, unit, status."""
        head = f"{'name':<16}{'nominal':>14}{'value':>14}{'deviation':>13}{'std':>11}  {'unit':<10}status"
        lines = [head, "-" * len(head)]
        for p in self.items:
            if p.fixed and not show_fixed:
                continue
            f = p.to_reading
            dev = f(p.value - p.nominal)
            std = f(p.std) if math.isfinite(p.std) else math.nan
            status = "fixed" if p.fixed else "free"
            if p.reason:
                status += f" ({p.reason})"
            lines.append(f"{p.name:<16}{_num(f(p.nominal)):>14}{_num(f(p.value)):>14}"
                         f"{_num(dev):>13}{_num(std):>11}  {p.reading_unit:<10}{status}")
        return "\n".join(lines)


def _num(x: float) -> str:
    return number(x, 6, exp_digits=4)
