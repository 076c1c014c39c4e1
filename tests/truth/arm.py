"""A robot's nominal numbers, read from its TOML text or the dict of ``tests/helpers/arms.py``
(docs/formats.md section 1).

Read here, not through casadical: unit conversions (degrees, the gravity
direction) are part of what the truth checks.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field

import numpy as np

G = 9.81


@dataclass
class Link:
    """One row of the robot file (SI units). ``beta``/``b`` None: not modelled on this row."""

    alpha: float
    a: float
    d: float
    theta: float = 0.0
    beta: float | None = None
    b: float | None = None
    lo: float = -math.pi
    hi: float = math.pi
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    coupling: np.ndarray | None = None
    coupling_offset: float = 0.0
    #: a linear axis (``type = "prismatic"``): the reading is a length (m) added to d, theta a constant
    prismatic: bool = False


@dataclass
class FourBar:
    """The ``[loop]`` table: joint ``joint``'s chain angle made by a four-bar (crank on the previous axis)."""

    joint: int
    crank: float
    coupler: float
    rocker: float


@dataclass
class Arm:
    """The nominal robot."""

    name: str
    convention: str
    links: list[Link]
    tool: np.ndarray
    payload: float
    payload_com: np.ndarray
    gravity: np.ndarray               # m/s^2, robot base frame
    loop: FourBar | None = None

    @property
    def n(self) -> int:
        return len(self.links)

    @property
    def limits(self) -> np.ndarray:
        """Reading limits, SI: rad (m for a prismatic joint)."""
        return np.array([[k.lo, k.hi] for k in self.links])

    @property
    def prismatic(self) -> tuple[bool, ...]:
        return tuple(k.prismatic for k in self.links)

    @classmethod
    def from_toml(cls, text: str) -> "Arm":
        return cls.from_dict(tomllib.loads(text))

    @classmethod
    def from_dict(cls, doc: dict) -> "Arm":
        deg = math.radians
        links = []
        for row in doc["joint"]:
            linear = row.get("type", "revolute") == "prismatic"
            if linear:       # limits in mm, the reading a length
                lo, hi = row["min_mm"] / 1000.0, row["max_mm"] / 1000.0
            else:
                lo, hi = deg(row.get("min_deg", -180.0)), deg(row.get("max_deg", 180.0))
            links.append(Link(
                alpha=deg(row["alpha_deg"]), a=float(row["a_m"]), d=float(row["d_m"]),
                theta=deg(row.get("theta_deg", 0.0)),
                beta=deg(row["beta_deg"]) if "beta_deg" in row else None,
                b=float(row["b_m"]) if "b_m" in row else None,
                lo=lo, hi=hi, prismatic=linear,
                mass=float(row.get("mass_kg", 0.0)), com=np.array(row.get("com_m", [0.0, 0.0, 0.0]), float),
                coupling=np.array(row["coupling"], float) if "coupling" in row else None,
                coupling_offset=deg(row.get("coupling_offset_deg", 0.0))))
        tool = doc.get("tool", {})
        payload = doc.get("payload", {})
        direction = np.array(doc.get("gravity", {}).get("direction", [0.0, 0.0, -1.0]), float)
        loop = doc.get("loop")
        return cls(
            name=doc["name"], convention=doc.get("convention", "mdh"), links=links,
            tool=np.array([tool.get("a_m", 0.0), tool.get("b_m", 0.0), tool.get("d_m", 0.0)], float),
            payload=float(payload.get("mass_kg", 0.0)),
            payload_com=np.array(payload.get("com_m", [0.0, 0.0, 0.0]), float),
            gravity=G * direction / np.linalg.norm(direction),
            loop=None if loop is None else FourBar(int(loop["joint"]), float(loop["crank_m"]),
                                                   float(loop["coupler_m"]), float(loop["rocker_m"])))
