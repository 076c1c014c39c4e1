"""Simulated measurements with known truth and optional hidden effects.

The simulator is the calibration model itself, evaluated with "true"
parameter values: nominal geometry plus random errors, joint compliance and
any of the hidden effects (periodic gear error, encoder scale, backlash,
thermal expansion), then Gaussian noise. Tests hide an effect here and ask
the identification or the diagnosis to find it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..kinematics import base_pose_matrix
from ..loading import load_robot
from ..model._symbolic import Model, pose_to_base0
from ..robot import PROBLEMS, Robot, _Validator
from ..runtime._files import finite_number, named_toml, read_toml
from ..terms import make_term
from ..terms._carriage_angle import CarriageAngle
from ..terms._drift import Drift
from ..terms._geometric import Geometric
from ..terms._straightness import Straightness
from ._measurements import Measurements


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
    backlash_motion : dict of int to float
        Half the play (rad) taken up by the direction of the joint's last
        move (in row order): the output trails its motor.
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
        Velocity (m per second of ``time_s``) at which the measured points
        drift; the simulated data then get a ``time_s`` column, one pose a
        second.
    noise : float
        Std of the measurement noise per axis (m).
    base_xyz, base_rpy : sequence of 3 floats
        Pose of the robot base in the measurement frame (m, rad).
    orientation_noise : float or None
        Full pose: std of the measured orientation's noise per axis (rad);
        the data then have ``rx_deg, ry_deg, rz_deg`` (the probe's orientation,
        intrinsic XYZ). None (default): positions only.
    tool_rpy : sequence of 3 floats
        Full pose: the probe's mounting rotation on the flange, fixed-axis
        roll-pitch-yaw ``Rz(yaw) Ry(pitch) Rx(roll)`` (rad).
    straightness : list of (joint, direction, (c2, c3))
        A linear axis' straightness across it (``x`` or ``y``): the
        coefficients of its Legendre polynomials P2, P3 of the position (m;
        :mod:`casadical.terms._straightness`).
    carriage_angle : list of (joint, angle, (c1, c2))
        A linear axis' carriage turning as it travels (``roll``, ``pitch``,
        ``yaw``): the coefficients of P1, P2 of the position (rad;
        :mod:`casadical.terms._carriage_angle`).

    On a linear axis ``periodic`` is ``(joint, cycles per metre, amplitude m,
    phase rad)``, ``backlash`` and ``backlash_motion`` are half plays in m
    and ``encoder_scale`` a relative scale of the travel.
    """

    length_sigma: float = 0.5e-3
    angle_sigma: float = math.radians(0.05)
    stiffness: dict[int, float] = field(default_factory=dict)
    periodic: list[tuple[int, int, float, float]] = field(default_factory=list)
    encoder_scale: dict[int, float] = field(default_factory=dict)
    backlash: dict[int, float] = field(default_factory=dict)
    backlash_motion: dict[int, float] = field(default_factory=dict)
    cubic: dict[int, float] = field(default_factory=dict)
    thermal_alpha: float = 0.0
    thermal_links: dict[int, float] = field(default_factory=dict)
    temperature: tuple[float, float] = (18.0, 28.0)
    drift: tuple[float, float, float] = (0.0, 0.0, 0.0)
    noise: float = 20e-6
    base_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation_noise: float | None = None
    tool_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    straightness: list[tuple[int, str, tuple[float, float]]] = field(default_factory=list)
    carriage_angle: list[tuple[int, str, tuple[float, float]]] = field(default_factory=list)


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

    def predict_rotations(self, data: Measurements) -> np.ndarray:
        """Noise-free true probe orientations (N, 3, 3) of the poses in ``data`` (full-pose truths)."""
        return self.model.probe_rotation(data.q, self.values, self.model.covariates(data), self.base0)

    def tool_rotation(self) -> np.ndarray:
        """The true probe mounting on the flange (3x3)."""
        return base_pose_matrix((0.0, 0.0, 0.0), self.effects.tool_rpy)[:3, :3]


