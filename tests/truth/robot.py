"""The true robot: its geometry, the physical effects of its drives, and where its flange is.

Every effect is written from its physical definition as the docs state it
(docs/guide.md's term table, docs/diagnosis.md "Sign conventions",
docs/formats.md section 1), not from casadical's terms:

- **Link transforms** (formats.md): ``mdh`` Rx(alpha) Tx(a) Ry(beta) Ty(b)
  Rz(angle + theta) Tz(d); ``dh`` Rz(angle + theta) Tz(d) Tx(a) Rx(alpha)
  Ry(beta) Ty(b); the tool point Tx Ty Tz of the tool's a, b, d in the last
  link frame.
- **Drives.** Each joint reading q_j is its drive's (motor-side) angle. The
  drive really stands at ``m_j = q_j + e_j``, where e_j sums what the drive
  does (below). The chain angles are made from the drives' angles: the
  angle itself, or ``sum_k coupling[k] m_k + offset`` for a coupled row, or
  the four-bar's rocker (loop). For an arm without couplings or loops, e_j
  is simply added to joint j's angle.
- **Gravity torques**: about each joint's axis, of the weights of every link
  after it (its own included) at their centres of mass (given in their link
  frames) and the row's payload at its centre of mass in the tool frame
  (the robot file's tool point, orientation of the last link). A drive
  carries the torque its angle does work against: ``tau_drive = J^T tau``
  with ``J = d chain angles / d drive angles`` (virtual work; the identity
  for an arm without couplings). Torques are those of the **deflected**
  arm: the equilibrium is found by fixed-point iteration. (casadical takes
  those of the undeflected arm: an approximation, second order in the
  deflection, 3e-3 of the effect at 1 mrad; tests/model/test_truth_vs_package.py.)
- **Joint compliance**: ``e_j += tau_j / k_j``: the joint gives way in the
  direction of its torque. **Progressive stiffness**: ``e_j += k3_j
  tau_j^3`` beyond it (k3 < 0: stiffens with load).
- **Periodic gear error**: ``e_j += A sin(h q_j + phi)`` of the reading. On a
  linear axis (a prismatic joint) ``h`` is cycles per metre of travel (a
  screw's or a rack's pitch): ``e_j += A sin(2 pi h q_j + phi)``, A in m.
- **Encoder scale**: the drive turns by ``(1 + s) q_j``: ``e_j += s q_j``.
- **Backlash, torque side**: half play b >= 0 taken up in the direction of
  the torque: ``e_j += b sign(tau_j)``. **Motion side** (lag): the output
  trails its motor, after a move in the positive direction it stands b short
  of its reading: ``e_j -= b sign(last move_j)``, the last move being the
  joint's last change of reading in measurement order (a joint that has not
  moved since keeps the flank of its earlier move); before its first move a
  joint sits mid-play (0).
- **Thermal expansion**: every length (links' a, b, d, the tool, the loop)
  times ``1 + alpha (T - t_ref)``; per link: that row's a, b and d times ``1
  + alpha_j (T - t_ref)``. Centres of mass do not move.

- **A linear axis' carriage** (ISO 230-1): the carriage of prismatic joint j
  at position ``p`` (its travel, the reading plus its errors) stands off the
  straight line by ``straightness[(j, "x")](p)`` and ``[(j, "y")](p)`` (m)
  across the axis, and turns by ``carriage_angle[(j, "roll")](p)`` about the
  travel and by ``"pitch"`` and ``"yaw"`` about the axes across it (rad); all
  in the axis' frame right after its travel, ``Rz(theta) Tz(d + p)`` (z
  along the travel, x the link's x): the link transform becomes ``...
  Rz(theta) Tz(d + p) Tx(ex) Ty(ey) Rx(pitch) Ry(yaw) Rz(roll) ...`` (the
  rest of the row after it: dh ``Tx(a) Rx(alpha) Ry(beta) Ty(b)``).

Effects outside casadical's diagnosis catalogue (what the hidden-effect
matrix hides so that the diagnosis must say "unexplained", or what the
new terms of casadical/terms must find):

- **Joint coupling** (the gear coupling of a wrist: one drive's motion
  turns the next joint's gears): ``e_j += c_jk q_k``, joint k's *reading*
  (``Effects.coupling[(j, k)] = c_jk``, rad/rad).
- **Another joint's reading, any function**: ``e_j += f(q_k)``
  (``Effects.cross_error[(j, k)] = f``); ``reading_error`` is a function of
  the joint's own reading.
- **Axis tilt** (a wobbling bearing): the link turning about joint j turns
  also about its own x axis by ``w = a sin(c_j) + b cos(c_j)``, c_j joint
  j's chain angle (its reading plus its errors, theta not included): the
  link transform becomes ``... Rz(c_j + theta_j) Rx(w) ...`` (the rest of
  the row after it: mdh ``Tz(d)``, dh ``Tz(d) Tx(a) Rx(alpha) Ry(beta)
  Ty(b)``). Not an angle error: the axis itself tips
  (``Effects.axis_tilt[j] = (a, b)``, rad).
- **Mount compliance**: the robot's base frame tilts on its mount (a
  pedestal, a column, a track's carriage) under the moment of the weights
  ``M = sum_i c_i x (m_i g)`` of every link and the payload about the base
  frame's origin (the mount point; ``g`` the robot file's gravity in the
  base frame, the centres of the deflected arm). The tilt is the rotation
  by the vector ``theta = C M`` (one compliance ``C`` >= 0, rad/(N m); or
  ``(Cx, Cy)``: ``theta = (Cx M_x, Cy M_y, 0)``, for a robot standing on its
  base), about the base frame's origin, before joint 1: every frame of the
  arm, the tool point and the flange's orientation turn with it. The arm
  tilts *towards* its weights (a weight at +x: ``M_y > 0``, Ry turns +x
  down). ``Effects.mount_compliance``; a session may have its own
  (``Session.mount_compliance``: the column's height differs), and the
  compliance may follow a law over a session column, ``C = C_0 + sum c_k
  v_k`` or ``C_0 + f(v)`` (``Effects.mount_law = {"height_m": c}``, ``v`` the session's
  ``Session.columns["height_m"]``: a column's top tilts by ``M L / (E I)``
  under a moment M, its compliance grows with its length L). The
  torques are those of the untilted arm (the tilt changes gravity's
  direction in the arm by theta, 1e-4: second order).
- **Bearing compliance** (a joint bearing's tilting stiffness): joint j's
  axis tips under the moment of the weights it carries (links j..n and the
  payload, at their centres of the deflected arm) about the origin of its
  axis, ``M_j = sum_{k >= j} (c_k - o_j) x (m_k g)``. In the axis' own frame
  (the frame whose z is joint j's axis, before the joint turns: mdh after
  ``Rx Tx Ry Ty``, dh the frame before the row) the two components across
  the axis turn the joint about its origin by the rotation vector ``(cx
  M_x, cy M_y, 0)`` (rad/(N m) each, >= 0): the link transform becomes
  ``... R(cx M_x, cy M_y, 0) Rz(c_j + theta_j) ...``, and every link after
  it turns with it (``Effects.bearing_compliance[j] = (cx, cy)``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from . import transforms as tf
from .arm import Arm


@dataclass
class Effects:
    """What the true robot's drives and structure do (SI units; joints 1-based)."""

    stiffness: dict[int, float] = field(default_factory=dict)          # k_j, N m/rad
    cubic: dict[int, float] = field(default_factory=dict)              # k3_j, rad/(N m)^3
    periodic: list[tuple[int, int, float, float]] = field(default_factory=list)   # (j, h, A rad, phi rad)
    encoder_scale: dict[int, float] = field(default_factory=dict)      # s_j
    backlash: dict[int, float] = field(default_factory=dict)           # half play b_j, rad, torque side
    backlash_motion: dict[int, float] = field(default_factory=dict)    # half play b_j, rad, motion side
    thermal_alpha: float = 0.0                                         # 1/K, every length
    thermal_links: dict[int, float] = field(default_factory=dict)      # 1/K, lengths of row j
    t_ref: float = 20.0                                                # deg C at which the geometry holds
    #: an angle error of joint j as any function of its reading (rad -> rad): structure in no catalogue
    reading_error: dict[int, Callable] = field(default_factory=dict)
    #: e_j += c_jk q_k by (j, k): joint j's drive turned by joint k's reading (rad/rad)
    coupling: dict[tuple[int, int], float] = field(default_factory=dict)
    #: e_j += f(q_k) by (j, k): joint j's error as any function of joint k's reading (rad -> rad)
    cross_error: dict[tuple[int, int], Callable] = field(default_factory=dict)
    #: joint j gives way under joint k's torque: e_j += tau_k / k_jk (a drive train shared under load; in no
    #: catalogue: a compliance answers its own joint's torque)
    cross_stiffness: dict[tuple[int, int], float] = field(default_factory=dict)
    #: (a, b) rad by joint: the link after joint j turns about its x axis by a sin(c_j) + b cos(c_j)
    axis_tilt: dict[int, tuple[float, float]] = field(default_factory=dict)
    #: rad/(N m): the base tilts by C M (one C) or (Cx M_x, Cy M_y, 0) (a pair)
    mount_compliance: float | tuple[float, float] = 0.0
    #: (cx, cy) rad/(N m) by joint: its axis tips by (cx M_x, cy M_y, 0) in its own frame, M the moment of the
    #: weights it carries about its origin
    bearing_compliance: dict[int, tuple[float, float]] = field(default_factory=dict)
    #: rad/(N m) per unit of a session column, by its name: in each session the mount's compliance grows by
    #: ``c0 x value`` (``{"height_m": c0}``: a column bends more the higher the arm sits; truth.campaign.measure),
    #: or by ``f(value)`` for a function (a telescoping column's give grows faster than its length)
    mount_law: dict[str, float | Callable] = field(default_factory=dict)
    #: m by (joint, "x" | "y"): a linear axis' carriage off its straight line, a function of its position (m)
    straightness: dict[tuple[int, str], Callable] = field(default_factory=dict)
    #: rad by (joint, "roll" | "pitch" | "yaw"): its carriage's turn, a function of its position (m)
    carriage_angle: dict[tuple[int, str], Callable] = field(default_factory=dict)


