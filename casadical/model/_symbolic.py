"""The symbolic calibration model: robot + error terms -> CasADi Functions.

A :class:`Model` is built once (its size does not depend on the number of
poses); data enter as function inputs and batches are evaluated with
``casadi.Function.map``.

Inputs of every model function, per pose:

- ``q``: joint readings (rad), ``n``;
- ``p``: the full parameter vector (SI), in :attr:`Model.parameters` order;
- ``cov``: covariates (:attr:`Model.covariate_names`, e.g. payload, temperature);
- ``base0``: the reference base pose, 12 numbers (rotation row-major, then
  translation, metres); the ``base_*`` parameters are small deviations from
  it, so a tracker metres away at any rotation is no difficulty.

A full-pose model (term ``tool_orientation``, :attr:`Model.orientation`)
also gives the probe's rotation, from the same base composition as the
point; its ``pose_*`` Functions take the measured rotation ``Rm`` (9
numbers, row-major) after these, already turned by the reference mounting
R0 that the calibration keeps, so no Function depends on R0.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import CasadicalWarning, DataFileError, ModelError
from ..kinematics import (
    Geometry,
    base_pose_matrix,
    chain_angles,
    compose,
    forward,
    rpy_pose,
    small_pose,
    small_rotation,
)
from ..parameters import Parameters
from ..robot import Robot
from ..runtime._threads import evaluation_threads
from ..terms import REGISTRY, Context, ErrorTerm, SessionLocal, covariate_names, make_term
from ..terms._definitions import by_name
from ..terms._geometric import Geometric
from ..terms._sessions import SessionFrames
from ..terms._user import UserTerm
from . import _jitcache as jitcache
from ._batch import BLOCK_MIN, batch, mapped  # noqa: F401 (names the tests use)
from ._batch import Batch as _Batch
from ._batch import Blocks as _Blocks
from ._superset import Mapping
from ._superset import outputs as superset_outputs

#: batches of this many poses or more run compiled code, compiled once per machine and kept in the disk cache
#: (casadical.model._jitcache); smaller ones use it only if the cache has it. Measured on the UR10 kinematic model
#: (benchmarks/speed/bench_calibrate_cli.py): compiling costs ~1.2 s of CPU more than a run on the VM, once, and
#: saves ~0.55 s per later 200-pose calibration, so it pays from the third run
JIT_MIN_POSES = 100
#: a model's own functions that a fit evaluates once (its torques, their derivatives, the probe's rotation) are
#: compiled from this many poses, below it taken compiled only from the cache: on the VM they cost 1-3 ms for
#: 300 UR10 poses, 0.7-2 s for 200,000 (compiled 0.3-0.5 s), a compile 0.5-1 s per model, which would be one per
#: candidate the diagnosis tries
JIT_ONCE_MIN_POSES = 20_000
_EVALUATED_ONCE = frozenset({"tau", "tau_q_jac", "probe"})
_SPEC_ITEM = re.compile(r"^\s*([a-z_][a-z0-9_]*)\s*(?:\[([^\]]*)\])?\s*(?:@\s*([A-Za-z0-9_.-]+))?\s*$")


def parse_spec(spec: str, user_terms=()) -> list[ErrorTerm]:
    """Terms of a model specification such as ``kinematic+compliance[2,3]+periodic[2:1]``.

    ``user_terms``: the definitions of the causes of the user's own it may name (a terms file's,
    :class:`~casadical.terms._definitions.TermDefinition` objects or a dict of them by name).

    ``nominal`` (or ``base``) means the nominal geometry with only the base
    pose estimated. ``kinematic`` (alias ``geometric``) frees every
    geometric parameter. Per-joint terms take ``[j,...]``; ``periodic``
    takes ``[joint:harmonic,...]``. ``@session`` after a term makes it a
    term of that measurement session only (``drift@B``).
    """
    terms: list[ErrorTerm] = []
    for item in spec.split("+"):
        m = _SPEC_ITEM.match(item)
        if not m:
            raise ModelError(f"cannot read model item {item!r} in {spec!r}; "
                             "expected e.g. kinematic+compliance[2,3]+periodic[2:1]")
        name, args, session = m.group(1), m.group(2), m.group(3)
        if name in ("nominal", "base"):
            if session:
                raise ModelError(f"{item!r}: the base pose of each session is always estimated; drop @{session}")
            continue
        user = by_name(user_terms)
        if name in user and name not in REGISTRY:     # a cause of the user's own (casadical.terms._definitions)
            if args is not None:
                raise ModelError(f"{item!r}: the user term {name} acts where its terms file says; drop [{args}]")
            term = UserTerm(user[name])
            terms.append(SessionLocal(term, session) if session else term)
            continue
        if name not in REGISTRY:
            raise ModelError(f"unknown model item {name!r} in {spec!r}; known: nominal, "
                             + ", ".join(sorted(REGISTRY)) + (f"; user terms: {', '.join(sorted(user))}" if user
                                                              else " (a cause of your own: --terms FILE)"))
        kwargs: dict = {}
        if args is not None and args.strip():
            try:
                if hasattr(REGISTRY[name], "arguments"):     # a term that reads its own (warmup[600], periodic[2:1])
                    kwargs = REGISTRY[name].arguments(args)
                else:
                    kwargs["joints"] = [int(a) for a in args.split(",")]
            except ValueError as e:
                raise ModelError(f"cannot read the arguments of {item!r}: {e}") from e
        term = make_term(name, **kwargs)
        terms.append(SessionLocal(term, session) if session else term)
    return terms


def spec_of(terms: list[ErrorTerm], geometric_free: bool) -> str:
    """The specification of a model of ``terms`` (the geometric term, if among them, is the first part)."""
    return "+".join(["kinematic" if geometric_free else "nominal"]
                    + [t.spec() for t in terms if not isinstance(t, Geometric)])


def assemble_terms(terms: list[ErrorTerm], robot: Robot) -> list[ErrorTerm]:
    """The terms of a model, geometric first (the nominal geometry if none is given), each bound to ``robot``.

    Raises
    ------
    ModelError
        A term is given twice, or does not fit the robot.
    """
    geo = [t for t in terms if isinstance(t, Geometric)]
    frames = [t for t in terms if isinstance(t, SessionFrames)]   # right after the geometry: the base and tool
    out = (geo[:1] or [Geometric()]) + frames + [t for t in terms if not isinstance(t, (Geometric, SessionFrames))]
    seen = set()
    for t in out:
        if t.spec() in seen:
            raise ModelError(f"term {t.spec()} given twice")
        seen.add(t.spec())
        t.bind(robot)
    return out


@dataclass
class ExpressionSize:
    """Sizes of the symbolic expressions (for ``inspect``)."""

    n_parameters: int
    fk_instructions: int
    jacobian_instructions: int
    fk_nodes: int


class Model:
    """Robot plus error terms, as CasADi Functions of (q, p, cov, base0).

    Parameters
    ----------
    robot : Robot
    terms : list of ErrorTerm or str
        Terms beyond the geometric one, or a specification string
        (:func:`parse_spec`). The geometric term is always present; it is
        free only if listed (``kinematic``), otherwise only the base pose is.
    jit : bool, optional
        Evaluate through compiled machine code (system C compiler, kept in the
        disk cache of :mod:`casadical.model._jitcache`; 4-7x less CPU than the VM).
        A model the robot's superset expresses (:mod:`casadical.model._superset`:
        every term of the diagnosis, periodic errors and terms of one session
        too) is evaluated through the superset's compiled functions, compiled
        once per robot, sessions and machine (1-13 s); any other model
        compiles its own functions (0.2-3 s each). Default: for batches of
        ``JIT_MIN_POSES`` poses or more when a compiler is available, and for
        smaller batches when the cache already holds the functions. False:
        the model's own graph on CasADi's virtual machine.

    Notes
    -----
    On CasADi's virtual machine a batch of ``2 * BLOCK_MIN`` poses or more
    is evaluated in blocks side by side, one per evaluation thread
    (:func:`casadical.runtime._threads.evaluation_threads`); the results are the
    same bits. A model's batches share buffers: evaluate one model from one
    thread at a time.
    """

    def __init__(self, robot: Robot, terms: list[ErrorTerm] | str = "kinematic",
                 jit: bool | None = None, user_terms=()):
        if isinstance(terms, str):
            terms = parse_spec(terms, user_terms)
        self.robot = robot
        self.geometric_free = any(isinstance(t, Geometric) for t in terms)
        self.terms: list[ErrorTerm] = assemble_terms(terms, robot)
        items = [p for t in self.terms for p in t.parameters(robot)]
        self.parameters = Parameters(items)
        if not self.geometric_free:
            for p in self.parameters:
                if p.term == Geometric.name and p.group != "base":
                    p.fixed, p.reason = True, "nominal model"
        self.covariate_names: list[str] = covariate_names(self.terms)
        self.jit = jit
        self._base0: np.ndarray | None = None
        self._maps: dict = {}
        self._compiled: dict = {}
        self._quick: dict = {}      # (which, jit) -> the VM Function whose optimised code compiles in the background
        self._graphs: dict = {}
        self._fk: ca.Function | None = None
        self._fk_jac: ca.Function | None = None
        self._symbols: dict | None = None       # the symbolic model, built on first use (_sym)
        #: the model has the probe's orientation (a term turns the probe against the flange)
        self.orientation = any(type(t).tool_rotation is not ErrorTerm.tool_rotation for t in self.terms)
        # where the model is in its robot's superset (casadical.model._superset); None: its own graph evaluates it
        self._mapping = Mapping.of(self) if jit is not False else None

    # --- construction -------------------------------------------------------------

    @property
    def spec(self) -> str:
        """Specification string that rebuilds this model."""
        return spec_of(self.terms, self.geometric_free)

    @property
    def n_joints(self) -> int:
        return self.robot.n

    @property
    def _sym(self) -> dict:
        """The symbolic model (built on first use: a model the superset evaluates never needs its own graph, and
        building one costs 7 ms, paid by each of the 60-odd models a diagnosis tries)."""
        if self._symbols is None:
            self._build()
        return self._symbols

    def _build(self) -> None:
        robot = self.robot
        n, npar = robot.n, len(self.parameters)
        q = ca.SX.sym("q", n)
        p = ca.SX.sym("p", npar)
        c = ca.SX.sym("cov", len(self.covariate_names))
        b0 = ca.SX.sym("base0", 12)
        psym = {name: p[i] for i, name in enumerate(self.parameters.names)}
        csym = {name: c[i] for i, name in enumerate(self.covariate_names)}
        # joint errors are the drives' (terms/_base.py): added to the readings, then the couplings and the loop
        drives = getattr(self.terms[0], "drive_errors", True)
        ctx = Context(robot, q, psym, csym, drives=drives)
        geom = Geometry.nominal(robot)
        for t in self.terms:
            geom = t.geometry(ctx, geom)
        ctx.geom = geom
        offsets = [0] * n
        for t in self.terms:
            for j, off in t.joint_offsets(ctx).items():
                offsets[j - 1] = offsets[j - 1] + off
        drive = [q[i] + offsets[i] for i in range(n)]
        if drives:
            chain = chain_angles(robot, drive, geom)
        else:
            chain = [a + o for a, o in zip(chain_angles(robot, q, geom), offsets)]
        frames = forward(robot, chain, geom)
        R0, t0 = ca.reshape(b0[:9], 3, 3).T, b0[9:12]  # row-major input
        for t in self.terms:
            R0, t0 = t.reference(ctx, R0, t0)
        base = compose((R0, t0), rpy_pose(*geom.base))
        if geom.mount:      # a user term's change of the base, right after the estimated base pose
            base = compose(base, small_pose(*geom.mount))
        point, tool_rotation, to_measurement = frames.tool[1], frames.tool[0], base[0]
        tilts = [v for v in (t.base_tilt(ctx) for t in self.terms) if v is not None]
        if tilts:       # the base tilts on its mount: the whole arm turns about the base frame's origin
            tilt = small_rotation(sum(tilts[1:], tilts[0]))
            point, tool_rotation = ca.mtimes(tilt, point), ca.mtimes(tilt, tool_rotation)
            to_measurement = ca.mtimes(base[0], tilt)
        for t in self.terms:
            off = t.robot_frame_offset(ctx)
            if off is not None:
                point = point + off
        xyz = base[1] + ca.mtimes(base[0], point)
        ctx.point = xyz
        for t in self.terms:
            off = t.base_offset(ctx)
            if off is not None:
                xyz = xyz + off
        tau = ca.vertcat(*ctx.torques()) if robot.n else ca.SX.zeros(0)
        dq = ca.vertcat(*[ca.SX(o) if not isinstance(o, ca.SX) else o for o in offsets])
        flange = ca.mtimes(base[0], tool_rotation)  # flange (last link) rotation, measurement frame
        # full pose: the probe's rotation, from the same base composition as the point (the flange, every term,
        # times the probe's mounting); without the reference mounting R0, which the data carry (Model docstring)
        probe = flange
        for t in self.terms:
            r = t.tool_rotation(ctx)
            if r is not None:
                probe = ca.mtimes(probe, r)
        if (probe is not flange) != self.orientation:
            raise ModelError(f"model {self.spec}: its terms' tool rotations disagree with its graph's")
        self._symbols = {"q": q, "p": p, "c": c, "b0": b0, "xyz": xyz, "tau": tau, "dq": dq, "flange": flange,
                         "chain": chain, "drive": drive, "drives": drives, "geom": geom, "R": to_measurement,
                         "probe": probe, "checks": ctx.checks}

    def _graph(self, which: str) -> tuple:
        """``(inputs, outputs, broadcast inputs, summed outputs)`` of a per-pose Function, built on first use.

        Derivatives are what makes a model expensive to build: each is made
        only when a computation asks for it.
        """
        g = self._graphs.get(which)
        if g is not None:
            return g
        S = self._sym
        q, p, c, b0, xyz = S["q"], S["p"], S["c"], S["b0"], S["xyz"]
        ins = [q, p, c, b0]
        if which == "cost":
            # the loss of one pose, summed over poses by map's reduce_out: the pseudo-Huber loss (u2 / 2 when
            # delta = 0), see casadical.problem.RobustLoss; IPOPT's exact Hessian differentiates it
            y = ca.SX.sym("y", 3)
            delta = ca.SX.sym("delta")  # robust loss: 1 / (c sigma)^2, 0 for plain least squares
            r = xyz - y
            u2 = ca.dot(r, r)
            g = (ins + [y, delta], [u2 / (ca.sqrt(1 + delta * u2) + 1)], (1, 3, 5), (0,))
        elif which.startswith("pose_"):
            g = self._pose_graph(which)
        elif which == "probe":
            g = (ins, [S["probe"]], (1, 3), ())
        elif which == "fk":
            g = (ins, [xyz], (1, 3), ())
        elif which == "fk_jac_angles":
            # and the derivative w.r.t. a joint's angle offset (added to its reading, before the couplings; to
            # its chain angle in a legacy model): a joint-angle error term's column is this times the term's own
            # derivative (the diagnosis screens periodic errors so)
            A = ca.SX.sym("A", self.robot.n)
            angles = [A[i] for i in range(self.robot.n)]
            if S["drives"]:
                tool, at = forward(self.robot, chain_angles(self.robot, angles, S["geom"]), S["geom"]).tool[1], "drive"
            else:
                tool, at = forward(self.robot, angles, S["geom"]).tool[1], "chain"
            JA = ca.substitute(ca.mtimes(S["R"], ca.jacobian(tool, A)), A, ca.vertcat(*S[at]))
            g = (ins, [xyz, ca.densify(ca.jacobian(xyz, p)), ca.densify(JA)], (1, 3), ())
        elif which == "fk_jac":
            g = (ins, [xyz, ca.densify(ca.jacobian(xyz, p))], (1, 3), ())
        elif which in ("tau", "dq"):
            g = ([q, p, c], [S[which]], (1,), ())
        elif which == "tau_q_jac":  # the torques' change with the readings (casadical.stats._physics.first_order_sag)
            g = ([q, p, c], [S["tau"], ca.densify(ca.jacobian(S["tau"], q))], (1,), ())
        # joint-space derivatives for inverse problems (corrected joint targets): through every
        # term, since deflections and gear errors depend on q too
        elif which == "fk_q_jac":
            g = (ins, [xyz, ca.densify(ca.jacobian(xyz, q))], (1, 3), ())
        elif which == "flange":
            g = (ins, [S["flange"]], (1, 3), ())
        elif which == "flange_jac":
            g = (ins, [S["flange"], _angular_jacobian(S["flange"], q)], (1, 3), ())
        else:
            raise ModelError(f"no per-pose function {which!r}")
        self._graphs[which] = g
        return g

    def _pose_graph(self, which: str) -> tuple:
        """The full-pose per-pose Functions: position and orientation residuals (and their Jacobian), the loss.

        Extra inputs after ``(q, p, cov, base0)``: ``y`` (measured point, m; loss Functions only), ``Rm`` (9
        numbers, row-major: the measured probe rotation times the transpose of the reference mounting R0),
        then for the loss ``delta`` (robust loss) and ``k`` (m/rad: the orientation residual's weight
        relative to the position residual, the ratio of their noise scales).
        """
        if not self.orientation:
            raise ModelError(f"model {self.spec} has no probe orientation (term tool_orientation): no {which!r}")
        S = self._sym
        q, p, c, b0, xyz = S["q"], S["p"], S["c"], S["b0"], S["xyz"]
        ins = [q, p, c, b0]
        Rm = ca.SX.sym("Rm", 9)
        E = ca.mtimes(ca.reshape(Rm, 3, 3), S["probe"])     # reshape of a row-major matrix: its transpose
        # the rotation vector of E = Rm^T R_pred for small angles (exact to third order): vee of its skew part
        ro = 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])
        if which == "pose_fk":
            return ins + [Rm], [xyz, ro], (1, 3), ()
        if which == "pose_fk_jac":
            return (ins + [Rm], [xyz, ca.densify(ca.jacobian(xyz, p)), ro, ca.densify(ca.jacobian(ro, p))],
                    (1, 3), ())
        y = ca.SX.sym("y", 3)
        delta, k = ca.SX.sym("delta"), ca.SX.sym("k")
        # one pose's residual: position (m) and orientation (rad) in position units, |r_p|^2 + k^2 |r_o|^2 =
        # sp^2 (|r_p|^2 / sp^2 + |r_o|^2 / so^2) with k = sp / so; the pseudo-Huber loss on the sum
        r = ca.vertcat(xyz - y, k * ro)
        u2 = ca.dot(r, r)
        root = ca.sqrt(1 + delta * u2)
        cost = u2 / (root + 1)
        lsq = ins + [y, Rm, delta, k]
        if which == "pose_cost":
            return lsq, [cost], (1, 3, 6, 7), (0,)
        raise ModelError(f"no per-pose function {which!r}")

    @property
    def fk(self) -> ca.Function:
        """Tool point of one pose: ``fk(q, p, cov, base0) -> xyz``."""
        if self._fk is None:
            ins, outs, _, _ = self._graph("fk")
            self._fk = ca.Function("fk", ins, outs, ["q", "p", "cov", "base0"], ["xyz"])
        return self._fk

    @property
    def fk_jac(self) -> ca.Function:
        """Tool point and its Jacobian w.r.t. the parameters: ``fk_jac(q, p, cov, base0) -> (xyz, J)``."""
        if self._fk_jac is None:
            ins, outs, _, _ = self._graph("fk_jac")
            self._fk_jac = ca.Function("fk_jac", ins, outs, ["q", "p", "cov", "base0"], ["xyz", "J"])
        return self._fk_jac

    def expression_size(self) -> ExpressionSize:
        return ExpressionSize(len(self.parameters), self.fk.n_instructions(),
                              self.fk_jac.n_instructions(), self.fk.n_nodes())

    # --- numeric evaluation -------------------------------------------------------

    def _use_jit(self, N: int) -> bool | str:
        if self.jit is not None:
            return self.jit
        if not compiler_available():
            return False
        return True if N >= JIT_MIN_POSES else "cached"

    def per_pose_function(self, which: str, jit: bool | str = False) -> ca.Function:
        """One of the per-pose Functions (``fk``, ``fk_jac``, ``fk_jac_angles``, ``cost``, ``tau``, ``tau_q_jac``,
        ``dq``, ``fk_q_jac``, ``flange``, ``flange_jac``; full-pose models also ``probe``, ``pose_fk``,
        ``pose_fk_jac``, ``pose_cost``).

        ``jit``: False for CasADi's virtual machine; True for compiled code,
        from the disk cache (:mod:`casadical.model._jitcache`) or compiled now and
        stored there; ``"cached"`` for compiled code if the cache has it,
        else the virtual machine.
        """
        key = (which, jit)
        fun = self._compiled.get(key)
        if fun is None and jit == "cached":
            key = (which, True)
            fun = self._compiled.get(key)
        if fun is not None and key in self._quick:     # compiled quickly: the optimised code once it is ready
            better = jitcache.upgraded(self._quick[key])
            if better is not None or not jitcache.pending(self._quick[key]):
                del self._quick[key]
            if better is not None:
                fun = self._compiled[key] = better
        if fun is None:
            ins, outs, _, _ = self._graph(which)
            fun = ca.Function(which, ins, outs)
            if jit:
                try:
                    vm = fun
                    # compiled now: quickly, optimised in the background where a core is free (jitcache)
                    fun = jitcache.load_all([vm], compile=jit is True, quick=jitcache.spare_core())[0] or vm
                    if jitcache.pending(vm):
                        self._quick[key] = vm
                except jitcache.CompileError as e:
                    # a broken compiler must not stop a calibration: the VM gives the same numbers
                    warnings.warn(f"JIT compilation failed, using CasADi's virtual machine ({str(e)[-200:]})",
                                  CasadicalWarning, stacklevel=3)
                    self.jit = False
            self._compiled[(which, jit)] = fun
        return fun

    def batch_function(self, which: str, N: int, compiled: bool | None = None) -> ca.Function:
        """``which`` mapped over N poses: parameters and base0 broadcast, sums reduced.

        ``compiled=False`` keeps CasADi's own expression graph, whose derivatives CasADi can take (a
        compiled library has none); default: compiled for large batches.
        """
        _, _, bcast, reduce = self._graph(which)
        fun = self.per_pose_function(which, self._use_jit(N) if compiled is None else compiled)
        return mapped(fun, N, bcast, reduce)

    def _batch(self, which: str, N: int) -> "_Batch | _Blocks":
        jit = self._use_jit(N)
        if jit is True and which in _EVALUATED_ONCE and N < JIT_ONCE_MIN_POSES:
            jit = "cached"
        fun = self.per_pose_function(which, jit)
        compiled = fun.class_name() == "External"
        # compiled: which code (the quick compile gives way to the optimised one, jitcache)
        key = (which, N, jit, id(fun) if compiled else evaluation_threads())
        b = self._maps.get(key)
        if b is None:
            if len(self._maps) > 32:  # many distinct batch sizes: keep memory bounded
                self._maps.clear()
            if compiled:
                b = _Batch(self.batch_function(which, N), N)
            else:
                b = batch(lambda n: self.batch_function(which, n, compiled=jit), N, self._graph(which)[2], False)
            self._maps[key] = b
        return b

    def _inputs(self, q, params, cov, base0):
        q = np.atleast_2d(np.asarray(q, dtype=float))
        N = q.shape[0]
        if q.ndim != 2 or q.shape[1] != self.robot.n:
            raise ModelError(f"expected {self.robot.n} joint values per pose, got shape {q.shape}")
        p = self.parameters.values if params is None else np.asarray(params, dtype=float)
        if p.shape != (len(self.parameters),):
            raise ModelError(f"expected {len(self.parameters)} parameter values, got shape {p.shape}")
        if cov is None:
            cov = self.default_covariates(N)
        cov = np.asarray(cov, dtype=float).reshape(N, len(self.covariate_names))
        b0 = self.base0_nominal() if base0 is None else np.asarray(base0, dtype=float)
        return N, q, p, cov, b0

    def _superset(self, which: str, N: int, q, p, cov, b0, Rm=None, angles: bool = False, columns=None):
        """``which`` of N poses through the robot's superset (:func:`casadical.model._superset.outputs`), or None when
        the model's own graph evaluates it: ``jit=False``, no compiler, a model the superset cannot express, or
        a batch below ``JIT_MIN_POSES`` while nothing of the superset is compiled."""
        if self._mapping is None or not (jitcache.compiler() if self.jit is True else compiler_available()):
            return None
        return superset_outputs(self, which, q, p, cov, b0, Rm, compile=self.jit is True or N >= JIT_MIN_POSES,
                                required=False, angles=angles, columns=columns)

    def predict(self, q, params=None, cov=None, base0=None) -> np.ndarray:
        """Tool point positions (m), shape (N, 3), for readings ``q`` (rad, (N, n))."""
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        out = self._superset("fk", N, q, p, cov, b0)
        if out is not None:
            return out[:, :3]
        return self._batch("fk", N)(q, p, cov, b0)[0]

    def predict_jacobian(self, q, params=None, cov=None, base0=None, columns=None
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, 3) and their Jacobian w.r.t. the full parameter vector (N, 3, P), or with ``columns``
        (parameter indices) w.r.t. those alone (N, 3, len(columns)): the same numbers, fewer copied."""
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        out = self._superset("jac", N, q, p, cov, b0, columns=columns)
        if out is not None:
            return out[0][:, :3], out[1][:, :3]
        xyz, J = self._batch("fk_jac", N)(q, p, cov, b0)
        # CasADi is column-major: each pose's 3 x P block arrives transposed
        J = J.reshape(N, len(self.parameters), 3).transpose(0, 2, 1)
        return xyz, (J if columns is None else J[:, :, columns])

    def predict_angle_jacobian(self, q, params=None, cov=None, base0=None
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (N, 3), their Jacobian w.r.t. the parameters (N, 3, P) and w.r.t. each joint's angle offset
        (N, 3, n): an offset of its reading, through the couplings (the chain angle, in a legacy model)."""
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        out = self._superset("jac", N, q, p, cov, b0, angles=True)
        if out is not None:
            return out[0][:, :3], out[1][:, :3], out[2][:, :3]
        xyz, J, JA = self._batch("fk_jac_angles", N)(q, p, cov, b0)
        return (xyz, J.reshape(N, len(self.parameters), 3).transpose(0, 2, 1),
                JA.reshape(N, self.robot.n, 3).transpose(0, 2, 1))

    def predict_q_jacobian(self, q, params=None, cov=None, base0=None) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, 3) and their Jacobian w.r.t. the joint readings (N, 3, n), exact by AD."""
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        xyz, J = self._batch("fk_q_jac", N)(q, p, cov, b0)
        return xyz, J.reshape(N, self.robot.n, 3).transpose(0, 2, 1)

    def flange_rotation(self, q, params=None, cov=None, base0=None) -> np.ndarray:
        """Rotation of the last link frame in the measurement frame (N, 3, 3), every term included."""
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        return self._batch("flange", N)(q, p, cov, b0)[0].reshape(N, 3, 3).transpose(0, 2, 1)

    def flange_rotation_jacobian(self, q, params=None, cov=None, base0=None) -> tuple[np.ndarray, np.ndarray]:
        """Flange rotation (N, 3, 3) and its angular-velocity Jacobian (N, 3, n), measurement frame.

        Column k is the rotation rate vector w with dR/dq_k = [w]x R.
        """
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        R, Jw = self._batch("flange_jac", N)(q, p, cov, b0)
        return (R.reshape(N, 3, 3).transpose(0, 2, 1),
                Jw.reshape(N, self.robot.n, 3).transpose(0, 2, 1))

    def probe_rotation(self, q, params=None, cov=None, base0=None) -> np.ndarray:
        """Rotation of the probe in the measurement frame without its reference mounting R0 (N, 3, 3).

        Base rotation x flange rotation (every term) x the mounting deviation
        (``tool_roll, tool_pitch, tool_yaw``); times R0 (kept with the
        calibration: :meth:`CalibrationResult.predict_rotations`) it is the
        probe's orientation. Full-pose models only.
        """
        if not self.orientation:
            raise ModelError(f"model {self.spec} has no probe orientation (term tool_orientation)")
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        R = self._superset("probe", N, q, p, cov, b0)
        if R is None:
            R = self._batch("probe", N)(q, p, cov, b0)[0]
        return R.reshape(N, 3, 3).transpose(0, 2, 1)

    def pose_residuals(self, q, Rm, params=None, cov=None, base0=None) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, 3) and orientation residuals (N, 3, rad) against ``Rm`` (N, 3, 3).

        ``Rm``: measured probe rotations times the transpose of the reference
        mounting R0. The residual is the rotation vector of ``Rm^T R``
        (``R``: :meth:`probe_rotation`) for small angles, the vector of its
        skew-symmetric part. Full-pose models only.
        """
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        Rm = np.asarray(Rm, float).reshape(N, 9)
        if not self.orientation:
            raise ModelError(f"model {self.spec} has no probe orientation (term tool_orientation): no 'pose_fk'")
        out = self._superset("pose_fk", N, q, p, cov, b0, Rm)
        if out is not None:
            return out[:, :3], out[:, 3:]
        xyz, ro = self._batch("pose_fk", N)(q, p, cov, b0, Rm)
        return xyz, ro

    def pose_jacobian(self, q, Rm, params=None, cov=None, base0=None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`pose_residuals` and their Jacobians w.r.t. the parameters: xyz, J (N, 3, P), r_o, J_o (N, 3, P)."""
        N, q, p, cov, b0 = self._inputs(q, params, cov, base0)
        Rm = np.asarray(Rm, float).reshape(N, 9)
        if not self.orientation:
            raise ModelError(f"model {self.spec} has no probe orientation (term tool_orientation): no "
                             "'pose_fk_jac'")
        out = self._superset("pose_jac", N, q, p, cov, b0, Rm)
        if out is not None:
            y, J, _ = out
            return y[:, :3], J[:, :3], y[:, 3:], J[:, 3:]
        xyz, J, ro, Jo = self._batch("pose_fk_jac", N)(q, p, cov, b0, Rm)
        P = len(self.parameters)
        return (xyz, J.reshape(N, P, 3).transpose(0, 2, 1), ro, Jo.reshape(N, P, 3).transpose(0, 2, 1))

    def torques(self, q, params=None, cov=None) -> np.ndarray:
        """Gravity torques (N m) that every joint's drive carries, shape (N, n)
        (:func:`~casadical.kinematics.drive_torques`)."""
        N, q, p, cov, _ = self._inputs(q, params, cov, None)
        return self._batch("tau", N)(q, p, cov)[0]

    def torque_jacobian(self, q, params=None, cov=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`torques` (N, n) and their derivatives w.r.t. the joint readings (N, n, n): ``[k, i, j]`` is
        d tau_i / d q_j at pose k."""
        N, q, p, cov, _ = self._inputs(q, params, cov, None)
        tau, J = self._batch("tau_q_jac", N)(q, p, cov)
        return tau, J.reshape(N, self.robot.n, self.robot.n).transpose(0, 2, 1)

    def joint_offsets(self, q, params=None, cov=None) -> np.ndarray:
        """Sum of the terms' joint-angle offsets (rad), shape (N, n)."""
        N, q, p, cov, _ = self._inputs(q, params, cov, None)
        return self._batch("dq", N)(q, p, cov)[0]

    # --- defaults -----------------------------------------------------------------

    def base0_nominal(self) -> np.ndarray:
        """The robot file's base pose as the 12-number ``base0`` input."""
        if self._base0 is None:
            self._base0 = pose_to_base0(base_pose_matrix(self.robot.base_xyz, self.robot.base_rpy))
        return self._base0

    def default_covariates(self, N: int) -> np.ndarray:
        """Covariates when the data give none: robot payload, reference temperature, ..."""
        cols = []
        for name in self.covariate_names:
            if name == "payload_kg":
                cols.append(np.full(N, self.robot.payload_mass))
            elif name in ("temperature_c", "time_s"):
                # at the reference of the term that reads it, the term has no effect (a user term's, read only
                # by user terms: not a number, which their check of the data names)
                owner = next((t for t in self.terms if name in t.covariates and not isinstance(
                    getattr(t, "inner", t), UserTerm)), None)
                cols.append(np.full(N, owner.t_ref if owner is not None else np.nan))
            else:
                cols.append(np.zeros(N))
        return np.column_stack(cols) if cols else np.zeros((N, 0))

    def covariates(self, data) -> np.ndarray:
        """Covariate matrix (N, n_cov) of a :class:`~casadical.data._measurements.Measurements`.

        Missing columns take defaults: the robot's payload, the thermal
        reference temperature; ``move<j>`` is the sign of joint j's last move
        in row order (0 for the first row). Time is never made up: a term
        driven by ``time_s`` (drift) needs the column.

        Raises
        ------
        DataFileError
            ``data`` lacks the ``time_s`` a term of the model needs.
        """
        N = len(data)
        out = self.default_covariates(N)
        for k, name in enumerate(self.covariate_names):
            col = data.get(name)
            if col is not None:
                out[:, k] = col
            elif name == "time_s":
                owner = next(t for t in self.terms if name in t.covariates)
                raise DataFileError(f"has no time_s column, which the {owner.spec()} term of the model needs (the "
                                    "time of each pose, in seconds); add it, or, if the rows are in time order at "
                                    "a known spacing, say so with --row-spacing-s SECONDS "
                                    "(Measurements.with_row_times)", file=data.path, row=1, column="time_s")
            elif name.startswith("move"):
                out[:, k] = data.moves[:, int(name[4:]) - 1]
        for t in self.terms:
            for name, values in t.covariate_values(data).items():
                out[:, self.covariate_names.index(name)] = values
        if self.user_terms:
            self.check_finite(data, out)
        return out

    @property
    def user_terms(self) -> list[UserTerm]:
        """The model's user terms (:mod:`casadical.terms._user`), of one session too."""
        return [t for t in (getattr(t, "inner", t) for t in self.terms) if isinstance(t, UserTerm)]

    def check_finite(self, data, cov: np.ndarray, params=None, base0=None) -> None:
        """Every user term's expression is a finite number at every pose of ``data`` (parameters: the model's
        values; base pose: the robot file's).

        Raises
        ------
        DataFileError
            Naming the file and row of the first pose where one is not, the term and its key.
        """
        checks = self._sym["checks"]
        if not checks:
            return
        S = self._sym
        f = ca.Function("user_checks", [S["q"], S["p"], S["c"], S["b0"]],
                        [ca.vertcat(*[ca.SX(v) if not isinstance(v, ca.SX) else v for _, _, v in checks])])
        N = len(data)
        p = self.parameters.values if params is None else np.asarray(params, dtype=float)
        b0 = self.base0_nominal() if base0 is None else base0
        values = np.asarray(f.map(N)(data.q.T, p, np.asarray(cov, dtype=float).T, b0)).T.reshape(N, len(checks))
        bad = ~np.isfinite(values)
        if bad.any():
            i, k = np.argwhere(bad)[0]
            term, key, _ = checks[k]
            raise DataFileError(f"user term {term.name!r}, key {key!r} ({term.definition.file}): the expression "
                                f"{term.text(key)!r} is {values[i, k]} at this pose, "
                                "not a finite number", file=data.file(i), row=data.line(i))

    @property
    def user_definitions(self) -> tuple:
        """The definitions of the causes of the user's own in the model (what a specification derived from its own
        needs to name them), one per term."""
        return tuple({t.definition.name: t.definition for t in self.user_terms}.values())

    def term(self, name: str) -> ErrorTerm | None:
        """The model's term called ``name`` (or alias), if any."""
        cls = REGISTRY.get(name)
        if cls is None:     # a user term, by its name
            return next((t for t in self.terms if isinstance(t, UserTerm) and t.name == name), None)
        return next((t for t in self.terms if isinstance(t, cls)), None)


def _angular_jacobian(R, q):
    """Columns w_k with dR/dq_k = [w_k]x R, i.e. the vector of the skew matrix dR/dq_k R^T."""
    dR = ca.jacobian(ca.vec(R), q)  # column-major vec(R)
    cols = []
    for k in range(q.shape[0]):
        S = ca.mtimes(ca.reshape(dR[:, k], 3, 3), R.T)
        cols.append(ca.vertcat(S[2, 1], S[0, 2], S[1, 0]))
    return ca.densify(ca.horzcat(*cols)) if cols else ca.SX.zeros(3, 0)


def pose_to_base0(T: np.ndarray) -> np.ndarray:
    """4x4 pose -> the 12-number ``base0`` input (rotation row-major, translation)."""
    return np.concatenate([T[:3, :3].ravel(), T[:3, 3]])


def base0_to_pose(b0: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.asarray(b0[:9]).reshape(3, 3)
    T[:3, 3] = b0[9:12]
    return T


def compiler_available() -> bool:
    """True if a C compiler is on PATH and ``CASADICAL_JIT=0`` does not turn automatic compilation off."""
    return jitcache.jit_setting() and jitcache.compiler() is not None