def another_session(truth: Truth, base_xyz=(0.0, 0.0, 0.0), base_rpy=(0.0, 0.0, 0.0),
                    tool_shift=(0.0, 0.0, 0.0), drift=(0.0, 0.0, 0.0), t_ref: float = 0.0) -> Truth:
    """The same robot measured in another session: the tracker elsewhere (``base_xyz`` m, ``base_rpy`` rad),
    the probe re-mounted (its point moved by ``tool_shift``, m, in the flange frame), and a drift of that
    session (m/s of ``time_s``, from ``t_ref``) instead of the truth's own."""
    terms = [t for t in truth.model.terms if not isinstance(t, Drift)]
    if any(drift):
        terms.append(make_term("drift", t_ref=t_ref))
    model = Model(truth.model.robot, [t for t in terms if not isinstance(t, Geometric)] + [Geometric()])
    values = model.parameters.nominal.copy()
    for i, name in enumerate(truth.model.parameters.names):
        if name in model.parameters and not name.startswith("drift"):
            values[model.parameters.index(name)] = truth.values[i]
    for k, d, v in zip("xyz", tool_shift, drift):
        values[model.parameters.index(f"tool_{k}")] += d
        if any(drift):
            values[model.parameters.index(f"drift_{k}")] = v
    return Truth(model, values, pose_to_base0(base_pose_matrix(base_xyz, base_rpy)),
                 replace(truth.effects, drift=tuple(drift)))


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
    if effects.backlash_motion:
        terms.append(make_term("backlash_motion", joints=sorted(effects.backlash_motion)))
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
    if effects.straightness:
        terms.append(make_term("straightness", pairs=[(j, k) for j, k, _ in effects.straightness]))
    if effects.carriage_angle:
        terms.append(make_term("carriage_angle", pairs=[(j, k) for j, k, _ in effects.carriage_angle]))
    if effects.orientation_noise is not None:   # the probe's mounting: tool_* hold the whole rotation (R0 = I)
        terms.append(make_term("tool_orientation"))
    model = Model(robot, terms)
    values = model.parameters.nominal.copy()
    for i, p in enumerate(model.parameters):
        if p.term != Geometric.name or p.group == "base":
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
    for j, b in effects.backlash_motion.items():
        values[idx(f"backlash_m{j}")] = b
    for j, k3 in effects.cubic.items():
        values[idx(f"cubic{j}")] = k3
    if effects.thermal_alpha:
        values[idx("thermal_alpha")] = effects.thermal_alpha
    for j, a in effects.thermal_links.items():
        values[idx(f"thermal_alpha{j}")] = a
    for k, v in zip("xyz", effects.drift):
        if any(effects.drift):
            values[idx(f"drift_{k}")] = v
    for name, table in ((Straightness.name, effects.straightness), (CarriageAngle.name, effects.carriage_angle)):
        term = model.term(name)
        for j, key, coefs in table:
            for k, c in zip(term.DEGREES, coefs):
                values[idx(term.parameter_name(j, key, k))] = c
    if effects.orientation_noise is not None:
        for k, v in zip(("roll", "pitch", "yaw"), effects.tool_rpy):
            values[idx(f"tool_{k}")] = v
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
        Keep this far from the joint limits (rad; as many millimetres as degrees for a prismatic joint).
    """
    if n < 1:
        raise InputError(f"number of poses must be at least 1, got {n}")
    lim = robot.limits.copy()
    # the margin in degrees, millimetres on a linear axis
    margin = robot.from_file_units(np.full(robot.n, math.degrees(margin)))
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
        With ``x_mm, y_mm, z_mm`` in the measurement frame,
        ``temperature_c`` when thermal expansion is simulated, and ``rx_deg,
        ry_deg, rz_deg`` with ``effects.orientation_noise`` (drawn after the
        positions' noise: the positions are those of the same seed without).
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
    if any(effects.drift):   # one pose a second
        extra["time_s"] = np.arange(len(q), dtype=float)
    data = Measurements.from_arrays(q, None, prismatic=robot.prismatic, **extra)
    xyz = truth.predict(data) + rng.normal(0.0, effects.noise, size=(len(q), 3))
    data = data.with_positions(xyz)
    if effects.orientation_noise is not None:
        from scipy.spatial.transform import Rotation
        turn = Rotation.from_rotvec(rng.normal(0.0, effects.orientation_noise, size=(len(q), 3))).as_matrix()
        data = data.with_orientations(truth.predict_rotations(data) @ turn)
    return data, truth


# --- protocols ---------------------------------------------------------------------

PROTOCOL_DIR = PROBLEMS / "protocols"
#: most poses a protocol's set may ask for (a calibration uses hundreds, a benchmark a few hundred thousand;
#: beyond this the memory of the simulation, not the work, would be the limit)
MAX_POSES = 1_000_000


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

    Raises
    ------
    InputError
        Unknown name, invalid TOML, or an invalid key (the message names the
        file and the key, e.g. ``column 'truth.noise_mm'``).
    """
    path = named_toml(spec, PROTOCOL_DIR, "no such protocol; known: {known}")
    d = read_toml(path)
    v = TomlValidator(str(path))
    v.keys(d, {"name", "robot", "description", "seed", "sets", "truth", "workspace"}, "")
    robot = load_robot(resolve_path(v.string(d, "robot", "", required=True), path))
    sets = v.table(d, "sets", "", required=True)
    if not sets:
        raise InputError("needs at least one pose set", file=str(path), column="sets")
    return Protocol(name=v.string(d, "name", "", default=path.stem), robot=robot,
                    effects=effects_from_table(v.table(d, "truth", ""), robot, str(path)),
                    sets={k: v.integer(sets, k, "sets", minimum=1, maximum=MAX_POSES) for k in sets},
                    seed=v.integer(d, "seed", "", default=0, minimum=0),
                    description=v.string(d, "description", "", default=""),
                    workspace=workspace_from_table(v.table(d, "workspace", ""), str(path)))


