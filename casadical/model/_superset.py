"""One compiled model per robot and sessions: every model the diagnosis tries is a mask of it (docs/speed.md).

The superset holds every term a model of the robot may have (:func:`superset_terms`) and a per-pose offset of
each chain angle. A model maps onto it once (:class:`Mapping`): its parameter values go into the superset's
vector (the terms it lacks at their zero effect), its covariates by name; a periodic error of any joint and
harmonic enters through the chain angle as ``s sin(h q_j) + c cos(h q_j)``, its columns the Jacobian w.r.t. that
offset times ``sin`` and ``cos`` (a joint coupling likewise, as ``c q_k``, its column that Jacobian times the
source joint's reading); a mount compliance is the superset's where the robot has masses; a term of one session
(``c2@B``) is its cause's term with the parameter per pose (``c2 + [pose in B] c2@B``: every such cause is
linear in its parameters, a mount's tilts add up), its column the cause's at that session's poses; a GP
compensator's Gaussian process (frozen) is evaluated in numpy and enters as an offset of the tool point before
the base pose. A model the superset cannot express (an RBF compensator's network in the graph, the legacy
backlash sign, a drift of the robot and of a session together) has no mapping and is evaluated on its own graph.

The superset's four functions (``fk``: the measured quantities; ``jac``: them and their Jacobian w.r.t.
the parameters and the chain offsets; ``pose_*``: with the orientation residual, full pose) are compiled
once per machine and kept in the disk cache (:mod:`casadical.model._jitcache`), when a batch of ``JIT_MIN_POSES``
poses or more first needs them (smaller batches use them only when compiled). CasADi's virtual machine gives
the same bits as the compiled code, so a failed compilation falls back to it without changing a result.
"""

from __future__ import annotations

import threading
import warnings
from collections import OrderedDict
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import CasadicalWarning
from ..runtime._kept import Kept, array_key
from ..runtime._threads import evaluation_threads
from ..terms import REGISTRY, ErrorTerm, SessionLocal, covariate_names, make_term
from ..terms._drift import Drift
from ..terms._joint_coupling import JointCoupling
from ..terms._periodic import JointPeriodic
from ..terms._thermal import ThermalExpansion
from . import _jitcache as jitcache
from ._batch import Batch, batch, mapped

#: the covariates of the tool point's offset in the robot's base frame (a compensator's prediction)
POINT_OFFSET = ("point_offset_x", "point_offset_y", "point_offset_z")
#: supersets kept per process (a robot and its sessions each; least recently used dropped first)
MAX_SUPERSETS = 8
#: poses evaluated at a time: the buffers of a batch stay small (a serial map holds one call's work memory per
#: pose) and one batch size serves any number of poses
BLOCK = 4096
#: the periodic columns' factors (Mapping.features) of this many sets of poses are kept, by the poses' bytes: a
#: fit evaluates its model at the same poses at every iteration, and the models of a diagnosis share columns
MAX_FEATURES = 8
_FEATURES = Kept(MAX_FEATURES)


class ChainOffsets(ErrorTerm):
    """A per-pose offset of each chain angle (covariates ``chain_offset<j>``): where a periodic error enters."""

    name = "chain_offsets"

    def __init__(self, n: int):
        super().__init__(None)
        self.n = n

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(chain_offset(j) for j in range(1, self.n + 1))

    def bind(self, robot) -> None:
        pass

    def spec(self) -> str:
        return self.name

    def joint_offsets(self, ctx) -> dict:
        return {j: ctx.cov[chain_offset(j)] for j in range(1, self.n + 1)}


def chain_offset(j: int) -> str:
    return f"chain_offset{j}"


class PointOffset(ErrorTerm):
    """A per-pose offset of the tool point in the robot's base frame (covariates ``point_offset_x/y/z``, m):
    where a frozen compensator's prediction enters (a GP compensator's Gaussian process, evaluated in
    numpy by :meth:`Mapping.inputs`, as the compensator's own graph adds it before the base pose)."""

    name = "point_offset"
    covariates = POINT_OFFSET

    def __init__(self):
        super().__init__(None)

    def bind(self, robot) -> None:
        pass

    def spec(self) -> str:
        return self.name

    def robot_frame_offset(self, ctx):
        return ca.vertcat(*[ctx.cov[c] for c in POINT_OFFSET])


