"""What a diagnosis carries from stage to stage (:mod:`casadical.diagnosis._pipeline`).

:class:`DiagnosisRun` holds the diagnosis under way: what the caller gave, the fields each stage sets
(grouped below by the stage that sets them), and what every stage asks of the calibration poses: a fit of a
model specification (:meth:`~DiagnosisRun.fit`), a fit's validation errors (computed once per fit), its
deviance under a loss, the comparison of two nested fits (:meth:`~DiagnosisRun.compare`, the one F-test and
BIC of the diagnosis), its held-out means on the folds.

A stage is a function ``stage(run)`` that sets the fields of its own group, or returns what it adds to the
fields several stages change (a :class:`StageOutcome`: notes, steps, the fits they hold, the findings, the model of
the named causes, the final model), which the pipeline installs (:meth:`DiagnosisRun.install`, the one writer of
those fields). To add a stage, give it a group of fields of its own, or return what it changes of the shared
ones; ``tests/diagnosis/test_stage_writes.py`` fails where two stage modules write one field.

What a cause's acceptance or rejection carries is in :mod:`._evidence`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, Mapping

import numpy as np

from ..calibration._for_data import model_for
from ..calibration._gravity import GravityCheck
from ..calibration._pipeline import calibrate
from ..calibration._solve import STD_TOL
from ..data._measurements import Measurements
from ..problem import RobustLoss
from ..result import AngleStats, CalibrationResult, ErrorStats, touch_stats
from ..robot import Robot
from ..runtime._kept import Kept
from ..terms import ErrorTerm, make_term
from ._candidates import Candidate
from ._catalogue import Catalogue
from ._evidence import Support
from ._findings import UnexplainedLog
from ._report import Finding, Step
from ._settings import DiagnosisSettings
from ._statistics import NestedTest, nested_test, set_aside_share
from ._validation import CVResult, Linearized, by_kind, joint_levers, schemes

if TYPE_CHECKING:
    from ..stats._outliers import SetAsideStructure
    from ._design import Design
    from ._noise import NoiseFloor
    from ._report import DiagnosisReport
    from ._transfer import TransferStudy


#: fits whose linearisation on the calibration poses a run keeps (:meth:`DiagnosisRun.linearized`): the search's
#: judge asks the current fit and the new one, which the next round's judge asks again; the final checks ask the
#: final fit and the kinematic one. Each is 3 x 8 bytes per pose and free parameter (40 MB at 20,000 poses: the
#: 20,000-pose diagnosis of bench_diagnosis_scale.py peaked at 676 MB keeping 2, 692 MB keeping 3, 644 MB none)
KEPT_FITS = 2


@dataclass(frozen=True)
class ModelUnderWay:
    """The model of the named causes as a stage leaves it (the search, a final check), for the pipeline to install
    (:meth:`DiagnosisRun.install`): the fit, the causes it holds in the order accepted, whether it holds the
    geometry, and what is kept for each cause it holds: the evidence that accepted it (``support``) and the fit
    before it (``before``)."""

    current: CalibrationResult
    accepted: tuple[Candidate, ...]
    geometric: bool
    support: Mapping[Candidate, Support]
    before: Mapping[Candidate, CalibrationResult]

    def holding(self, fit: CalibrationResult, accepted, geometric: bool | None = None) -> ModelUnderWay:
        """``fit``, the model of ``accepted`` (some of these causes; the geometry as here unless ``geometric``
        says): what was kept for the others goes with them."""
        return ModelUnderWay(fit, tuple(accepted), self.geometric if geometric is None else geometric,
                             {c: v for c, v in self.support.items() if c in accepted},
                             {c: v for c, v in self.before.items() if c in accepted})


@dataclass(frozen=True)
class FinalModel:
    """The model a stage ends the diagnosis with, returned for the pipeline to install (:meth:`DiagnosisRun.install`):
    the model of the named causes (``model``; its fit is ``parametric``), the final model (it with the GP
    compensator where one is kept) and the final model's specification."""

    model: ModelUnderWay
    final: CalibrationResult
    spec: str

    @property
    def parametric(self) -> CalibrationResult:
        return self.model.current


