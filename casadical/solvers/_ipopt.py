"""IPOPT through CasADi ``nlpsol``, with bounds (e.g. positive, bounded compliance).

The Hessian is the Gauss-Newton one of the (robust) loss (J^T J for plain
least squares): what the least squares structure offers for free, and
positive semi-definite. IPOPT's objective, gradient and Hessian are
callbacks on the problem's own linearisation
(:meth:`casadical.problem.CalibrationProblem.linearize`: the model's
Jacobian, ``J^T W J`` in numpy), the matrix Levenberg-Marquardt uses, so
both minimise the same objective (full pose too: each pose's residual is
``(r_p, k r_o)``); one linearisation per iterate serves the objective, the
gradient and the Hessian, and the trials of a backtracking line search
evaluate the loss alone (:meth:`~casadical.problem.CalibrationProblem.cost`).
The model is evaluated as every calibration evaluates it (compiled once per robot,
:mod:`casadical.model._superset`): no function is compiled per model, and a built
solver serves every problem with the same number of free parameters.

With ``hessian="exact"`` the objective is the mapped model Function with
the data as NLP parameters, and IPOPT takes CasADi's exact Hessian of it.
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..errors import SolverError
from ..problem import CalibrationProblem
from ..runtime._interrupts import checkpoint, noticed, wanted
from ._base import Solver, SolverResult

#: built solvers shared by every Ipopt instance of the process, least recently used dropped first: the
#: robust loop of a calibration, and a diagnosis calibrating many models, re-solve problems of the same
#: number of free parameters (the exact Hessian: of the same model, size and free set; building one costs
#: 0.05-0.5 s)
_BUILT: OrderedDict = OrderedDict()
MAX_BUILT = 4
#: consecutive iterations at IPOPT's acceptable level that end a solve (IPOPT's default: 15)
ACCEPTABLE_ITER = 5
#: IPOPT's acceptable level, in the units of ``tol`` (IPOPT's default, 1e-6: 100 times its default tol)
ACCEPTABLE_TOL = 1e-6
#: the objective IPOPT sees: the loss summed over the poses in mm^2 (the loss itself is in m^2)
OBJ_SCALE = 1e6
#: IPOPT's barrier_tol_factor (its default), per pose: each barrier problem is solved to this times mu
BARRIER_TOL_FACTOR = 10.0
#: a Newton step below this share of every parameter's typical size (relative to 1 + |x|, x in typical sizes)
#: is taken without a line search (IPOPT's tiny_step_tol; its default is 10 machine epsilons)
TINY_STEP = 1e-6
#: IPOPT's start from a Levenberg-Marquardt solution that left the bounds (``solver="auto"``): the problem is
#: solved but for the bounds, so a small barrier and a start at the bounds (YS100 kinematic+compliance, 80
#: poses, 6 seeds with 1-3 compliances below 0: 3-5 iterations instead of 10-16, the cost the same to 1e-8)
HANDOVER = {"mu_init": 1e-8, "bound_push": 1e-8, "bound_frac": 1e-8}
#: how IPOPT ends a solve that counts as converged ("Search_Direction_Becomes_Too_Small": two tiny steps in a
#: row with the barrier parameter at its floor, the best the rounding allows)
CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level", "Search_Direction_Becomes_Too_Small")


@dataclass
class Ipopt(Solver):
    """IPOPT with bounds on the parameters.

    Parameters
    ----------
    max_iter : int
    tol : float
        IPOPT's convergence tolerance, in mm^2 per pose: on the gradient
        of the loss per pose (its sum over the poses divided by their
        number, with respect to the scaled parameters), so that it means
        the same at any number of poses; and on the complementarity of the
        bounds of the summed loss, so that a parameter near its bound ends
        as close to it as before. Near the optimum the objective's rounding
        can hide the decrease of a step: a Newton step below ``TINY_STEP``
        (1e-6) of every parameter's typical size is taken without a line
        search, and a solve also ends after ``ACCEPTABLE_ITER`` (5)
        iterations in a row at IPOPT's acceptable level
        (``ACCEPTABLE_TOL``, 1e-6, in the same units). For a tighter
        ``tol`` to hold, pass ``options={"acceptable_iter": 15}`` or more.
    hessian : {"gauss-newton", "exact"}
    options : dict
        Further IPOPT options (``{"print_level": 5}`` to watch it).
    """

    max_iter: int = 200
    tol: float = 1e-8
    hessian: str = "gauss-newton"
    options: dict = field(default_factory=dict)
    name = "ipopt"
    _last: object = field(default=None, repr=False, compare=False)  # the solver of the last solve (its stats)

    def _options(self, N: int) -> dict:
        """IPOPT's options for N poses (the comments say why each is what it is)."""
        # The objective in mm^2 (OBJ_SCALE). No nlp_grad: it is only for the multipliers of the data
        # parameters.
        # Tests per pose (issue 21). IPOPT's tol, acceptable_tol and the tolerance of each barrier problem
        # (barrier_tol_factor * mu) bound the gradient of the objective, a sum over the N poses: a fixed bound
        # is N times tighter per pose at N poses. Near the optimum the last decreases it asks for fall below
        # the rounding of the summed objective, the line search backtracks 10-37 times per iteration, and only
        # IPOPT's watchdog, the acceptable rule or max_iter end it (YS100 kinematic fitted to a compliant arm,
        # from nominal: 6 iterations to the optimum, then 200,000 poses ran to max_iter, 2,677 objective
        # evaluations, 579 s). Per pose (times N on the sum) a test means the same at any N and stays far
        # above the rounding (300 real UR10 poses repeated 20 times take the iterations of the 300). The
        # complementarity keeps its test on the summed loss (compl_inf_tol is on the unscaled objective, m^2):
        # it sets the barrier parameter's floor, min(tol, compl_inf_tol in mm^2) / (barrier_tol_factor + 1),
        # and with it how close a parameter on its bound ends, as before.
        # Per pose the objective's rounding can still hide the decrease of the last Newton step where the
        # residuals are large (a misfit): on 2,000 poses of that arm (the ca-ys100 truth) the robust loop's
        # first solve reached 7e-8 mm^2 per pose in 4 iterations, then backtracked 20-26 times per iteration
        # for 5 more (138 objective evaluations). tiny_step_tol: a step below TINY_STEP of every parameter's
        # typical size cannot matter to a calibration, and IPOPT takes it unchecked (there: 5 iterations, 6
        # evaluations); two in a row at the barrier parameter's floor end the solve, converged.
        # acceptable_iter: 5 iterations in a row at IPOPT's acceptable level end a stall should one remain
        # (docs/benchmarks.md)
        return {"print_time": False, "no_nlp_grad": True, "calc_lam_p": False,
                "ipopt": {"print_level": 0, "sb": "yes", "max_iter": self.max_iter, "tol": self.tol * N,
                          "acceptable_tol": ACCEPTABLE_TOL * N, "compl_inf_tol": self.tol / OBJ_SCALE,
                          "acceptable_compl_inf_tol": ACCEPTABLE_TOL / OBJ_SCALE,
                          "barrier_tol_factor": BARRIER_TOL_FACTOR * N, "tiny_step_tol": TINY_STEP,
                          "acceptable_iter": ACCEPTABLE_ITER, "obj_scaling_factor": OBJ_SCALE, **self.options}}

    def _build(self, problem: CalibrationProblem):
        """The built solver and, for the Gauss-Newton Hessian, its callbacks' view of the problem."""
        if self.hessian == "exact":
            return self._build_exact(problem), None
        if self.hessian != "gauss-newton":
            raise SolverError(f"unknown Hessian option {self.hessian!r}: use 'gauss-newton' or 'exact'")
        N, nf = problem.n_poses, len(problem.free)
        # a built solver holds its callbacks' state: one per thread
        key = (nf, N, self.max_iter, self.tol, repr(sorted(self.options.items())), threading.get_ident())
        if key in _BUILT:
            _BUILT.move_to_end(key)
        else:
            at = _Iterates()
            cbs = [_Callback(kind, at, nf) for kind in ("f", "grad_f", "hess_l")]
            x, p = ca.MX.sym("x", nf), ca.MX.sym("p", 0)
            lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", 0)
            opts = self._options(N)
            # an exception in a callback (Ctrl-C, SIGTERM, an error) stops IPOPT at its next iteration, with no
            # warning for the NaN it sees until then; solve() raises it again (the iteration callback is also
            # where a test has the process signal itself)
            cbs.append(_Stop(at, nf))
            opts.update(iteration_callback=cbs[-1], show_eval_warnings=False)
            opts["grad_f"] = ca.Function("nlp_grad_f", [x, p], list(cbs[1](x)), ["x", "p"], ["f", "grad_f_x"])
            opts["hess_lag"] = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [cbs[2](x, lam_f)],
                                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
            solver = ca.nlpsol("calibration", "ipopt", {"x": x, "p": p, "f": cbs[0](x)}, opts)
            _BUILT[key] = (solver, at, cbs)       # the callbacks live as long as the solver that calls them
            while len(_BUILT) > MAX_BUILT:  # a few problem shapes at a time keep memory flat
                _BUILT.popitem(last=False)
        solver, at, _ = _BUILT[key]
        self._last = solver
        return solver, at

    def _build_exact(self, problem: CalibrationProblem):
        """IPOPT on the mapped model Function, the data as NLP parameters; CasADi's exact Hessian."""
        model = problem.model
        N, nf = problem.n_poses, len(problem.free)
        # holds the model (an id could be reused); jit: a solver built on the VM is not the compiled one
        pose = problem.full_pose
        at_iteration = wanted("solver")     # a test stops IPOPT while it iterates (CASADICAL_SIGNAL_AT)
        key = (model, N, tuple(problem.free), model._use_jit(N), self.hessian, self.max_iter, self.tol,
               repr(sorted(self.options.items())), pose, "exact", at_iteration)
        if key in _BUILT:
            _BUILT.move_to_end(key)
            self._last = _BUILT[key]
            return self._last
        P, nc = len(problem.params), len(model.covariate_names)
        x = ca.MX.sym("x", nf)
        # full pose: the measured rotations (9 per pose) and the orientation's weight k follow
        sizes = [model.n_joints * N, 3 * N, nc * N, 12, P, P, 1] + ([9 * N, 1] if pose else [])
        data = ca.MX.sym("data", sum(sizes))
        parts = ca.vertsplit(data, np.cumsum([0] + sizes).tolist())
        Q = ca.reshape(parts[0], model.n_joints, N)
        XYZ = ca.reshape(parts[1], 3, N)
        C = ca.reshape(parts[2], nc, N)
        base0, pfix, sel_scale, delta = parts[3], parts[4], parts[5], parts[6]
        # the per-pose loss Functions and their data inputs after (q, p, cov, base0)
        prefix, tail = ("pose_", [XYZ, ca.reshape(parts[7], 9, N), delta, parts[8]]) if pose else ("", [XYZ, delta])
        E = np.zeros((P, nf))
        E[problem.free, np.arange(nf)] = 1.0
        # p = fixed values (zeros at free entries) + nominal + scale * x at free entries
        p = pfix + sel_scale * ca.mtimes(ca.DM(E), x)
        # the objective as an expression graph, which IPOPT differentiates (a compiled library has no derivatives)
        f = model.batch_function(prefix + "cost", N, compiled=False)(Q, p, C, base0, *tail)
        nlp = {"x": x, "p": data, "f": f}
        opts = self._options(N)
        callback = _Checkpoint(nf) if at_iteration else None
        if callback is not None:
            opts["iteration_callback"] = callback
        solver = ca.nlpsol("calibration", "ipopt", nlp, opts)
        solver.checkpoint = callback    # CasADi does not keep the Python callback alive
        _BUILT[key] = solver
        while len(_BUILT) > MAX_BUILT:  # a few problem shapes at a time keep memory flat
            _BUILT.popitem(last=False)
        self._last = solver
        return solver

    def solve(self, problem: CalibrationProblem, x0: np.ndarray | None = None) -> SolverResult:
        t0 = time.perf_counter()
        solver, at = self._build(problem)
        setup = time.perf_counter() - t0
        x0 = problem.x_from_values(problem.params.values) if x0 is None else np.asarray(x0, float)
        lbx, ubx = problem.bounds_x()
        x0 = np.clip(x0, lbx, ubx)
        data = self._data(problem) if at is None else np.zeros(0)
        t1 = time.perf_counter()
        try:
            if at is not None:
                at.start(problem)
            with noticed():   # CasADi swallows a Ctrl-C and returns the last iterate: raised again here
                sol = solver(x0=x0, p=data, lbx=lbx, ubx=ubx)
        except RuntimeError as e:
            raise SolverError(f"IPOPT failed: {e}") from e
        finally:
            if at is not None:
                error = at.end()
        if at is not None and error is not None:     # raised in a callback: IPOPT saw only NaN
            raise error
        elapsed = time.perf_counter() - t1
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        ok = bool(stats.get("success", False)) or status in CONVERGED
        return SolverResult(x=np.array(sol["x"]).ravel(), cost=float(sol["f"]), success=ok, status=status,
                            iterations=int(stats.get("iter_count", -1)), solve_time_s=elapsed,
                            setup_time_s=setup)

    @staticmethod
    def _data(problem: CalibrationProblem) -> np.ndarray:
        """The NLP parameters of the exact-Hessian solver: the data, the fixed values, the scales."""
        P = len(problem.params)
        pfix = problem.params.values.copy()
        sel_scale = np.zeros(P)
        f = problem.free
        pfix[f] = problem.params.nominal[f]
        sel_scale[f] = problem.params.scales[f]
        data = [problem.q.ravel(), problem.xyz.ravel(), problem.cov.ravel(), problem.base0, pfix, sel_scale,
                [problem.loss.delta]]
        if problem.full_pose:   # row-major rotations, as the model's Rm input reads them
            data += [problem.rot.reshape(-1), [problem.loss.rot_weight]]
        return np.concatenate(data)