# --- protocol tables (shared with casadical.study) ---------------------------------

#: keys of a protocol's ``[truth]`` table
TRUTH_KEYS = {"length_sigma_mm", "angle_sigma_deg", "noise_mm", "stiffness", "periodic_deg", "encoder_scale",
              "backlash_deg", "backlash_motion_deg", "thermal_alpha", "thermal_links", "cubic", "base_xyz_m",
              "base_rpy_deg", "periodic_mm", "backlash_mm", "backlash_motion_mm", "straightness_mm",
              "carriage_angle_mrad"}
#: keys of a protocol's ``[workspace]`` table
WORKSPACE_KEYS = {"floor_z_m", "box_min_m", "box_max_m"}


class TomlValidator(_Validator):
    """Typed look-ups in a protocol TOML; errors are :class:`InputError` naming ``table.key``."""

    def _err(self, msg: str, table: str, key: str) -> InputError:
        return InputError(msg, file=self.file, column=f"{table}.{key}" if table else key)

    def table(self, tab: dict, key: str, table: str, required: bool = False) -> dict:
        if key not in tab:
            if required:
                raise self._err("missing required table", table, key)
            return {}
        if not isinstance(tab[key], dict):
            raise self._err(f"must be a table, got {tab[key]!r}", table, key)
        return tab[key]

    def integer(self, tab: dict, key: str, table: str, required: bool = False, default=None,
                minimum: int | None = None, maximum: int | None = None):
        if key not in tab:
            if required:
                raise self._err("missing required key", table, key)
            return default
        x = tab[key]
        if isinstance(x, bool) or not isinstance(x, int):
            raise self._err(f"must be a whole number, got {x!r}", table, key)
        if minimum is not None and x < minimum:
            raise self._err(f"must be at least {minimum}, got {x}", table, key)
        if maximum is not None and x > maximum:
            raise self._err(f"must be at most {maximum:,}, got {x:,}", table, key)
        return x

    def nonnegative(self, tab: dict, key: str, table: str, default: float) -> float:
        x = self.number(tab, key, table, default=default)
        if x < 0:
            raise self._err(f"must not be negative, got {x}", table, key)
        return x

    def per_joint(self, tab: dict, key: str, table: str, n_joints: int) -> dict[int, float]:
        """A table ``{joint = number}`` with joints 1..n_joints."""
        sub = self.table(tab, key, table)
        out = {}
        for k in sub:
            if not (k.isdigit() and 1 <= int(k) <= n_joints):
                raise self._err(f"must be a joint number from 1 to {n_joints}", f"{table}.{key}", k)
            out[int(k)] = self.number(sub, k, f"{table}.{key}")
        return out


