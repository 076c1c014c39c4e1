"""Simulated measurements with known truth and optional hidden effects.

The simulator is the calibration model itself, evaluated with "true"
parameter values: nominal geometry plus random errors, joint compliance and
any of the hidden effects (periodic gear error, encoder scale, backlash,
thermal expansion), then Gaussian noise. Tests hide an effect here and ask
the identification or the diagnosis to find it.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .data import Measurements
from .errors import InputError
from .kinematics import base_pose_matrix
from .model import Model, pose_to_base0
from .robot import PROBLEMS, Robot, load_robot
from .terms import make_term


@dataclass
class Effects:
    """What the simulated robot does differently from its nominal model.

    Parameters
    ----------
    length_sigma : float
        Std of the random errors of link lengths and tool offset (m).
    angle_sigma : float
        Std of the random errors of link angles (rad).
    stiffness : dict of int to float
        Joint stiffness (N m/rad) of compliant joints, by 1-based joint.
    periodic : list of (joint, harmonic, amplitude_rad, phase_rad)
        Periodic transmission errors ``A sin(h q_j + phi)``.
    encoder_scale : dict of int to float
        Relative scale error ``s`` of joint readings (angle ``(1 + s) q``).
    backlash : dict of int to float
        Half the play (rad); the sign follows the joint's gravity torque.
    cubic : dict of int to float
        Progressive stiffness: a further deflection ``k3 tau^3`` (rad/(N m)^3)
        of the joint, by 1-based joint (negative: the joint stiffens with load).
    thermal_alpha : float
        Relative growth of every length per kelvin.
    thermal_links : dict of int to float
        Relative growth per kelvin of the lengths of single links (by joint).
    temperature : (float, float)
        Range of the ``temperature_c`` column when ``thermal_alpha`` is set
        (a slow drift in row order).
    drift : sequence of 3 floats
        Velocity (m per second of ``time_s``, or per row) at which the
        measured points drift.
    noise : float
        Std of the measurement noise per axis (m).
    base_xyz, base_rpy : sequence of 3 floats
        Pose of the robot base in the measurement frame (m, rad).
    """

    length_sigma: float = 0.5e-3
    angle_sigma: float = math.radians(0.05)
    stiffness: dict[int, float] = field(default_factory=dict)
    periodic: list[tuple[int, int, float, float]] = field(default_factory=list)
    encoder_scale: dict[int, float] = field(default_factory=dict)
    backlash: dict[int, float] = field(default_factory=dict)
    cubic: dict[int, float] = field(default_factory=dict)
    thermal_alpha: float = 0.0
    thermal_links: dict[int, float] = field(default_factory=dict)
    temperature: tuple[float, float] = (18.0, 28.0)
    drift: tuple[float, float, float] = (0.0, 0.0, 0.0)
    noise: float = 20e-6
    base_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class Truth:
    """The simulated robot: a model and its true parameter values."""

    model: Model
    values: np.ndarray
    base0: np.ndarray
    effects: Effects

    def value(self, name: str) -> float:
        """True value of a parameter (SI)."""
        return float(self.values[self.model.parameters.index(name)])

    def predict(self, data: Measurements) -> np.ndarray:
        """Noise-free true positions (m) of the poses in ``data``."""
        return self.model.predict(data.q, self.values, self.model.covariates(data), self.base0)


def true_model(robot: Robot, effects: Effects, rng: np.random.Generator,
               t_ref: float | None = None) -> Truth:
    """Draw a true robot: nominal + random geometry, plus the effects' terms."""
    terms = [make_term("geometric")]
    if effects.stiffness:
        terms.append(make_term("joint_compliance", joints=sorted(effects.stiffness)))
    if effects.periodic:
        terms.append(make_term("joint_periodic", harmonics=[(j, h) for j, h, _, _ in effects.periodic]))
    if effects.encoder_scale:
        terms.append(make_term("encoder_scale", joints=sorted(effects.encoder_scale)))
    if effects.backlash:
        terms.append(make_term("backlash", joints=sorted(effects.backlash)))
    if effects.cubic:
        terms.append(make_term("nonlinear_stiffness", joints=sorted(effects.cubic)))
    lo, hi = effects.temperature
    if effects.thermal_alpha:
        terms.append(make_term("thermal_expansion", t_ref=(lo + hi) / 2 if t_ref is None else t_ref))
    if effects.thermal_links:
        terms.append(make_term("thermal_expansion", joints=sorted(effects.thermal_links),
                               t_ref=(lo + hi) / 2 if t_ref is None else t_ref))
    if any(effects.drift):
        terms.append(make_term("drift"))
    model = Model(robot, terms)
    values = model.parameters.nominal.copy()
    for i, p in enumerate(model.parameters):
        if p.term != "geometric" or p.group == "base":
            continue
        sigma = effects.length_sigma if p.unit == "m" else effects.angle_sigma
        values[i] += rng.normal(0.0, sigma)
    idx = model.parameters.index
    for j, k in effects.stiffness.items():
        values[idx(f"c{j}")] = 1.0 / k
    for j, h, amp, phase in effects.periodic:
        # A sin(h q + phi) = A cos(phi) sin(h q) + A sin(phi) cos(h q)
        values[idx(f"gear{j}_s{h}")] += amp * math.cos(phase)
        values[idx(f"gear{j}_c{h}")] += amp * math.sin(phase)
    for j, s in effects.encoder_scale.items():
        values[idx(f"escale{j}")] = s
    for j, b in effects.backlash.items():
        values[idx(f"backlash{j}")] = b
    for j, k3 in effects.cubic.items():
        values[idx(f"cubic{j}")] = k3
    if effects.thermal_alpha:
        values[idx("thermal_alpha")] = effects.thermal_alpha
    for j, a in effects.thermal_links.items():
        values[idx(f"thermal_alpha{j}")] = a
    for k, v in zip("xyz", effects.drift):
        if any(effects.drift):
            values[idx(f"drift_{k}")] = v
    base0 = pose_to_base0(base_pose_matrix(effects.base_xyz, effects.base_rpy))
    return Truth(model, values, base0, effects)


