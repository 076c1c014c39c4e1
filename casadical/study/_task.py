"""One repetition of a study: the task every backend runs, and the rows it returns.

A repetition draws a true robot, a validation set, an optional extra set
and the candidate pools from the study seed and its index alone
(:class:`numpy.random.SeedSequence` with a spawn key per stream), selects
the calibration poses of every plan and runs every method on them. The same
``(study, repetition)`` gives the same rows in any process, in any order,
on any number of workers.

Errors never escape: a repetition, plan or method that fails gives rows
with ``status = "error"`` and the error, so a study always completes. A
task the backend lost (its worker died) gives rows with ``status =
"lost"``: they are kept, and a resumed run computes them again.
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
import time
import warnings
import zlib
from dataclasses import dataclass, replace

import numpy as np

from ..calibration import calibrate
from ..data._measurements import Measurements
from ..data._simulate import Truth, sample_poses, simulate, true_model
from ..methods import run_method
from ..methods._base import Inputs, Method, MethodResult, new_result
from ..model._symbolic import Model
from ..planning import PlanSettings, design_problem, select_poses
from ..robot import Robot, robot_to_dict
from ._protocol import MethodSpec, PlanSpec, Study
from ._selection import Selection
from ._touch import TouchWorld, draw_touch_world, select_touch_rows, touch_figures

#: The results table: column name and kind (``int``, ``float``, ``str``, ``map``), in order.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("repetition", "int"), ("plan", "str"), ("selector", "str"), ("n_poses", "int"), ("pool", "int"),
    ("method", "str"), ("status", "str"), ("error", "str"),
    ("cal_mean_mm", "float"), ("cal_max_mm", "float"), ("cal_std_mm", "float"), ("cal_rms_mm", "float"),
    ("val_mean_mm", "float"), ("val_max_mm", "float"), ("val_std_mm", "float"), ("val_rms_mm", "float"),
    ("val_true_mean_mm", "float"), ("val_true_max_mm", "float"),
    ("placements", "int"), ("rows_per_point", "int"), ("cal_consistency_mm", "float"),
    ("val_consistency_mm", "float"), ("val_distance_error_mm", "float"),
    ("stiffness_error_pct", "float"), ("parameter_errors", "map"),
    ("plan_o1", "float"), ("plan_log_det", "float"), ("seed", "int"),
    ("plan_time_s", "float"), ("fit_time_s", "float"),
)
#: Columns that measure the run rather than the result: they differ between runs of one study.
TIME_COLUMNS = ("plan_time_s", "fit_time_s")
_STATS = ("mean", "max", "std", "rms")


def seed_of(study: Study, repetition: int, *stream: str | int) -> int:
    """A 32-bit seed for one stream of one repetition (stable across processes and protocol edits).

    Streams are named (``"truth"``, ``("pool", 70)``, ...), so adding a plan
    or a method to a protocol leaves the draws of the others unchanged.
    """
    key = [repetition] + [zlib.crc32(s.encode()) if isinstance(s, str) else int(s) for s in stream]
    return int(np.random.SeedSequence(study.seed, spawn_key=key).generate_state(1)[0])


@dataclass
class Repetition:
    """The simulated world of one repetition.

    Attributes
    ----------
    index : int
    truth : Truth
    validation : Measurements
    extra : Measurements or None
    pools : dict of int to Measurements
        Measured candidate poses by pool size.
    touch : TouchWorld or None
        A touch study's rows (:mod:`casadical.study._touch`); ``validation`` is then its fresh placements.
    """

    index: int
    truth: Truth
    validation: Measurements
    extra: Measurements | None
    pools: dict[int, Measurements]
    touch: TouchWorld | None = None


def draw_repetition(study: Study, repetition: int) -> Repetition:
    """Draw the true robot and every pose set of a repetition (no calibration).

    Useful to look at the data behind one row of the results.
    """
    robot, ws = study.robot, study.workspace
    truth = true_model(robot, study.effects, np.random.default_rng(seed_of(study, repetition, "truth")))
    if study.touch is not None:
        world, validation = draw_touch_world(study, repetition, truth,
                                             lambda *stream: seed_of(study, repetition, *stream))
        return Repetition(repetition, truth, validation, None, {}, world)

    def measured(n: int, *stream) -> Measurements:
        rng = np.random.default_rng(seed_of(study, repetition, *stream))
        q = sample_poses(robot, n, rng, **ws)
        return simulate(robot, q, truth=truth, seed=int(rng.integers(2**32)))[0]

    validation = measured(study.validation_poses, "validation")
    extra = measured(study.extra_poses, "extra") if study.extra_poses else None
    sizes = sorted({p.pool_size(m) for p, m in study.cells()})
    return Repetition(repetition, truth, validation, extra, {n: measured(n, "pool", n) for n in sizes})


def select(study: Study, rep: Repetition, plan: PlanSpec, m: int, designs: dict) -> Selection:
    """Select the ``m`` poses of ``plan`` from its pool (``designs`` caches the pools' Jacobians)."""
    if rep.touch is not None:
        return select_touch_rows(study, rep.touch, plan, m, designs, seed_of(study, rep.index, "plan", plan.name, m))
    pool = rep.pools[plan.pool_size(m)]
    if len(pool) == m:            # the plan takes its whole pool (random poses drawn directly)
        return Selection(np.arange(m))
    key = (plan.model, len(pool))
    if key not in designs:
        model = Model(study.robot, plan.model, jit=False)
        # the rows keep only the selection, its O1 and log det: no comparison with a reference pose set
        designs[key] = (model, design_problem(model, pool.q, model.covariates(pool), reference=False))
    model, problem = designs[key]
    t0 = time.perf_counter()
    res = select_poses(model, None, m, plan.selector, problem=problem,
                       seed=seed_of(study, rep.index, "plan", plan.name, m),
                       settings=PlanSettings(certify=False, ga_generations=plan.ga_generations))
    return Selection(np.asarray(res.indices), res.O1, res.log_det, time.perf_counter() - t0)


class ModelSpecMethod(Method):
    """A plain model specification calibrated by :func:`casadical.calibrate` (not registered)."""

    name = "model"
    model = "kinematic"
    solver = "ipopt"

    def fit(self, inputs: Inputs) -> MethodResult:
        res = calibrate(inputs.robot, inputs.calibration, self.model, self.solver, warn=False)
        return new_result(res, info={"solver": res.solver_name, "iterations": res.solver.iterations})


def run_method_spec(spec: MethodSpec, study: Study, cal: Measurements, rep: Repetition, seed: int) -> MethodResult:
    """Run one method of the study on calibration poses ``cal``, validated on the repetition's set."""
    if spec.method is not None:
        return run_method(spec.method, study.robot, cal, rep.validation, extra=rep.extra, seed=seed,
                          **spec.settings)
    return ModelSpecMethod(model=spec.model, solver=spec.solver).run(Inputs(study.robot, cal, rep.extra, seed),
                                                                    rep.validation)


def _row(repetition: int, plan: PlanSpec, m: int, method: MethodSpec, error: str = "", status: str = "error"
         ) -> dict:
    row: dict = {name: (float("nan") if kind == "float" else {} if kind == "map" else 0 if kind == "int" else "")
                 for name, kind in COLUMNS}
    row.update(repetition=repetition, plan=plan.name, selector=plan.selector, n_poses=m, pool=plan.pool_size(m),
               method=method.name, status=status if error else "ok", error=error, placements=plan.placements,
               rows_per_point=plan.rows_per_point[plan.poses.index(m)] if plan.placements else 0)
    return row


def describe(e: BaseException) -> str:
    """One line: the exception's type and the first line of its message."""
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__


def error_rows(study: Study, repetition: int, error: BaseException | str, status: str = "error") -> list[dict]:
    """The rows of a repetition that failed as a whole, each carrying the error.

    ``status``: ``error`` (the repetition itself failed: it would again) or
    ``lost`` (the backend lost the task: a resumed run computes it again).
    """
    msg = error if isinstance(error, str) else describe(error)
    return [_row(repetition, p, m, meth, msg, status) for p, m in study.cells() for meth in study.methods]


def _figures(res: MethodResult, truth: Truth, val: Measurements, touch: TouchWorld | None = None) -> dict:
    """The result columns of one method's row."""
    row = {f"{what}_{s}_mm": getattr(stats, f"{s}_mm")
           for what, stats in (("cal", res.calibration), ("val", res.validation)) for s in _STATS}
    if touch is not None:
        row.update(touch_figures(res, touch))
    else:
        e_true = np.linalg.norm(res.predict(val) - truth.predict(val), axis=1) * 1000.0
        row["val_true_mean_mm"], row["val_true_max_mm"] = float(e_true.mean()), float(e_true.max())
    k = res.stiffness()
    errs = [abs(k[j] / kt - 1.0) * 100.0 for j, kt in truth.effects.stiffness.items() if j in k]
    row["stiffness_error_pct"] = float(max(errs)) if errs else float("nan")
    names = set(truth.model.parameters.names)
    row["parameter_errors"] = {p.name: float(p.value - truth.value(p.name)) for p in res.result.parameters
                               if not p.fixed and p.group != "base" and p.name in names}
    row["fit_time_s"] = res.time_s
    return row


#: the environment of a task: CasADi's virtual machine, one thread per task (a study runs a task per core)
_TASK_ENV = {"CASADICAL_JIT": "0", "CASADICAL_EVAL_THREADS": "1"}
_vm = {"users": 0, "old": {}, "lock": threading.Lock()}


@contextlib.contextmanager
def _task_environment():
    """Warnings off (pytest's filters or a user's must not turn one into an error on one backend only),
    CasADi's virtual machine instead of JIT compilation (tasks evaluate small batches on fresh models,
    and the VM gives the same floats whether or not a worker has a compiler) and one evaluation thread
    (the study already runs a task per core). Safe for tasks in several threads of one process: the
    first in sets the environment (:data:`_TASK_ENV`), the last out restores it."""
    with _vm["lock"]:
        if _vm["users"] == 0:
            _vm["old"] = {k: os.environ.get(k) for k in _TASK_ENV}
            os.environ.update(_TASK_ENV)
        _vm["users"] += 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        with _vm["lock"]:
            _vm["users"] -= 1
            if _vm["users"] == 0:
                for k, v in _vm["old"].items():
                    if v is None:
                        os.environ.pop(k, None)
                    else:
                        os.environ[k] = v


_ROBOTS: dict[str, Robot] = {}


def _robot_key(robot: Robot) -> str:
    return json.dumps(robot_to_dict(robot), sort_keys=True)


def _shared_robot(study: Study) -> Study:
    """``study`` with the first robot of the same description that reached this process.

    Each Dask task unpickles its own copy of the study; one robot object keeps
    the calibration's per-robot cache (structural identifiability) warm from
    task to task, as in a serial run (a quarter of the time of small tasks).
    The cached robot is checked against its description at every use.
    """
    key = _robot_key(study.robot)
    robot = _ROBOTS.get(key)
    if robot is None or _robot_key(robot) != key:
        if len(_ROBOTS) > 8:
            _ROBOTS.clear()
        robot = _ROBOTS[key] = study.robot
    return study if robot is study.robot else replace(study, robot=robot)


def run_task(study: Study, repetition: int) -> list[dict]:
    """Run one repetition: every plan times every method; one row each (see :data:`COLUMNS`).

    Deterministic from ``(study.seed, repetition)``; never raises for a
    failure of the simulation, a selection or a method (the row records it).
    """
    study = _shared_robot(study)
    with _task_environment():
        try:
            rep = draw_repetition(study, repetition)
        except Exception as e:  # noqa: BLE001  (a failed repetition is a result, not the end of the study)
            return error_rows(study, repetition, e)
        rows: list[dict] = []
        designs: dict = {}
        for plan, m in study.cells():
            try:
                sel = select(study, rep, plan, m, designs)
                cal = (rep.touch.rows if rep.touch is not None else rep.pools[plan.pool_size(m)]).subset(sel.indices)
            except Exception as e:  # noqa: BLE001
                rows += [_row(repetition, plan, m, meth, describe(e)) for meth in study.methods]
                continue
            for meth in study.methods:
                row = _row(repetition, plan, m, meth)
                row.update(plan_o1=sel.o1, plan_log_det=sel.log_det, plan_time_s=sel.time_s,
                           seed=seed_of(study, repetition, "method", plan.name, m, meth.name))
                try:
                    res = run_method_spec(meth, study, cal, rep, row["seed"])
                    row.update(_figures(res, rep.truth, rep.validation, rep.touch))
                except Exception as e:  # noqa: BLE001
                    row.update(status="error", error=describe(e))
                rows.append(row)
        return rows