#: the superset's optional groups of terms a model asks for unless it says (:attr:`ErrorTerm.superset_group`)
TORQUES = frozenset({"torques"})


def superset_terms(robot, frames=None, groups: frozenset = TORQUES) -> list[ErrorTerm]:
    """The terms of the superset of ``robot`` (with ``frames``, a sessions term: its sessions and tools; of the
    optional groups, ``groups``' only: without ``torques``, none that reads the gravity torques): the geometry,
    the sessions, each term kind's own in its :attr:`~casadical.terms._base.ErrorTerm.superset_order`
    (:meth:`~casadical.terms._base.ErrorTerm.superset`: a revolute joint's errors on the revolute joints, a linear
    axis' on the linear axes), the chain offsets and the point offset.

    Terms driven by a covariate against a reference (thermal expansion, drift) have the reference 0: a
    model's covariate comes minus its own reference, so no reference is a constant of the graph.
    """
    terms = [make_term("geometric")]
    if frames is not None:
        terms.append(make_term("sessions", names=frames.names, tools=frames.tools))
    kinds = sorted({cls for cls in REGISTRY.values() if cls.superset_order is not None
                    and (cls.superset_group is None or cls.superset_group in groups)},
                   key=lambda cls: cls.superset_order)
    terms += [t for cls in kinds for t in cls.superset(robot)]
    return terms + [ChainOffsets(robot.n), PointOffset()]


def frames_key(frames) -> tuple | None:
    return None if frames is None else (tuple(frames.names), tuple(frames.tools))


@dataclass
class _Column:
    """Where a model's parameter is in the superset: ``index`` (a parameter, or after them a chain offset);
    ``session``: the session whose indicator multiplies it; ``factor``: the model's covariate that multiplies it
    (a mount compliance's law); ``harmonic`` and ``kind`` ("s", "c"): a periodic error's; ``kind`` "q" and
    ``source``: a joint coupling's (a chain offset times the source joint's reading)."""

    index: int
    session: str | None = None
    harmonic: int = 0
    kind: str = ""
    source: int = 0
    factor: str | None = None