def resolve_path(spec: str, relative_to: str | Path) -> str:
    """A file named in a TOML file: relative to that file's folder if it exists there, else as given."""
    beside = Path(relative_to).parent / spec
    return str(beside) if not Path(spec).is_absolute() and beside.exists() else spec


def effects_from_table(t: dict, robot: Robot, file: str, table: str = "truth") -> Effects:
    """The :class:`Effects` of a protocol's ``[truth]`` table (mm, degrees; see docs/formats.md)."""
    v = TomlValidator(file)
    v.keys(t, TRUTH_KEYS, table)
    n = robot.n
    stiffness = v.per_joint(t, "stiffness", table, n)
    for j, k in stiffness.items():
        if k <= 0:
            raise InputError(f"stiffness must be positive, got {k}", file=file, column=f"{table}.stiffness.{j}")
    # a revolute joint's errors in degrees, a linear axis' in mm (and the encoder scale of either, relative)
    linear = {j for j in range(1, n + 1) if robot.joints[j - 1].prismatic}
    for key, want in (("stiffness", False), ("backlash_deg", False), ("backlash_motion_deg", False),
                      ("cubic", False), ("backlash_mm", True), ("backlash_motion_mm", True)):
        for j in v.per_joint(t, key, table, n):
            if (j in linear) != want:
                raise InputError(f"joint {j} is {'revolute' if want else 'prismatic (a linear axis)'}: {key} is "
                                 f"an error of a {'linear axis' if want else 'revolute joint'}"
                                 + ("" if want else " (a linear axis' play: backlash_mm, backlash_motion_mm)"),
                                 file=file, column=f"{table}.{key}.{j}")
    backlash = {j: math.radians(b) for j, b in v.per_joint(t, "backlash_deg", table, n).items()}
    backlash.update({j: b / 1000 for j, b in v.per_joint(t, "backlash_mm", table, n).items()})
    backlash_motion = {j: math.radians(b) for j, b in v.per_joint(t, "backlash_motion_deg", table, n).items()}
    backlash_motion.update({j: b / 1000 for j, b in v.per_joint(t, "backlash_motion_mm", table, n).items()})
    periodic = []
    for key, item_form, on_axis in (("periodic_deg", "[joint, harmonic, amplitude_deg, phase_deg]", False),
                                    ("periodic_mm", "[joint, cycles_per_m, amplitude_mm, phase_deg]", True)):
        for i, (j, h, amp, ph) in enumerate(_items(t, key, table, file, item_form, n)):
            where = f"{table}.{key}[{i + 1}]"
            if h != int(h) or h < 1:
                raise InputError(f"the harmonic must be a whole number >= 1, got {h!r}", file=file, column=where)
            if (j in linear) != on_axis:
                raise InputError(f"joint {j} is {'revolute' if on_axis else 'prismatic (a linear axis)'}: {key} is a "
                                 f"{'linear axis' if on_axis else 'revolute joint'}'s periodic error"
                                 + ("" if on_axis else " (a linear axis': periodic_mm, cycles per metre)"),
                                 file=file, column=where)
            periodic.append((j, int(h), amp / 1000 if on_axis else math.radians(amp), math.radians(ph)))
    axis_errors = {}
    for key, kinds, form in (("straightness_mm", ("x", "y"), "[joint, direction, p2_mm, p3_mm]"),
                             ("carriage_angle_mrad", ("roll", "pitch", "yaw"), "[joint, angle, p1_mrad, p2_mrad]")):
        axis_errors[key] = []
        for i, (j, kind, a, b) in enumerate(_items(t, key, table, file, form, n, word=1)):
            where = f"{table}.{key}[{i + 1}]"
            if kind not in kinds:
                raise InputError(f"must name one of {', '.join(kinds)}, got {kind!r}", file=file, column=where)
            if j not in linear:
                raise InputError(f"joint {j} is revolute: {key} is a linear axis' error", file=file, column=where)
            axis_errors[key].append((j, kind, (a / 1000, b / 1000)))     # mm and mrad to m and rad
    return Effects(
        length_sigma=v.nonnegative(t, "length_sigma_mm", table, 0.5) / 1000,
        angle_sigma=math.radians(v.nonnegative(t, "angle_sigma_deg", table, 0.05)),
        stiffness=stiffness,
        periodic=periodic,
        encoder_scale=v.per_joint(t, "encoder_scale", table, n),
        backlash=backlash,
        backlash_motion=backlash_motion,
        straightness=axis_errors["straightness_mm"],
        carriage_angle=axis_errors["carriage_angle_mrad"],
        thermal_alpha=v.number(t, "thermal_alpha", table, default=0.0),
        thermal_links=v.per_joint(t, "thermal_links", table, n),
        cubic=v.per_joint(t, "cubic", table, n),
        noise=v.nonnegative(t, "noise_mm", table, 0.02) / 1000,
        base_xyz=tuple(float(x) for x in v.vector(t, "base_xyz_m", table, 3, default=np.zeros(3))),
        base_rpy=tuple(math.radians(x) for x in v.vector(t, "base_rpy_deg", table, 3, default=np.zeros(3))),
    )