class _Iterates:
    """The problem at IPOPT's iterates: one linearisation per point, which the objective, the gradient and the
    Hessian there share, and the loss alone at the trials of a backtracking line search. An exception in a
    callback is kept, and every later call gives NaN (IPOPT stops); :meth:`end` hands it back."""

    def __init__(self):
        self.start(None)

    def start(self, problem: CalibrationProblem | None) -> None:
        self.problem, self.error = problem, None
        # the last point asked about, its loss, its linearisation (None: the loss alone), and whether IPOPT
        # asked for its gradient (it accepted the point)
        self.x, self.f, self.lin, self.accepted = None, None, None, True

    def end(self) -> BaseException | None:
        error = self.error
        self.start(None)
        return error

    def _linearize(self, x: np.ndarray) -> None:
        self.lin = self.problem.linearize(self.problem.values_from_x(x))
        self.x, self.f = x.copy(), self.lin.cost

    def linearization(self, x: np.ndarray):
        """The linearisation at x, where IPOPT asks for the gradient or the Hessian."""
        if self.lin is None or not np.array_equal(x, self.x):
            self._linearize(x)
        self.accepted = True
        return self.lin

    def cost(self, x: np.ndarray) -> float:
        """The loss at x, IPOPT's objective (it asks again at the same x: the second-order corrections)."""
        if self.x is None or not np.array_equal(x, self.x):
            if self.accepted:
                # the first trial of an iteration: the linearisation at once, as IPOPT accepts most first trials
                # and then asks for the gradient there (YS100 80 poses: 18 objectives, 19 gradients)
                self._linearize(x)
            else:
                # the last trial was rejected: a backtracking line search, whose trials need the loss alone (the
                # same number as the linearisation's, to the bit; README split with tolerances on the sum: 361
                # objectives, 301 of them trials after a rejected one)
                self.x, self.f, self.lin = x.copy(), self.problem.cost(self.problem.values_from_x(x)), None
            self.accepted = False
        return self.f