def sample_poses(robot: Robot, n: int, rng: np.random.Generator, *,
                 floor_z: float | None = 0.0, box: tuple | None = None,
                 margin: float = math.radians(5.0), max_tries: int = 1000) -> np.ndarray:
    """Joint readings (rad, (n, n_joints)) uniform within the limits and a workspace filter.

    Parameters
    ----------
    floor_z : float, optional
        Keep poses whose tool point is above this height in the robot base
        frame (m); None disables the floor.
    box : ((xmin, ymin, zmin), (xmax, ymax, zmax)), optional
        Keep poses whose tool point lies inside this box (robot base frame).
    margin : float
        Keep this far from the joint limits (rad).
    """
    if n < 1:
        raise InputError(f"number of poses must be at least 1, got {n}")
    lim = robot.limits.copy()
    lim[:, 0] += margin
    lim[:, 1] -= margin
    lim[lim[:, 0] > lim[:, 1]] = robot.limits[lim[:, 0] > lim[:, 1]]
    # the tool point only where a filter needs it (the identifiability analysis samples without one)
    nominal = Model(robot, "nominal", jit=False) if floor_z is not None or box is not None else None
    eye = pose_to_base0(np.eye(4))
    kept: list[np.ndarray] = []
    for _ in range(max_tries):
        # chunks bound the memory of large pools (10^5 candidates)
        q = rng.uniform(lim[:, 0], lim[:, 1], size=(min(max(4 * (n - len(kept)), 64), 20_000), robot.n))
        xyz = nominal.predict(q, base0=eye) if nominal is not None else None
        ok = np.ones(len(q), dtype=bool)
        if floor_z is not None:
            ok &= xyz[:, 2] > floor_z
        if box is not None:
            lo, hi = np.asarray(box[0]), np.asarray(box[1])
            ok &= np.all((xyz >= lo) & (xyz <= hi), axis=1)
        if robot.loop is not None:
            # keep the four-bar away from its dead points (crank parallel to the link)
            j = robot.loop.joint - 1
            ok &= np.abs(np.sin(q[:, j] - q[:, j - 1])) > 0.5
        kept.extend(q[ok])
        if len(kept) >= n:
            return np.array(kept[:n])
    raise InputError(f"the workspace filter keeps too few poses ({len(kept)} of {n} wanted); "
                     "widen the box or lower the floor")


def simulate(robot: Robot, q: np.ndarray | int, effects: Effects | None = None, *,
             seed: int | None = None, truth: Truth | None = None,
             payload_kg: np.ndarray | None = None, **pose_options) -> tuple[Measurements, Truth]:
    """Simulate a measurement campaign.

    Parameters
    ----------
    robot : Robot
    q : ndarray or int
        Joint readings (rad) or a number of poses to sample.
    effects : Effects, optional
        Defaults to geometric errors and noise only.
    seed : int, optional
    truth : Truth, optional
        Reuse a true robot (e.g. for a validation set of the same robot).
    payload_kg : ndarray, optional
        Payload per pose (adds a ``payload_kg`` column).

    Returns
    -------
    data : Measurements
        With ``x_mm, y_mm, z_mm`` in the measurement frame, and
        ``temperature_c`` when thermal expansion is simulated.
    truth : Truth
    """
    rng = np.random.default_rng(seed)
    effects = effects or (truth.effects if truth else Effects())
    if truth is None:
        truth = true_model(robot, effects, rng)
    if isinstance(q, (int, np.integer)):
        q = sample_poses(robot, int(q), rng, **pose_options)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    extra: dict[str, np.ndarray] = {}
    if payload_kg is not None:
        extra["payload_kg"] = np.broadcast_to(np.asarray(payload_kg, dtype=float), (len(q),)).copy()
    if effects.thermal_alpha or effects.thermal_links:
        lo, hi = effects.temperature
        drift = np.linspace(lo, hi, len(q)) + rng.normal(0, 0.05 * (hi - lo), len(q))
        extra["temperature_c"] = np.clip(drift, lo, hi)
    data = Measurements.from_arrays(q, None, **extra)
    xyz = truth.predict(data) + rng.normal(0.0, effects.noise, size=(len(q), 3))
    return data.with_positions(xyz), truth