class Mapping:
    """A model as a mask of the superset: where its parameters, covariates and columns are.

    Built by :meth:`of` (None when the superset cannot express the model);
    the references of its thermal and drift terms are read then, as the
    model's own graph bakes them in when it is built.
    """

    def __init__(self, model, params: list, covariates: list[str], columns: list[_Column],
                 shifts: dict[str, list[tuple[str | None, float]]], groups: frozenset = TORQUES,
                 compensators: list | None = None):
        own = model.covariate_names
        self.groups = groups             # the superset's optional groups of terms it has (the torques')
        self.prismatic = model.robot.prismatic
        self.n_params = len(params)
        self.n_covariates = len(covariates)
        self.nominal = np.array([p.nominal for p in params])
        self.columns = columns
        # the model's covariates that are the superset's (by name); the chain offsets after the superset's own
        pairs = [(k, own.index(c)) for k, c in enumerate(covariates) if c in own]
        self.cov_to, self.cov_from = (np.array(x, dtype=int) for x in zip(*pairs))
        self.first_chain = covariates.index(chain_offset(1))
        self.first_point = covariates.index(POINT_OFFSET[0])
        #: each frozen process: its gate covariate, its session's indicator (-1: every pose) and the process
        self.compensators = [(own.index(gate), -1 if s is None else own.index(f"session@{s}"), gp)
                             for gate, s, gp in compensators or []]
        self.shifts = [(covariates.index(name), [(None if s is None else own.index(f"session@{s}"), ref)
                                                 for s, ref in refs]) for name, refs in shifts.items()]
        # the covariate that multiplies each column per pose: its session's indicator, or a law's factor (-1: none)
        self.at = np.array([own.index(c.factor) if c.factor is not None else -1 if c.session is None else
                            own.index(f"session@{c.session}") for c in columns])
        periodic = np.array([bool(c.kind) for c in columns], dtype=bool)
        self.shared = np.flatnonzero(~periodic & (self.at < 0))
        self.local = np.flatnonzero(~periodic & (self.at >= 0))
        self.periodic = np.flatnonzero(periodic)
        # the periodic columns side by side (features()): each one's reading (a coupling's source joint, a
        # harmonic's own), and of the harmonics their number, their factor (2 pi per metre on a linear axis) and
        # which is a sine
        per = [columns[i] for i in self.periodic]
        self._reading = np.array([c.source - 1 if c.kind == "q" else c.index - self.n_params for c in per], dtype=int)
        self._trig = np.array([c.kind != "q" for c in per], dtype=bool)
        trig = [c for c in per if c.kind != "q"]
        self._harmonic = np.array([float(c.harmonic) for c in trig])
        self._factor = np.array([2 * np.pi if self.prismatic[c.index - self.n_params] else 1.0 for c in trig])
        self._sine = np.array([c.kind == "s" for c in trig], dtype=bool)
        self._sines = np.flatnonzero(self._trig)[self._sine]
        self._cosines = np.flatnonzero(self._trig)[~self._sine]
        self._of_session = np.flatnonzero(self.at[self.periodic] >= 0)
        #: what the factors are made of, column by column: a key of the ones kept (models of one superset share it)
        self._signature = (tuple(self._reading), tuple(self._trig), tuple(self._harmonic), tuple(self._factor),
                           tuple(self._sine), tuple(self._of_session), tuple(self.at[self.periodic]))
        #: the parameters are per pose (a term of one session other than a periodic error)
        self.per_pose = bool(len(self.local))
        self.index = np.array([c.index for c in columns], dtype=int)

    @classmethod
    def of(cls, model) -> "Mapping | None":
        """The mapping of ``model`` onto its superset, or None if the superset cannot express it."""
        robot = model.robot
        groups = frozenset(g for g in ((t.inner if isinstance(t, SessionLocal) else t).superset_group
                                       for t in model.terms) if g is not None)
        sup = superset_terms(robot, model.term("sessions"), groups)
        params = [p for t in sup for p in t.parameters(robot)]
        index = {p.name: i for i, p in enumerate(params)}
        columns: list[_Column] = []
        drifts, thermal, compensators = [], set(), []
        for t in model.terms:
            inner, session = (t.inner, t.session_name) if isinstance(t, SessionLocal) else (t, None)
            if inner.name == "gp_compensator":    # frozen: no parameters, its prediction a point offset
                if inner.gp is not None:
                    gate, = inner.own_covariates
                    compensators.append((t.rename(gate) if session else gate, session, inner.gp))
                continue
            if not inner.superset_member() or (session is not None and not inner.session_local):
                return None
            if isinstance(inner, JointPeriodic):
                for j, h in inner.harmonics:
                    columns += [_Column(len(params) + j - 1, session, h, k) for k in "sc"]
                continue
            if isinstance(inner, JointCoupling):    # c q_k added to joint j's angle: through its chain offset
                columns += [_Column(len(params) + j - 1, session, kind="q", source=k) for j, k in inner.pairs]
                continue
            for name, factor in inner.superset_parameters(robot):
                if name not in index or (factor is not None and session is not None):
                    return None
                columns.append(_Column(index[name], session, factor=factor))
            if isinstance(inner, Drift):
                drifts.append((session, inner.t_ref))
            elif isinstance(inner, ThermalExpansion):
                thermal.add(inner.t_ref)
        if len(thermal) > 1 or (len(drifts) > 1 and any(s is None for s, _ in drifts)):
            return None     # two references of one covariate: not a mask of the superset
        shifts = {"time_s": drifts} if drifts else {}
        if thermal:
            shifts["temperature_c"] = [(None, thermal.pop())]
        return cls(model, params, covariate_names(sup), columns, shifts, groups, compensators)

    # -- inputs and outputs ------------------------------------------------------------

    def predictions(self, q: np.ndarray, cov: np.ndarray) -> list:
        """Each compensator's prediction (N, 3) at the poses where :meth:`inputs` adds it (its gate not 0; zeros
        elsewhere), for :meth:`inputs`' ``predictions``: asked at every pose of its session (of the data), the
        poses its gate was made at, where the process kept its answer (``ResidualGP._posterior``), not block by
        block nor only where its gate is not 0 (each a kernel of its own)."""
        out = []
        for gate, at, gp in self.compensators:
            pred = np.zeros((len(q), 3))
            rows = np.arange(len(q)) if at < 0 else np.flatnonzero(cov[:, at])
            if len(rows) and np.any(cov[rows, gate]):
                pred[rows] = gp.predict(q[rows])
            out.append(pred)
        return out

    def inputs(self, q: np.ndarray, values: np.ndarray, cov: np.ndarray, offsets: bool = True,
               predictions: list | None = None, features: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The superset's parameters (a vector, or one per pose) and covariates for the model's; without
        ``offsets``, the compensators' point offsets stay at zero (the probe's rotation: they do not turn it);
        ``predictions``: the compensators' at these poses (:meth:`predictions`), ``features`` the periodic
        columns' (:meth:`features`), else made here."""
        N = len(q)
        C = np.zeros((N, self.n_covariates))
        C[:, self.cov_to] = cov[:, self.cov_from]
        for k, refs in self.shifts:     # covariates against the model's references (a drift's: its session's)
            C[:, k] -= refs[0][1] if refs[0][0] is None else sum(cov[:, at] * ref for at, ref in refs)
        F = self.features(q, cov) if features is None else features
        for k, i in enumerate(self.periodic):
            C[:, self.first_chain + self.index[i] - self.n_params] += values[i] * F[:, k]
        if offsets and self.compensators:
            preds = self.predictions(q, cov) if predictions is None else predictions
            for (gate, at, _), pred in zip(self.compensators, preds):   # as the term: [its session] * gate * prediction
                g = cov[:, gate] if at < 0 else cov[:, at] * cov[:, gate]
                on = np.flatnonzero(g)
                C[on, self.first_point:self.first_point + 3] += g[on, None] * pred[on]
        p = self.nominal.copy()
        p[self.index[self.shared]] = values[self.shared]
        if not self.per_pose:
            return p, C
        P = np.repeat(p[None, :], N, axis=0)
        for i in self.local:
            P[:, self.index[i]] += cov[:, self.at[i]] * values[i]
        return P, C

    def features(self, q: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """The factor of each periodic column (N, len(periodic)): a coupling's source reading; the sine or cosine
        of a harmonic times its joint's reading (per metre on a linear axis: times 2 pi); times its session's
        indicator for a column of one session. All columns at once, each number by the arithmetic a column alone
        had (the same bits; a call per column cost more than its sine: 34,000 calls in the two-session job), and
        kept (:data:`MAX_FEATURES`): read them, never write to them."""
        if not len(self.periodic):
            return np.zeros((len(q), 0))
        ats = self.at[self.periodic[self._of_session]]
        q = np.ascontiguousarray(q)
        key = (self._signature, *array_key(q, cov[:, ats]))
        F = _FEATURES.get(key)
        if F is not None:
            return F
        F = q[:, self._reading]
        if len(self._harmonic):
            x = F[:, self._trig] * self._harmonic
            x *= self._factor
            F[:, self._sines] = np.sin(x[:, self._sine])
            F[:, self._cosines] = np.cos(x[:, ~self._sine])
        if len(self._of_session):
            F[:, self._of_session] *= cov[:, ats]
        F.flags.writeable = False
        _FEATURES.put(key, F)
        return F

    def jacobian(self, D: np.ndarray, q: np.ndarray, cov: np.ndarray, columns: np.ndarray | None = None,
                 features: np.ndarray | None = None) -> np.ndarray:
        """The model's Jacobian (N, m, P) from the superset's D (N, P_S + n, m); with ``columns`` (indices of the
        model's parameters) only theirs (N, m, len(columns)): a solver's free columns, without a copy of the rest;
        ``features``: :meth:`features` at these poses, made already."""
        cols = np.arange(len(self.index)) if columns is None else np.asarray(columns, dtype=int)
        sel = self.index[cols]
        if len(sel) and np.all(np.diff(sel) == 1):     # a run of the superset's columns (the usual): one copy,
            J = np.ascontiguousarray(D[:, sel[0]:sel[-1] + 1, :].transpose(0, 2, 1))   # in (N, m, P) order
        else:
            J = np.ascontiguousarray(D[:, sel, :].transpose(0, 2, 1))
        at = {int(i): k for k, i in enumerate(cols)}
        if any(int(i) in at for i in self.periodic):
            F = self.features(q, cov) if features is None else features
            for k, i in enumerate(self.periodic):
                if i in at:
                    J[:, :, at[i]] *= F[:, k, None]
        for i in self.local:
            if i in at:
                J[:, :, at[i]] *= cov[:, self.at[i], None]
        return J

    def angle_jacobian(self, D: np.ndarray) -> np.ndarray:
        """The Jacobian w.r.t. an offset of each chain angle (N, m, n)."""
        return D[:, self.n_params:, :].transpose(0, 2, 1)


class Superset:
    """The superset model of a robot and its sessions, and its functions (compiled, or on CasADi's VM).

    Parameters
    ----------
    build : callable
        ``build(terms)``: the symbolic model of those terms (a :class:`~casadical.model._symbolic.Model`
        on the VM: the superset never evaluates through itself).
    robot, frames
        The robot and its sessions term (or None).
    """

    def __init__(self, build, robot, frames=None, groups: frozenset = TORQUES):
        self.graph = build(superset_terms(robot, frames, groups))
        self.robot = robot
        self.n_params = len(self.graph.parameters)
        self._vm: dict[str, ca.Function] = {}
        self._compiled: dict[str, ca.Function] = {}
        self._checked: set[str] = set()          # looked up in the disk cache
        self._failed = False                      # the compiler failed: the VM from then on
        self._quick: set[str] = set()             # compiled quickly, the optimised code on its way (jitcache)
        self._quick_now = False                   # the compile under way is the quick one
        self._lock = threading.RLock()            # one evaluation at a time (the batches' buffers)
        self._batches: OrderedDict = OrderedDict()

    def function(self, which: str) -> ca.Function:
        """``which`` as a CasADi Function on the VM (built on first use)."""
        f = self._vm.get(which)
        if f is None:
            g = self.graph
            S = g._sym
            q, p, c, b0 = S["q"], S["p"], S["c"], S["b0"]
            dq = ca.vertcat(*[c[g.covariate_names.index(chain_offset(j))] for j in range(1, g.robot.n + 1)])
            ins, y = [q, p, c, b0], S["xyz"]
            if which == "probe":       # the probe's rotation (Model.probe_rotation): a model's start pose, and
                y = S["probe"]         # its orientation errors on the validation poses of every judge
            elif which.startswith("pose_"):
                Rm = ca.SX.sym("Rm", 9)
                E = ca.mtimes(ca.reshape(Rm, 3, 3), S["probe"])    # as Model's pose functions
                y = ca.vertcat(y, 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]))
                ins.append(Rm)
            outs = [y]
            if which.endswith("jac"):   # one Jacobian w.r.t. both: fewer instructions than two
                outs.append(ca.densify(ca.jacobian(y, ca.vertcat(p, dq))))
            f = self._vm[which] = ca.Function(f"superset_{which}", ins, outs)
        return f

    def _cached(self, which: str) -> ca.Function | None:
        """``which`` compiled: in this process, or from the disk cache (looked up once)."""
        with self._lock:
            if which not in self._compiled and which not in self._checked:
                self._checked.add(which)
                hit = jitcache.load(self.function(which), compile=False)
                if hit is not None:
                    self._compiled[which] = hit
            return self._compiled.get(which)

    def _sibling(self, which: str) -> str | None:
        """The full-pose function that gives ``which``'s outputs too (the same bits), if compiled in this process."""
        s = "pose_" + which
        return s if not which.startswith("pose_") and s in self._compiled else None

    def available(self, which: str) -> bool:
        """``which`` (or its full-pose sibling) is compiled: evaluating it compiles nothing."""
        return self._sibling(which) is not None or self._cached(which) is not None

    def resolve(self, which: str, compile: bool) -> tuple[ca.Function, str]:
        """The Function that evaluates ``which`` and which one it is: compiled (a position function's compiled
        full-pose sibling too; with ``compile``, compiled now with its kind's other function, side by side,
        and kept in the disk cache), else the VM's."""
        with self._lock:
            if which not in self._compiled and self._sibling(which):
                which = self._sibling(which)
            hit = self._cached(which)
            if hit is None and compile and not self._failed:
                kind = "pose_" if which.startswith("pose_") else ""
                group = (which,) if which == "probe" else (kind + "fk", kind + "jac")
                names = [w for w in group if w not in self._compiled]
                try:
                    # a first run does not wait for the optimised code: compiled quickly now, optimised in the
                    # background, taken below once ready (jitcache's module docstring)
                    funs = [self.function(w) for w in names]
                    self._quick_now = jitcache.spare_core()
                    done = jitcache.load_all(funs, before=self._announce, quick=self._quick_now)
                except jitcache.CompileError as e:
                    # a broken compiler must not stop a calibration: the VM gives the same numbers
                    warnings.warn(f"JIT compilation failed, using CasADi's virtual machine ({str(e)[-200:]})",
                                  CasadicalWarning, stacklevel=4)
                    self._failed = True
                else:
                    self._compiled.update(zip(names, done))
                    self._checked.update(names)
                    self._quick.update(w for w, f in zip(names, funs) if jitcache.pending(f))
                    hit = self._compiled[which]
            if which in self._quick:
                better = jitcache.upgraded(self.function(which))
                if better is not None or not jitcache.pending(self.function(which)):
                    self._quick.discard(which)
                if better is not None:
                    hit = self._compiled[which] = better
            return (hit, which) if hit is not None else (self.function(which), which)

    def _announce(self, funs: list[ca.Function]) -> None:
        """Say that the compiler starts (it takes seconds) to whoever listens (:func:`jitcache.announcing`)."""
        # about 0.1 ms of compiling an instruction at -O0 on one core (the quick compile a run waits for when a
        # core is free; -O1: 0.5 ms, in the background then, else and for a small function at once); side by
        # side, the longest counts
        seconds = max(1, round(max((1e-4 if self._quick_now and f.n_instructions() >= jitcache.QUICK_MIN_INSTRUCTIONS
                                    else 5e-4) * f.n_instructions() for f in funs)))
        jitcache.announce(f"compiling the model of {self.robot.name} for these data (about {seconds} s, more if the "
                          "run needs further parts; once: later runs load it from the cache)")

    def evaluate(self, which: str, N: int, inputs: list, per_pose: bool, take, compile: bool = True):
        """``take(outputs)`` of ``which`` on N poses (outputs: per pose, row-major, valid inside ``take``).

        ``inputs``: q, p (a vector, or one per pose with ``per_pose``), covariates, base0 and, for a
        ``pose_`` function, the measured rotations.
        """
        fun, used = self.resolve(which, compile)
        if used != which:       # the full-pose sibling: any rotation for the orientation it also gives
            inputs = list(inputs) + [np.tile(np.eye(3).ravel(), (N, 1))]
        compiled = fun.class_name() == "External"
        bcast = [3] if per_pose else [1, 3]
        # compiled: which code (the quick compile gives way to the optimised one, jitcache)
        key = (used, N, id(fun) if compiled else evaluation_threads(), per_pose)
        with self._lock:
            b = self._batches.get(key)
            if b is None:
                b = batch(lambda n: mapped(fun, n, bcast, []), N, bcast, compiled)
                self._batches[key] = b
                while len(self._batches) > 16:
                    self._batches.popitem(last=False)
            else:
                self._batches.move_to_end(key)
            if isinstance(b, Batch):
                b.evaluate(*inputs)
                res = b.res
            else:
                res = b(*inputs)
            m = 6 if used.startswith("pose_") else 9 if used == "probe" else 3
            return take([res[0].reshape(N, m)] + [r.reshape(N, -1, m) for r in res[1:]])