@dataclass
class Geometry:
    """True values of every row's parameters, the tool point and the loop's lengths."""

    alpha: np.ndarray
    a: np.ndarray
    beta: np.ndarray
    b: np.ndarray
    d: np.ndarray
    theta: np.ndarray
    tool: np.ndarray
    loop: np.ndarray | None = None      # crank, coupler, rocker

    @classmethod
    def nominal(cls, arm: Arm) -> "Geometry":
        L = arm.links
        return cls(*(np.array([getattr(k, f) or 0.0 for k in L]) for f in ("alpha", "a", "beta", "b", "d", "theta")),
                   tool=arm.tool.copy(),
                   loop=None if arm.loop is None else np.array([arm.loop.crank, arm.loop.coupler, arm.loop.rocker]))


@dataclass
class State:
    """The arm at a batch of poses: drive angles, chain angles, frames (robot base frame), torques."""

    drive: np.ndarray          # (N, n) rad
    chain: np.ndarray          # (N, n) rad
    links: np.ndarray          # (N, n, 4, 4) link frames
    axes: np.ndarray           # (N, n, 3) joint axes
    origins: np.ndarray        # (N, n, 3) a point on each axis
    flange: np.ndarray         # (N, 4, 4) last link frame
    torque: np.ndarray         # (N, n) gravity torque about each joint's axis (chain)
    drive_torque: np.ndarray   # (N, n) what each drive carries
    moment: np.ndarray | None = None   # (N, 3) moment of every weight about the base frame's origin (N m)
    tilt: np.ndarray | None = None     # (N, 3) rotation vector of the base on its mount (rad), None: none
    axis_frames: np.ndarray | None = None   # (N, n, 3, 3) each joint's axis frame (z its axis, before it turns)
    bearing: np.ndarray | None = None  # (N, n, 3) each joint's tilt on its bearing, axis frame (rad)


