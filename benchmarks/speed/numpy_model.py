"""A plain, vectorised numpy version of the ``kinematic+compliance`` model.

This is the honest baseline for the benchmarks: what one would write with
numpy alone to evaluate casadical's model for many poses at once, and its
Jacobian by forward finite differences. It follows docs/formats.md section 1 and
:mod:`casadical.kinematics` exactly:

- link transforms, ``mdh``: Rx(alpha) Tx(a) Ry(beta) Ty(b) Rz(q+theta) Tz(d);
  ``dh``: Rz(q+theta) Tz(d) Tx(a) Rx(alpha) Ry(beta) Ty(b); tool Tx Ty Tz;
- gravity torques of the undeflected configuration (links after joint i and
  the payload, each at its centre of mass), deflection ``c_j * tau_j`` added
  to joint j's angle, then the chain again;
- measured point = base0 * Trans(x, y, z) Rz(yaw) Ry(pitch) Rx(roll) * chain * tool,
  with ``base0`` the 12-number reference pose (rotation row-major, translation).

Everything broadcasts over poses *and* over parameter vectors: ``p`` of shape
(B, P) gives results of shape (B, N, 3), which is how the finite-difference
Jacobian evaluates all P perturbed parameter vectors in one batch.
Linear joint coupling is supported; four-bar loops are not (not needed for
the YS100 and UR10 used here).

Layout: a rotation is a list of its three columns, each a (3, B, N) array
(components first), so composing with an elementary rotation or translation
is a handful of elementwise products, with no small-matrix ``matmul``.
"""

from __future__ import annotations

import numpy as np

# A pose: (R, t); R = [col0, col1, col2], each (3, ...); t: (3, ...)


def _rotx(R, a):
    c, s = np.cos(a), np.sin(a)
    return [R[0], c * R[1] + s * R[2], c * R[2] - s * R[1]]


def _roty(R, a):
    c, s = np.cos(a), np.sin(a)
    return [c * R[0] - s * R[2], R[1], s * R[0] + c * R[2]]


def _rotz(R, a):
    c, s = np.cos(a), np.sin(a)
    return [c * R[0] + s * R[1], c * R[1] - s * R[0], R[2]]


def _move(R, t, x=None, y=None, z=None):
    """t + R @ (x, y, z); None components are structural zeros."""
    for k, v in ((0, x), (1, y), (2, z)):
        if v is not None:
            t = t + R[k] * v
    return t