_SUPERSETS: OrderedDict = OrderedDict()
_registry = threading.Lock()



def superset_for(build, robot, frames=None, groups: frozenset = TORQUES) -> Superset:
    """The process's superset of ``robot`` and ``frames``' sessions, with its optional ``groups`` of terms (with or
    without those that read the gravity torques; built on first use)."""
    key = (id(robot), frames_key(frames), groups)
    with _registry:
        hit = _SUPERSETS.get(key)
        if hit is not None and hit.robot is robot:
            _SUPERSETS.move_to_end(key)
            return hit
    sup = Superset(build, robot, frames, groups)
    with _registry:
        _SUPERSETS[key] = sup
        while len(_SUPERSETS) > MAX_SUPERSETS:
            _SUPERSETS.popitem(last=False)
    return sup


def outputs(model, which: str, q, p, cov, b0, Rm=None, compile: bool = True, required: bool = True,
            angles: bool = True, columns: np.ndarray | None = None):
    """``which`` (``fk``, ``jac``, ``pose_fk``, ``pose_jac``, ``probe``) of a model's poses through its robot's
    superset.

    Returns the measured quantities (N, m) (positions, then for ``pose_`` the orientation residuals; for
    ``probe`` the probe's rotation, 9 numbers a pose, column by column) and, for
    ``jac``, their Jacobian w.r.t. the model's parameters (N, m, P) and w.r.t. an offset of each chain angle
    (N, m, n; None without ``angles``); with ``columns`` (indices of the model's parameters) the Jacobian of
    those alone (N, m, len(columns)). ``compile``: compile what is not compiled yet (kept in the disk cache),
    else the VM; without ``required``, None when ``compile`` is off and the function is not compiled (the
    model's own graph is then the cheaper VM function). Many poses are evaluated in blocks of ``BLOCK``.
    """
    m = model._mapping
    N = len(q)
    sup = superset_for(lambda terms: type(model)(model.robot, terms, jit=False), model.robot, model.term("sessions"),
                       m.groups)
    if not (required or compile or sup.available(which)):
        return None
    if model.orientation and which in ("fk", "jac"):   # a full-pose model: its data kind's functions
        which, Rm = "pose_" + which, np.tile(np.eye(3).ravel(), (N, 1))
    parts = []
    preds = m.predictions(q, cov) if m.compensators and which != "probe" else None
    for a in range(0, N, BLOCK):
        s = slice(a, min(a + BLOCK, N))
        qs, cs = q[s], cov[s]
        F = m.features(qs, cs)      # the periodic columns': inputs' and jacobian's
        P, C = m.inputs(qs, p, cs, offsets=which != "probe",
                        predictions=None if preds is None else [x[s] for x in preds], features=F)

        def take(out, qs=qs, cs=cs, F=F):
            if len(out) == 1:
                return (out[0].copy(),)
            return (out[0].copy(), m.jacobian(out[1], qs, cs, columns, F),
                    m.angle_jacobian(out[1]).copy() if angles else None)
        parts.append(sup.evaluate(which, len(qs), [qs, P, C, b0] + ([Rm[s]] if Rm is not None else []), m.per_pose,
                                  take, compile))
    out = tuple(None if parts[0][k] is None else np.concatenate([x[k] for x in parts]) if len(parts) > 1
                else parts[0][k] for k in range(len(parts[0])))
    return out[0] if len(out) == 1 else out