def last_moves(q: np.ndarray) -> np.ndarray:
    """Sign of each joint's last change of reading before each row, in row order (0 before its first)."""
    out = np.zeros_like(q)
    for i in range(1, len(q)):
        step = np.sign(q[i] - q[i - 1])
        out[i] = np.where(step != 0, step, out[i - 1])
    return out


class TrueRobot:
    """An arm with its true geometry and effects; :meth:`state` gives its flange at any readings."""

    def __init__(self, arm: Arm, geometry: Geometry | None = None, effects: Effects | None = None):
        self.arm = arm
        self.geometry = geometry or Geometry.nominal(arm)
        self.effects = effects or Effects()

    @classmethod
    def draw(cls, arm: Arm, effects: Effects | None, rng: np.random.Generator,
             length_sigma: float = 0.5e-3, angle_sigma: float = math.radians(0.05)) -> "TrueRobot":
        """Nominal geometry plus random errors of every parameter the robot file models (beta, b only where it
        has them), the tool point included."""
        g = Geometry.nominal(arm)
        n = arm.n
        modelled = {"beta": np.array([k.beta is not None for k in arm.links]),
                    "b": np.array([k.b is not None for k in arm.links])}
        new = {}
        for name in ("alpha", "a", "beta", "b", "d", "theta"):
            sigma = angle_sigma if name in ("alpha", "beta", "theta") else length_sigma
            dev = rng.normal(0.0, sigma, n) * modelled.get(name, np.ones(n, bool))
            new[name] = getattr(g, name) + dev
        tool = g.tool + rng.normal(0.0, length_sigma, 3)
        loop = None if g.loop is None else g.loop + rng.normal(0.0, length_sigma, 3)
        return cls(arm, Geometry(**new, tool=tool, loop=loop), effects)

    def with_effects(self, effects: Effects) -> "TrueRobot":
        return TrueRobot(self.arm, self.geometry, effects)

    # --- geometry at a temperature ------------------------------------------------------

    def geometry_at(self, temperature: np.ndarray | None, N: int) -> dict[str, np.ndarray]:
        """Per-pose row values (N, n) and tool (N, 3) and loop (N, 3): thermal growth applied."""
        g, e, n = self.geometry, self.effects, self.arm.n
        out = {k: np.tile(getattr(g, k), (N, 1)) for k in ("alpha", "a", "beta", "b", "d", "theta")}
        out["tool"] = np.tile(g.tool, (N, 1))
        out["loop"] = None if g.loop is None else np.tile(g.loop, (N, 1))
        if temperature is None or not (e.thermal_alpha or e.thermal_links):
            return out
        dT = np.asarray(temperature, float) - e.t_ref
        grow = (1 + e.thermal_alpha * dT)[:, None]
        per_row = np.column_stack([1 + e.thermal_links.get(j, 0.0) * dT for j in range(1, n + 1)])
        for k in ("a", "b", "d"):
            out[k] = out[k] * grow * per_row
        out["tool"] = out["tool"] * grow
        if out["loop"] is not None:
            out["loop"] = out["loop"] * grow
        return out

    # --- chain angles from drive angles ---------------------------------------------------

    def chain_angles(self, m: np.ndarray, geo: dict) -> np.ndarray:
        """Chain angles (N, n) of drive angles ``m`` (N, n): couplings and the loop."""
        arm = self.arm
        out = m.copy()
        for i, link in enumerate(arm.links):
            if link.coupling is not None:
                out[:, i] = m @ link.coupling + link.coupling_offset
        if arm.loop is not None:
            i = arm.loop.joint - 1
            link_dir = out[:, i - 1] + geo["theta"][:, i - 1]
            ground = geo["a"][:, i] if arm.convention == "mdh" else geo["a"][:, i - 1]
            crank, coupler, rocker = geo["loop"].T
            rocker_dir = four_bar(link_dir, m[:, i], ground, crank, coupler, rocker)
            out[:, i] = rocker_dir - link_dir + arm.links[i].coupling_offset
        return out

    def chain_jacobian(self, m: np.ndarray, geo: dict, h: float = 1e-7) -> np.ndarray:
        """d chain angles / d drive angles (N, n, n): the couplings' factors, the loop's row by central
        differences."""
        N, n = m.shape
        J = np.tile(np.eye(n), (N, 1, 1))
        for i, link in enumerate(self.arm.links):
            if link.coupling is not None:
                J[:, i, :] = link.coupling
        if self.arm.loop is not None:
            i = self.arm.loop.joint - 1
            for k in range(n):
                dm = np.zeros(n)
                dm[k] = h
                J[:, i, k] = (self.chain_angles(m + dm, geo)[:, i] - self.chain_angles(m - dm, geo)[:, i]) / (2 * h)
        return J

    # --- frames and torques ----------------------------------------------------------------

    def frames(self, chain: np.ndarray, geo: dict, payload: np.ndarray, bearing: np.ndarray | None = None) -> State:
        """The frames and torques at chain angles ``chain``; ``bearing`` (N, n, 3): each joint's tilt on its
        bearing (a rotation vector in its axis frame, before it turns)."""
        N, n = chain.shape
        arm = self.arm
        T = tf.eye(N)
        links, axes, origins, frames_of_axes = [], [], [], []
        for i in range(n):
            alpha, a, beta, b, d, theta = (geo[k][:, i] for k in ("alpha", "a", "beta", "b", "d", "theta"))
            linear = arm.links[i].prismatic
            if linear:      # a linear axis: the reading slides the link along z, theta is a constant turn
                turn, d = tf.rot("z", theta), d + chain[:, i]
            else:
                turn = tf.rot("z", chain[:, i] + theta)
            if i + 1 in self.effects.axis_tilt:       # the bearing wobbles: the link tips about its x axis
                ta, tb = self.effects.axis_tilt[i + 1]
                turn = tf.chain(turn, tf.rot("x", ta * np.sin(chain[:, i]) + tb * np.cos(chain[:, i])))
            slide = self.carriage(i + 1, chain[:, i]) if linear else []
            if bearing is not None and np.any(bearing[:, i]):     # the axis tips on its bearing, then turns
                tip = np.tile(np.eye(4), (N, 1, 1))
                tip[:, :3, :3] = tf.rotation_vector_to_matrix(bearing[:, i])
                turn = tf.chain(tip, turn)
            if arm.convention == "mdh":
                T = tf.chain(T, tf.rot("x", alpha), tf.trans(a), tf.rot("y", beta), tf.trans(0.0, b))
                axes.append(T[:, :3, 2])
                origins.append(T[:, :3, 3])
                frames_of_axes.append(T[:, :3, :3])
                T = tf.chain(T, turn, tf.trans(0.0, 0.0, d), *slide)
            else:
                axes.append(T[:, :3, 2])
                origins.append(T[:, :3, 3])
                frames_of_axes.append(T[:, :3, :3])
                T = tf.chain(T, turn, tf.trans(0.0, 0.0, d), *slide, tf.trans(a),
                             tf.rot("x", alpha), tf.rot("y", beta), tf.trans(0.0, b))
            links.append(T)
        links = np.stack(links, axis=1)
        axes, origins = np.stack(axes, axis=1), np.stack(origins, axis=1)
        # weights: each link's mass at its centre of mass, the payload at its own in the tool frame
        centres = [links[:, i, :3, :3] @ arm.links[i].com + links[:, i, :3, 3] for i in range(n)]
        tool_frame = tf.chain(T, tf.trans(*self.geometry.tool))
        centres.append(tool_frame[:, :3, :3] @ arm.payload_com + tool_frame[:, :3, 3])
        masses = [np.full(N, k.mass) for k in arm.links] + [np.asarray(payload, float)]
        torque = np.zeros((N, n))
        for i in range(n):
            moment = np.zeros((N, 3))
            for c, mass in zip(centres[i:], masses[i:]):
                weight = mass[:, None] * arm.gravity
                # a linear axis carries the force of the weights along it (N), a revolute one their moment
                moment += weight if arm.links[i].prismatic else np.cross(c - origins[:, i], weight)
            torque[:, i] = np.einsum("nk,nk->n", axes[:, i], moment)
        mount = np.zeros((N, 3))
        for c, mass in zip(centres, masses):
            mount += np.cross(c, mass[:, None] * arm.gravity)
        frames_of_axes = np.stack(frames_of_axes, axis=1)
        tips = np.zeros((N, n, 3))
        for j, (cx, cy) in self.effects.bearing_compliance.items():
            moment = np.zeros((N, 3))
            for c, mass in zip(centres[j - 1:], masses[j - 1:]):
                moment += np.cross(c - origins[:, j - 1], mass[:, None] * arm.gravity)
            local = np.einsum("nki,nk->ni", frames_of_axes[:, j - 1], moment)     # in the axis' frame
            tips[:, j - 1] = np.column_stack([cx * local[:, 0], cy * local[:, 1], np.zeros(N)])
        return State(np.zeros((N, n)), chain, links, axes, origins, T, torque, torque, mount,
                     axis_frames=frames_of_axes, bearing=tips)

    def carriage(self, j: int, p: np.ndarray) -> list:
        """The transforms of linear axis ``j``'s carriage off its travel at positions ``p`` (m): straightness,
        then pitch, yaw and roll (none where the truth has none)."""
        e = self.effects
        ex, ey = (e.straightness.get((j, k)) for k in ("x", "y"))
        zero = np.zeros_like(p)
        out = []
        if ex is not None or ey is not None:
            out.append(tf.trans(ex(p) if ex else zero, ey(p) if ey else zero, zero))
        for name, axis in (("pitch", "x"), ("yaw", "y"), ("roll", "z")):
            f = e.carriage_angle.get((j, name))
            if f is not None:
                out.append(tf.rot(axis, f(p)))
        return out

    # --- the drives ---------------------------------------------------------------------

    def reading_errors(self, q: np.ndarray, moves: np.ndarray) -> np.ndarray:
        """What each drive adds that depends on its reading and its motion: gear error, encoder scale, the
        motion side of backlash, any other function of the reading (rad, (N, n))."""
        e = np.zeros_like(q)
        eff = self.effects
        for j, h, A, phi in eff.periodic:      # cycles per turn; per metre on a linear axis
            per = 2 * np.pi if self.arm.links[j - 1].prismatic else 1.0
            e[:, j - 1] += A * np.sin(h * per * q[:, j - 1] + phi)
        for j, s in eff.encoder_scale.items():
            e[:, j - 1] += s * q[:, j - 1]
        for j, b in eff.backlash_motion.items():
            e[:, j - 1] -= b * moves[:, j - 1]
        for j, f in eff.reading_error.items():
            e[:, j - 1] += f(q[:, j - 1])
        for (j, k), c in eff.coupling.items():
            e[:, j - 1] += c * q[:, k - 1]
        for (j, k), f in eff.cross_error.items():
            e[:, j - 1] += f(q[:, k - 1])
        return e

    def load_errors(self, tau: np.ndarray) -> np.ndarray:
        """What each drive gives way under its torque ``tau`` (N m, (N, n)): compliance, progressive
        stiffness, the torque side of backlash (rad)."""
        e = np.zeros_like(tau)
        eff = self.effects
        for j, k in eff.stiffness.items():
            e[:, j - 1] += tau[:, j - 1] / k
        for j, k3 in eff.cubic.items():
            e[:, j - 1] += k3 * tau[:, j - 1] ** 3
        for j, b in eff.backlash.items():
            e[:, j - 1] += b * np.sign(tau[:, j - 1])
        for (j, k), kk in eff.cross_stiffness.items():
            e[:, j - 1] += tau[:, k - 1] / kk
        return e

    def state(self, q: np.ndarray, payload=None, temperature=None, moves: np.ndarray | None = None,
              iterations: int = 50, mount=None) -> State:
        """The arm at readings ``q`` (rad, (N, n)) in equilibrium under gravity.

        ``payload``: kg per pose (default the robot file's); ``temperature``: deg C per pose (default: the
        reference, no growth); ``moves``: the sign of each joint's last move (default: :func:`last_moves` of
        ``q`` in row order); ``mount``: the mount's compliance (as ``Effects.mount_compliance``; default the
        robot's).
        """
        q = np.atleast_2d(np.asarray(q, float))
        N = len(q)
        payload = np.broadcast_to(self.arm.payload if payload is None else np.asarray(payload, float), (N,))
        moves = last_moves(q) if moves is None else moves
        geo = self.geometry_at(None if temperature is None else np.broadcast_to(temperature, (N,)), N)
        base = q + self.reading_errors(q, moves)
        m = base
        tips = None     # the bearings' tilts: of the arm in equilibrium, found with the drives' deflections
        for _ in range(iterations):
            s = self.frames(self.chain_angles(m, geo), geo, payload, tips)
            J = self.chain_jacobian(m, geo)
            tau_drive = np.einsum("nij,ni->nj", J, s.torque)
            new = base + self.load_errors(tau_drive)
            new_tips = s.bearing if self.effects.bearing_compliance else None
            done = np.max(np.abs(new - m)) < 1e-15 and (new_tips is None or (
                tips is not None and np.max(np.abs(new_tips - tips)) < 1e-15))
            m, tips = new, new_tips
            if done:
                break
        s = self.frames(self.chain_angles(m, geo), geo, payload, tips)
        s = replace(s, drive=m, drive_torque=np.einsum("nij,ni->nj", self.chain_jacobian(m, geo), s.torque))
        return tilted(s, self.effects.mount_compliance if mount is None else mount)

    def tool_point(self, state: State, temperature=None, shift=np.zeros(3)) -> np.ndarray:
        """The measured point (robot base frame, (N, 3)): the tool point (grown with the temperature) plus the
        probe's ``shift`` (m, flange frame)."""
        N = len(state.flange)
        geo = self.geometry_at(None if temperature is None else np.broadcast_to(temperature, (N,)), N)
        p = geo["tool"] + shift
        return np.einsum("nij,nj->ni", state.flange[:, :3, :3], p) + state.flange[:, :3, 3]