@dataclass(frozen=True)
class StageOutcome:
    """What a stage returns for the pipeline to install (:meth:`DiagnosisRun.install`), so that each field of the
    run has one writer: the notes and steps it adds, in order; the fits it records (``recorded``: each fit, the
    index of the step that holds it in the run's steps or None, and the causes of an accepted model of the search
    or None: :meth:`DiagnosisRun.step_of`, ``history``); the findings as it leaves them (None: as they were); the
    model of the named causes it leaves (None: as it was); the final model it makes (None: none)."""

    notes: tuple[str, ...] = ()
    steps: tuple[Step, ...] = ()
    recorded: tuple[tuple[CalibrationResult, int | None, tuple | None], ...] = ()
    findings: tuple[Finding, ...] | None = None
    model: ModelUnderWay | None = None
    final: FinalModel | None = None


@dataclass
class DiagnosisRun:
    """One diagnosis as it goes through the stages.

    The first fields are what the caller gave; every later group is set by the stage named above it and read
    by those after it (``None`` until then), except the fields several stages change: those are set only by
    :meth:`install`, from the :class:`StageOutcome` each stage returns.
    """

    robot: Robot
    cal: Measurements                   # the calibration poses: they decide
    val: Measurements                   # the validation poses: they judge, never decide
    s: DiagnosisSettings
    say: Callable[[str], None]          # one line of progress
    other: Measurements | None = None   # another series of the same robot (the transfer study)
    checks: dict = field(default_factory=dict)   # overrides of the plausibility checks of the poses
    t0: float = field(default_factory=time.perf_counter)

    # check_data: the equations, the folds, the sessions
    n_eq: int = 0                  # the screening and its linearised tests: positions
    full_pose: bool = False        # every full fit, and the tests on their losses, on 6 equations a pose
    n_fit_eq: int = 0
    sessions: list = field(default_factory=list)      # [] for one session
    catalogue: Catalogue | None = None

    # fit_nominal, fit_geometry: the reference models; how weak the design is
    nominal: CalibrationResult | None = None
    kinematic: CalibrationResult | None = None
    gravity: GravityCheck | None = None       # the robot file's gravity against a levelled instrument's down
    design: Design | None = None
    schemes: list = field(default_factory=list)     # the cross-validation folds (their own on a one-joint design)
    prior: dict[str, float] | None = None     # the folds' priors of the geometry on a weak design

    # installed from what the stages return (install): what the stages say, in order; the steps, the fits they
    # hold, the findings
    notes: list[str] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    history: list[tuple[list[Candidate], CalibrationResult]] = field(default_factory=list)  # accepted models
    fits_of_steps: list[tuple[CalibrationResult, int]] = field(default_factory=list)      # each fit, its step
    findings: list[Finding] = field(default_factory=list)

    # the model under way, installed from the ModelUnderWay the stages return (fit_geometry's; search_causes' and
    # the final checks' change it); what is kept for each cause it holds: the fit before it, the evidence
    current: CalibrationResult | None = None
    accepted: list[Candidate] = field(default_factory=list)
    geometric: bool = False
    before: dict[Candidate, CalibrationResult] = field(default_factory=dict)
    support: dict[Candidate, Support] = field(default_factory=dict)

    # search_causes
    not_tried: list = field(default_factory=list)     # kinds of cause these data cannot test
    round: int = 0                                    # the round under way (1, 2, ...)
    user_scores: dict = field(default_factory=dict)   # each user candidate's score test by round (.user_terms)
    round_steps: dict = field(default_factory=dict)   # round -> the number of steps before it (.user_terms)
    later: dict[Candidate, int] = field(default_factory=dict)    # not significant yet: screened again later
    unexplained: UnexplainedLog = field(default_factory=UnexplainedLog)

    # screen_structure: what the named causes leave: (structure, its finding), strongest first
    structures: list = field(default_factory=list)

    # keep_never_worse
    held_text: str = ""            # the final check's worst held-out errors, in words

    # the final model (add_compensator's, or keep_worst_case's with --worst-case): installed from the FinalModel the
    # stage returns
    parametric: CalibrationResult | None = None
    final: CalibrationResult | None = None
    final_spec: str = ""

    # judge_final_model
    final_errors: np.ndarray | None = None
    final_val: ErrorStats | None = None
    set_aside: SetAsideStructure | None = None
    structure_misses: dict[int, list[int]] = field(default_factory=dict)   # finding number -> file lines
    noise: NoiseFloor | None = None
    interval_coverage: float | None = None   # share of the validation poses inside the final model's 95 % interval

    # transfer_findings, assemble_report
    study: TransferStudy | None = None
    report: DiagnosisReport | None = None

    # caches: a fit's validation errors; the gravity torques of the calibration poses under the current fit
    _val_errors: dict[int, tuple] = field(default_factory=dict, repr=False)
    _torques: tuple | None = field(default=None, repr=False)
    # a fit's linearisation on the calibration poses and its held-out errors (with the schemes and prior they
    # are of), by the fit (each answer holds its fit, so no id is reused while it is kept): the search's judge, the
    # stand-in check, the never-worse check, the structure screen and the intervals ask them of the same fits
    _linearized: Kept = field(default_factory=lambda: Kept(KEPT_FITS), repr=False)
    _held_out: Kept = field(default_factory=lambda: Kept(KEPT_FITS), repr=False)

    def fold_schemes(self, moving: np.ndarray | None = None) -> list:
        """The cross-validation schemes of the calibration poses (``moving``: of a design of one joint at a time,
        :func:`._validation.schemes`)."""
        return schemes(self.cal.q, self.cal.rows, self.s.folds, self.s.seed, joint_levers(self.robot, self.cal),
                       sessions=self.cal.sessions, moving=moving)

    def install(self, made: StageOutcome) -> None:
        """What a stage returned becomes the run's (the one place these fields are set): its notes and steps
        appended, the fits of its steps recorded (``fits_of_steps``; an accepted model of the search in
        ``history``), its findings; the model under way (``current``, ``accepted``, ``geometric``, ``support``,
        ``before``) of its ``model``, or of its final model's, which also sets ``parametric``, ``final`` and
        ``final_spec``."""
        self.notes += made.notes
        self.steps += made.steps
        for res, step, causes in made.recorded:
            if step is not None:
                self.fits_of_steps.append((res, step))
            if causes is not None:
                self.history.append((list(causes), res))
        if made.findings is not None:
            self.findings = list(made.findings)
        model = made.final.model if made.final is not None else made.model
        if model is not None:
            self.current, self.accepted, self.geometric = model.current, list(model.accepted), model.geometric
            self.support, self.before = dict(model.support), dict(model.before)
        if made.final is not None:
            self.parametric = made.final.parametric
            self.final, self.final_spec = made.final.final, made.final.spec

    def under_way(self) -> ModelUnderWay:
        """The model under way as it stands (a stage changes it by returning another: :meth:`install`)."""
        return ModelUnderWay(self.current, tuple(self.accepted), self.geometric, dict(self.support),
                             dict(self.before))

    def step_of(self, res: CalibrationResult) -> int | None:
        """Index of the step whose model ``res`` is (None for a fit no step holds: a final-check refit)."""
        return next((k for fit, k in self.fits_of_steps if fit is res), None)

    def fit(self, terms: list[ErrorTerm], start: CalibrationResult | dict | None = None,
            loss: RobustLoss | None = None, parent: CalibrationResult | None = None) -> CalibrationResult:
        """Calibrate the model of ``terms`` (new ones: the model binds them,
        :func:`~casadical.diagnosis._candidates.compose_terms`) on the calibration poses (the settings' solver, LM
        by default), from ``start``'s values (a result, or a dict of ``parent``'s parameters as one step moved
        them), warm: from the base pose and probe mounting of the fit the values are of
        (``calibrate(start_from=...)``), so the solve starts at its solution."""
        model = model_for(self.robot, list(terms) + ([make_term("tool_orientation")] if self.full_pose else []),
                          self.cal, session_tools=self.s.session_tools)
        st = origin = None
        if start is not None:
            origin = start if isinstance(start, CalibrationResult) else parent
            values = start if isinstance(start, dict) else {p.name: p.value for p in start.parameters}
            st = {n: v for n, v in values.items() if n in model.parameters and not n.startswith("base_")}
        # each solve stops once its next step is below a hundredth of every parameter's standard error: the
        # steps after that moved no finding, and half the linearisations of the 2,000-pose job were the trials
        # of steps the cost's rounding rejected there (docs/speed.md)
        opts = {} if self.s.solver == "ipopt" else {"std_tol": STD_TOL}     # IPOPT stops by its own tolerance
        return calibrate(self.robot, self.cal, model, self.s.solver, solver_options=opts, start=st,
                         start_from=origin, warn=False, robust=loss or self.s.robust,
                         position_only=self.s.position_only)

    def val_errors(self, res: CalibrationResult) -> np.ndarray:
        """Position errors (m) of a fit on the validation poses, predicted once per fit."""
        hit = self._val_errors.get(id(res))
        if hit is None or hit[0] is not res:
            hit = self._val_errors[id(res)] = (res, res.errors(self.val))
        return hit[1]

    def val_stats(self, res: CalibrationResult) -> ErrorStats:
        """Errors of a fit on the validation poses; rows that touch: with their consistency and distance error
        (:func:`casadical.result.touch_stats`)."""
        if self.val.touches:
            return ErrorStats.of(self.val_errors(res), touch_stats(self.val.layout, res.predict(self.val)))
        return ErrorStats.of(self.val_errors(res))

    def val_angles(self, res: CalibrationResult) -> AngleStats | None:
        """Orientation errors of a full-pose fit on the validation poses (None without orientations)."""
        if not (res.has_orientation and self.val.has_orientation):
            return None
        return AngleStats.of(res.orientation_errors(self.val))

    def u2(self, res: CalibrationResult, loss: RobustLoss) -> np.ndarray:
        """Squared residual norm of each calibration pose under ``loss``: full pose, ``|r_p|^2 + k^2 |r_o|^2``."""
        r = res.residuals(self.cal)
        u2 = np.einsum("ij,ij->i", r, r)
        if res.full_pose and math.isfinite(loss.rot_weight):
            u2 = u2 + (loss.rot_weight * res.orientation_errors(self.cal)) ** 2
        return u2

    def deviance(self, res: CalibrationResult, loss: RobustLoss, noise: bool = False) -> float:
        """Twice the loss of ``res`` on the calibration poses under ``loss`` (SSR for least squares); ``noise``:
        with the set-aside poses counted by their influence (a test's noise scale, :func:`._statistics.nested_test`)."""
        u2 = self.u2(res, loss)
        return 2.0 * float(loss.rho(u2) @ (set_aside_share(loss.weight(u2)) if noise else np.ones(len(u2))))

    def compare(self, smaller: CalibrationResult, larger: CalibrationResult, loss: RobustLoss) -> NestedTest:
        """The F-test and BIC of ``larger`` against the nested ``smaller``, full fits on the calibration poses,
        both under ``loss``; the noise scale is ``larger``'s, its set-aside poses counted by their influence."""
        return nested_test(self.deviance(smaller, loss), int(smaller.parameters.free.sum()),
                           self.deviance(larger, loss), int(larger.parameters.free.sum()), self.n_fit_eq,
                           self.deviance(larger, loss, noise=True))

    def mask(self, res: CalibrationResult) -> np.ndarray:
        """Poses that count in held-out means: those the robust loss did not set aside."""
        return res.loss.weight(self.u2(res, res.loss)) >= 0.5

    def torques(self, res: CalibrationResult) -> np.ndarray:
        """Gravity torques (N m) of the calibration poses under a fit, computed once per fit."""
        if self._torques is None or self._torques[0] is not res:
            m = res.model
            self._torques = (res, m.torques(self.cal.q, res.parameters.values, m.covariates(self.cal)))
        return self._torques[1]

    def linearized(self, res: CalibrationResult) -> Linearized:
        """``res`` linearised at its solution on the calibration poses (:meth:`._validation.Linearized.of`), made
        once per fit (the last :data:`KEPT_FITS` kept)."""
        hit = self._linearized.get(id(res))
        if hit is None:
            hit = (res, Linearized.of(res, self.cal))
            self._linearized.put(id(res), hit)
        return hit[1]

    def held_out(self, res: CalibrationResult) -> CVResult:
        """The held-out errors of ``res`` on every fold of the diagnosis' schemes (:meth:`._validation.Linearized.cv`
        with its prior), computed once per fit."""
        key = (id(res), id(self.schemes), id(self.prior))
        hit = self._held_out.get(key)
        if hit is None:
            hit = (res, self.schemes, self.prior, self.linearized(res).cv(self.schemes, self.prior))
            self._held_out.put(key, hit)
        return hit[3]

    def cv(self, res: CalibrationResult, mask: np.ndarray) -> dict:
        """Held-out means (mm) by kind of fold of a fit, linearised at it, over the poses of ``mask``."""
        return by_kind(self.held_out(res), mask)

    def candidates(self, current: CalibrationResult, accepted: list[Candidate]) -> list[Candidate]:
        """Every candidate not yet in the model (:class:`._catalogue.Catalogue`)."""
        skip = self.unexplained.excluded_causes | {c for c, n in self.later.items() if n == len(accepted)}
        return self.catalogue.candidates(current, accepted, self.unexplained.excluded, skip,
                                         lambda: self.torques(current))

    def n_tests(self, cands: list[Candidate]) -> int:
        return self.catalogue.n_tests(cands)