# --- protocols ---------------------------------------------------------------------

PROTOCOL_DIR = PROBLEMS / "protocols"


@dataclass
class Protocol:
    """An experiment protocol: a robot, a simulated truth and named pose sets."""

    name: str
    robot: Robot
    effects: Effects
    sets: dict[str, int]
    seed: int
    description: str = ""
    workspace: dict = field(default_factory=dict)

    def generate(self, seed: int | None = None) -> tuple[dict[str, Measurements], Truth]:
        """Simulate every pose set of the protocol from one true robot."""
        rng = np.random.default_rng(self.seed if seed is None else seed)
        truth = true_model(self.robot, self.effects, rng)
        out = {}
        for k, (name, n) in enumerate(self.sets.items()):
            data, _ = simulate(self.robot, n, truth=truth, seed=int(rng.integers(2**31)),
                               **self.workspace)
            out[name] = data
        return out, truth


def load_protocol(spec: str | Path) -> Protocol:
    """Load a protocol by name (``problems/protocols/<name>.toml``) or path.

    Its ``robot`` is a built-in name or a robot file, relative to the
    protocol's folder (or to the working folder).
    """
    path = Path(spec)
    if not path.exists():
        path = PROTOCOL_DIR / f"{spec}.toml"
    if not path.exists():
        known = sorted(p.stem for p in PROTOCOL_DIR.glob("*.toml"))
        raise InputError(f"no such protocol; known: {', '.join(known)}", file=str(spec))
    try:
        with open(path, "rb") as fh:
            d = tomllib.load(fh)
        t = d.get("truth", {})
        effects = Effects(
            length_sigma=t.get("length_sigma_mm", 0.5) / 1000,
            angle_sigma=math.radians(t.get("angle_sigma_deg", 0.05)),
            stiffness={int(k): float(v) for k, v in t.get("stiffness", {}).items()},
            periodic=[(int(j), int(h), math.radians(a), math.radians(ph))
                      for j, h, a, ph in t.get("periodic_deg", [])],
            encoder_scale={int(k): float(v) for k, v in t.get("encoder_scale", {}).items()},
            backlash={int(k): math.radians(float(v)) for k, v in t.get("backlash_deg", {}).items()},
            thermal_alpha=float(t.get("thermal_alpha", 0.0)),
            thermal_links={int(k): float(v) for k, v in t.get("thermal_links", {}).items()},
            cubic={int(k): float(v) for k, v in t.get("cubic", {}).items()},
            noise=t.get("noise_mm", 0.02) / 1000,
            base_xyz=tuple(t.get("base_xyz_m", (0.0, 0.0, 0.0))),
            base_rpy=tuple(math.radians(x) for x in t.get("base_rpy_deg", (0.0, 0.0, 0.0))),
        )
        ws = d.get("workspace", {})
        workspace = {"floor_z": ws.get("floor_z_m", 0.0)}
        if "box_min_m" in ws:
            workspace["box"] = (tuple(map(float, ws["box_min_m"])), tuple(map(float, ws["box_max_m"])))
            if any(len(b) != 3 for b in workspace["box"]):
                raise ValueError("workspace box_min_m and box_max_m need three numbers each (x, y, z)")
        robot_spec = d["robot"]
        if isinstance(robot_spec, str) and (path.parent / robot_spec).is_file():
            robot_spec = path.parent / robot_spec   # a robot file beside the protocol
        return Protocol(name=d.get("name", path.stem), robot=load_robot(robot_spec), effects=effects,
                        sets={k: int(v) for k, v in d["sets"].items()}, seed=int(d.get("seed", 0)),
                        description=d.get("description", ""), workspace=workspace)
    except InputError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, tomllib.TOMLDecodeError) as e:
        raise InputError(f"invalid protocol: {e!r}", file=str(path)) from e