def tilted(s: State, compliance) -> State:
    """``s`` with the base tilted on its mount: every frame turned about the base frame's origin by the rotation
    vector ``C M`` (or ``(Cx M_x, Cy M_y, 0)``); unchanged for a zero compliance."""
    C = np.broadcast_to(np.asarray(compliance, float), (2,)) if np.ndim(compliance) else None
    if C is None:
        if compliance == 0:
            return s
        theta = compliance * s.moment
    else:
        if not C.any():
            return s
        theta = np.column_stack([C[0] * s.moment[:, 0], C[1] * s.moment[:, 1], np.zeros(len(s.moment))])
    R = tf.rotation_vector_to_matrix(theta)
    links = s.links.copy()
    links[:, :, :3, :3] = np.einsum("nij,nkjl->nkil", R, s.links[:, :, :3, :3])
    links[:, :, :3, 3] = np.einsum("nij,nkj->nki", R, s.links[:, :, :3, 3])
    flange = s.flange.copy()
    flange[:, :3, :3] = R @ s.flange[:, :3, :3]
    flange[:, :3, 3] = np.einsum("nij,nj->ni", R, s.flange[:, :3, 3])
    return replace(s, links=links, flange=flange, axes=np.einsum("nij,nkj->nki", R, s.axes),
                   origins=np.einsum("nij,nkj->nki", R, s.origins), tilt=theta)