def _items(t: dict, key: str, table: str, file: str, form: str, n_joints: int, word: int | None = None) -> list[tuple]:
    """The entries of a list of four-item lists ``key`` (``form`` in the messages): a joint 1..n_joints first,
    numbers after it (a word at index ``word``)."""
    items = t.get(key, [])
    if not isinstance(items, list):
        raise InputError(f"must be a list of {form}, got {items!r}", file=file, column=f"{table}.{key}")
    out = []
    for i, item in enumerate(items):
        where = f"{table}.{key}[{i + 1}]"
        ok = isinstance(item, list) and len(item) == 4 and all(
            isinstance(x, str) if k == word else finite_number(x) for k, x in enumerate(item))
        if not ok:
            raise InputError(f"must be {form}, got {item!r}", file=file, column=where)
        if item[0] != int(item[0]) or not 1 <= item[0] <= n_joints:
            raise InputError(f"the joint must be 1 to {n_joints}, got {item[0]!r}", file=file, column=where)
        out.append((int(item[0]), *item[1:]))
    return out


def workspace_from_table(ws: dict, file: str, table: str = "workspace") -> dict:
    """Pose filter options of :func:`sample_poses` from a protocol's ``[workspace]`` table."""
    v = TomlValidator(file)
    v.keys(ws, WORKSPACE_KEYS, table)
    out: dict = {"floor_z": v.number(ws, "floor_z_m", table, default=0.0)}
    if ("box_min_m" in ws) != ("box_max_m" in ws):
        raise InputError("give both box_min_m and box_max_m, or neither", file=file,
                         column=f"{table}.{'box_max_m' if 'box_min_m' in ws else 'box_min_m'}")
    if "box_min_m" in ws:
        lo, hi = (v.vector(ws, k, table, 3) for k in ("box_min_m", "box_max_m"))
        if not np.all(lo < hi):
            raise InputError(f"every component must exceed box_min_m {lo.tolist()}, got {hi.tolist()}",
                             file=file, column=f"{table}.box_max_m")
        out["box"] = (tuple(lo.tolist()), tuple(hi.tolist()))
    return out