class _Callback(ca.Callback):
    """IPOPT's objective (``f``), its gradient (``grad_f``: f and the gradient) or the Gauss-Newton Hessian of
    the Lagrangian (``hess_l``: its upper triangle, times the objective's multiplier) at x."""

    def __init__(self, kind: str, at: _Iterates, nf: int):
        ca.Callback.__init__(self)
        self.kind, self.at, self.nf = kind, at, nf
        self.construct(f"calibration_{kind}", {"enable_fd": False})

    def get_n_in(self) -> int:
        return 2 if self.kind == "hess_l" else 1

    def get_n_out(self) -> int:
        return 2 if self.kind == "grad_f" else 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self.nf) if i == 0 else ca.Sparsity.dense(1)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        if self.kind == "hess_l":
            return ca.Sparsity.upper(self.nf)
        return ca.Sparsity.dense(self.nf) if i == 1 else ca.Sparsity.dense(1)

    def eval(self, arg):
        at = self.at
        try:
            if at.error is None:
                x = np.asarray(arg[0], dtype=float).ravel()
                if self.kind == "f":
                    return [at.cost(x)]
                lin = at.linearization(x)
                if self.kind == "grad_f":
                    return [lin.cost, lin.g]
                return [ca.triu(ca.DM(float(arg[1]) * lin.A))]
        except BaseException as e:      # noqa: BLE001 (Ctrl-C too: raised again after the solve)
            at.error = e
        nan = np.full(self.nf, np.nan)
        return {"f": [math.nan], "grad_f": [math.nan, nan],
                "hess_l": [ca.triu(ca.DM(np.full((self.nf, self.nf), np.nan)))]}[self.kind]


class _Stop(ca.Callback):
    """IPOPT's iteration callback: stop (1) once a callback has raised, go on (0) otherwise."""

    def __init__(self, at: _Iterates, nf: int):
        ca.Callback.__init__(self)
        self.at, self.nf = at, nf
        self.construct("calibration_stop", {"enable_fd": False})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        n = {"x": self.nf, "f": 1, "lam_x": self.nf}.get(ca.nlpsol_out(i), 0)
        return ca.Sparsity.dense(n)

    def eval(self, arg):
        try:
            checkpoint("solver")    # where a test has the process signal itself (CASADICAL_SIGNAL_AT)
        except BaseException as e:      # noqa: BLE001 (raised again after the solve)
            self.at.error = self.at.error or e
        return [1.0 if self.at.error is not None else 0.0]


class _Checkpoint(ca.Callback):
    """The exact-Hessian solver's iteration callback where a test has the process signal itself
    (:func:`casadical.runtime._interrupts.checkpoint`)."""

    def __init__(self, nx: int):
        ca.Callback.__init__(self)
        self.nx = nx
        self.construct("checkpoint", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        checkpoint("solver")
        return [0]