def four_bar(link_dir, crank_dir, ground, crank, coupler, rocker) -> np.ndarray:
    """Absolute direction of the rocker of a four-bar (plane angles, rad).

    Crank on axis A at angle ``crank_dir``; the rocker's axis B lies ``ground`` from A in direction
    ``link_dir``; the coupler joins the crank's tip C to the rocker's tip R. R is where the circle about B
    (radius ``rocker``) meets the circle about C (radius ``coupler``); of the two, the one whose direction
    is nearer the crank's (a parallelogram's rocker stays parallel to its crank).
    """
    C = np.stack([crank * np.cos(crank_dir), crank * np.sin(crank_dir)], -1)
    B = np.stack([ground * np.cos(link_dir), ground * np.sin(link_dir)], -1)
    v = C - B
    dist = np.linalg.norm(v, axis=-1)
    # along B->C by x, across by +-y: x^2 + y^2 = rocker^2, (dist - x)^2 + y^2 = coupler^2
    x = (rocker ** 2 - coupler ** 2 + dist ** 2) / (2 * dist)
    y = np.sqrt(np.maximum(rocker ** 2 - x ** 2, 0.0))
    u = v / dist[:, None]
    w = np.stack([-u[:, 1], u[:, 0]], -1)
    best = None
    for sgn in (1.0, -1.0):
        R = x[:, None] * u + sgn * y[:, None] * w
        ang = np.arctan2(R[:, 1], R[:, 0])
        off = np.abs(np.angle(np.exp(1j * (ang - crank_dir))))
        if best is None:
            best, best_off = ang, off
        else:
            best = np.where(off < best_off, ang, best)
    return best