def _cross(a, b):
    return np.stack([a[1] * b[2] - a[2] * b[1],
                     a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


class NumpyModel:
    """The ``kinematic+compliance`` model of ``robot`` in numpy.

    Parameters
    ----------
    robot : casadical.robot.Robot
    names : list of str
        Parameter names in the order of the full parameter vector (e.g.
        ``Model(robot, "kinematic+compliance").parameters.names``).
    scales : array, optional
        Typical parameter sizes (``[p.scale for p in model.parameters]``),
        used for the finite-difference steps.
    chunk : int
        Poses x parameter vectors evaluated per block (bounds memory and keeps
        the temporaries in cache).
    """

    def __init__(self, robot, names, scales=None, chunk: int = 4096):
        if robot.loop is not None:
            raise NotImplementedError("four-bar loops are not implemented in the numpy baseline")
        self.robot = robot
        self.names = list(names)
        self.P = len(self.names)
        self.idx = {nm: i for i, nm in enumerate(self.names)}
        self.scales = None if scales is None else np.asarray(scales, dtype=float)
        self.chunk = int(chunk)
        n = robot.n
        self.masses = np.array([j.mass for j in robot.joints])
        self.coms = np.array([j.com for j in robot.joints])  # (n, 3), link frames
        self.g = np.asarray(robot.gravity, dtype=float)
        self.coupling = None
        if any(j.coupling is not None for j in robot.joints):
            C = np.eye(n)
            off = np.zeros(n)
            for i, j in enumerate(robot.joints):
                if j.coupling is not None:
                    C[i] = j.coupling
                    off[i] = j.coupling_offset
            self.coupling = (C, off)
        self.compliant = [j for j in range(1, n + 1) if f"c{j}" in self.idx]

    # --- parameters --------------------------------------------------------------

    def _geom(self, p):
        """Geometry from p (B, P): a dict of (B, 1) columns, None = not modelled."""
        def col(name):
            i = self.idx.get(name)
            return None if i is None else p[:, i:i + 1]

        n = self.robot.n
        g = {k: [col(f"{k}{i}") for i in range(1, n + 1)]
             for k in ("alpha", "a", "beta", "b", "d", "theta", "c")}
        g["tool"] = [col(f"tool_{k}") for k in "xyz"]
        g["base"] = [col(f"base_{k}") for k in ("x", "y", "z", "roll", "pitch", "yaw")]
        return g

    # --- kinematics --------------------------------------------------------------

    def _chain(self, angles, geo, frames: bool):
        """Tool pose (and, if ``frames``, joint axes/origins and link poses)."""
        R = [np.eye(3)[:, k].reshape(3, 1, 1) for k in range(3)]
        t = np.zeros((3, 1, 1))
        axes, origins, links = [], [], []
        mdh = self.robot.convention == "mdh"
        for i in range(self.robot.n):
            th = angles[i] + geo["theta"][i]
            al, a, be, b, d = (geo[k][i] for k in ("alpha", "a", "beta", "b", "d"))
            if mdh:
                R = _rotx(R, al)
                t = _move(R, t, x=a)
                if be is not None:
                    R = _roty(R, be)
                t = _move(R, t, y=b)
                if frames:
                    axes.append(R[2])
                    origins.append(t)
                R = _rotz(R, th)
                t = _move(R, t, z=d)
            else:
                if frames:
                    axes.append(R[2])
                    origins.append(t)
                R = _rotz(R, th)
                t = _move(R, t, z=d)
                t = _move(R, t, x=a)
                R = _rotx(R, al)
                if be is not None:
                    R = _roty(R, be)
                t = _move(R, t, y=b)
            if frames:
                links.append((R, t))
        x, y, z = geo["tool"]
        t = _move(R, t, x, y, z)
        return (R, t), axes, origins, links

    def _torques(self, tool, axes, origins, links, payload):
        """Gravity torques (n arrays (B, N)): tau_i = z_i . (S_i - M_i o_i) x g,
        S_i = sum_{k >= i} m_k c_k (payload included), M_i the matching mass sum."""
        n = self.robot.n
        pc = self.robot.payload_com
        Rt, tt = tool
        S = payload * _move(Rt, tt, pc[0] or None, pc[1] or None, pc[2] or None)
        M = payload
        tau = [None] * n
        for i in range(n - 1, -1, -1):
            R, t = links[i]
            c = self.coms[i]
            S = S + self.masses[i] * _move(R, t, c[0] or None, c[1] or None, c[2] or None)
            M = M + self.masses[i]
            moment = _cross(S - M * origins[i], self.g[:, None, None])
            tau[i] = np.einsum("i...,i...->...", axes[i], moment)
        return tau

    def _eval(self, q, p, payload, base0):
        """Positions (B, N, 3) for q (N, n), p (B, P), payload (N,), base0 (12,)."""
        geo = self._geom(p)
        if self.coupling is not None:
            C, off = self.coupling
            qa = q @ C.T + off
        else:
            qa = q
        angles = [qa[:, i] for i in range(self.robot.n)]
        if self.compliant:
            tool, axes, origins, links = self._chain(angles, geo, frames=True)
            tau = self._torques(tool, axes, origins, links, payload)
            angles = [a + geo["c"][i] * tau[i] if geo["c"][i] is not None else a
                      for i, a in enumerate(angles)]
        (_, tp), _, _, _ = self._chain(angles, geo, frames=False)
        # base: base0 * Trans(x, y, z) Rz(yaw) Ry(pitch) Rx(roll)
        x, y, z, roll, pitch, yaw = geo["base"]
        R0 = np.asarray(base0[:9], dtype=float).reshape(3, 3)
        R = [np.broadcast_to(R0[:, k].reshape(3, 1, 1), (3, p.shape[0], 1)) for k in range(3)]
        tb = _move(R, np.asarray(base0[9:12], dtype=float).reshape(3, 1, 1), x, y, z)
        R = _rotx(_roty(_rotz(R, yaw), pitch), roll)
        xyz = tb + R[0] * tp[0] + R[1] * tp[1] + R[2] * tp[2]  # (3, B, N)
        return np.moveaxis(xyz, 0, -1)

    def _blocks(self, N, B):
        step = max(1, self.chunk // max(B, 1))
        return [(s, min(s + step, N)) for s in range(0, N, step)]

    def predict(self, q, p, payload=None, base0=None):
        """Tool point positions (N, 3) for q (N, n) rad and p (P,); with p (B, P): (B, N, 3)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        p = np.asarray(p, dtype=float)
        single = p.ndim == 1
        p2 = np.atleast_2d(p)
        N, B = q.shape[0], p2.shape[0]
        payload = self._payload(payload, N)
        base0 = self._base0(base0)
        out = np.empty((B, N, 3))
        for s, e in self._blocks(N, B):
            out[:, s:e] = self._eval(q[s:e], p2, payload[s:e], base0)
        return out[0] if single else out

    def predict_jacobian(self, q, p, payload=None, base0=None):
        """Positions (N, 3) and forward-difference Jacobian (N, 3, P).

        All P perturbed parameter vectors are evaluated at once (one batch of
        P + 1 parameter vectors). Step of parameter j:
        sqrt(eps) * max(|p_j|, 1e3 * scale_j).
        """
        p = np.asarray(p, dtype=float)
        typ = 1e3 * self.scales if self.scales is not None else np.ones(self.P)
        h = np.sqrt(np.finfo(float).eps) * np.maximum(np.abs(p), typ)
        pp = p + np.diag(h)
        h = pp.diagonal() - p  # the steps actually taken (exact in floating point)
        batch = np.vstack([p, pp])
        f = self.predict(q, batch, payload, base0)  # (P + 1, N, 3)
        J = (f[1:] - f[0]) / h[:, None, None]         # (P, N, 3)
        return f[0], J.transpose(1, 2, 0)

    # --- defaults ----------------------------------------------------------------

    def _payload(self, payload, N):
        if payload is None:
            return np.full(N, self.robot.payload_mass)
        return np.broadcast_to(np.asarray(payload, dtype=float).reshape(-1), (N,))

    def _base0(self, base0):
        if base0 is None:
            return np.concatenate([np.eye(3).ravel(), np.zeros(3)])
        return np.asarray(base0, dtype=float)


def check(robot_name: str = "ys100", N: int = 200, seed: int = 0, verbose: bool = True) -> dict:
    """Compare the numpy model with casadical at random poses and perturbed parameters.

    Returns the max position deviation (m) and the Jacobian deviations:
    ``jac_rel`` = max |J_np - J_ca| / max |J_ca| over all entries (SI units, so
    dominated by the large compliance columns), and ``jac_rel_scaled`` the same
    with every column times its parameter's scale (metres per typical
    deviation: all parameters weigh alike).
    """
    from casadical.kinematics import base_pose_matrix
    from casadical.loading import load_robot
    from casadical.model import Model, pose_to_base0

    robot = load_robot(robot_name)
    model = Model(robot, "kinematic+compliance", jit=False)
    rng = np.random.default_rng(seed)
    lim = robot.limits
    q = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((N, robot.n))
    p = model.parameters.values.copy()
    for i, par in enumerate(model.parameters):
        if par.term == "geometric":
            p[i] += 2.0 * par.scale * rng.standard_normal()
        else:  # compliance: a realistic, clearly visible deflection (~1 mrad)
            p[i] = 30.0 * par.scale * rng.random()
    payload = rng.uniform(0.0, 1.5 * robot.payload_mass, N)
    base0 = pose_to_base0(base_pose_matrix([2.5, -1.0, 0.4], np.radians([3.0, -5.0, 140.0])))
    cov = payload[:, None]
    nm = NumpyModel(robot, model.parameters.names, [x.scale for x in model.parameters])
    x_ca = model.predict(q, p, cov, base0)
    x_np = nm.predict(q, p, payload, base0)
    x_ca2, J_ca = model.predict_jacobian(q, p, cov, base0)
    x_np2, J_np = nm.predict_jacobian(q, p, payload, base0)
    sc = np.array([x.scale for x in model.parameters])
    dJ = np.abs(J_np - J_ca)
    res = {"robot": robot_name, "convention": robot.convention, "N": N,
           "fk_max_m": float(np.abs(x_np - x_ca).max()),
           "fk_jac_xyz_max_m": float(np.abs(x_np2 - x_ca2).max()),
           "jac_rel": float(dJ.max() / np.abs(J_ca).max()),
           "jac_rel_scaled": float((dJ * sc).max() / np.abs(J_ca * sc).max()),
           "deflection_max_rad": float(np.abs(model.joint_offsets(q, p, cov)).max())}
    if verbose:
        print(f"numpy vs casadical, {robot_name} ({robot.convention}), {N} random poses, "
              f"perturbed parameters (max deflection {res['deflection_max_rad'] * 1e3:.2f} mrad):")
        print(f"  FK max |dx|             = {res['fk_max_m']:.2e} m")
        print(f"  Jacobian max |dJ|/max|J| = {res['jac_rel']:.2e} (SI units), "
              f"{res['jac_rel_scaled']:.2e} (columns x parameter scale)")
    return res


if __name__ == "__main__":
    for name in ("ys100", "ur10"):
        check(name)
