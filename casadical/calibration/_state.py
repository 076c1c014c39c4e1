"""What a calibration carries from stage to stage (:mod:`casadical.calibration._pipeline`).

:class:`Options` holds how the caller asked to calibrate; :class:`CalibrationRun`
holds the calibration under way: what the caller gave, and what each stage
adds (its fields are grouped by the stage that sets them). A stage is a
function ``stage(run) -> None`` that reads the fields of the stages before
it and sets its own.
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import CasadicalWarning

if TYPE_CHECKING:
    from ..data._measurements import Measurements
    from ..model._symbolic import Model
    from ..parameters import Parameters
    from ..problem import CalibrationProblem, Linearization, RobustLoss
    from ..result import CalibrationResult
    from ..robot import Robot
    from ..solvers import SolverResult
    from ..stats._identifiability import Identifiability
    from ..stats._uncertainty import Uncertainty
    from ..terms import ErrorTerm

#: the files a warning of :meth:`CalibrationRun.note` passes over: it names the line that called ``calibrate``
_INSIDE = (os.path.dirname(__file__) + os.sep, contextlib.__file__)


def _caller_level() -> int:
    """The ``stacklevel`` of the first frame outside this package and its thread-limit wrapper, for a warning
    issued by the function that calls this one."""
    level, f = 2, sys._getframe(2)
    while f is not None and f.f_code.co_filename.startswith(_INSIDE):
        f, level = f.f_back, level + 1
    return level


@dataclass
class Options:
    """How to calibrate: every setting of :func:`~casadical.calibration.calibrate` beyond the robot, the data
    and the model (its parameters of the same names)."""

    solver: str = "ipopt"
    solver_options: dict = field(default_factory=dict)
    fix: tuple[str, ...] = ()
    start: dict[str, float] = field(default_factory=dict)
    start_from: CalibrationResult | None = None
    check_identifiability: bool = True
    warn: bool = True
    robust: str | RobustLoss = "huber"
    position_only: bool = False
    allow_outside_limits: bool = False
    angles_are_degrees: bool = False
    positions_are_mm: bool = False
    allow_mismatch: bool = False
    session_tools: bool | list[str] = False
    keep_compensator: bool = False
    terms: tuple = ()       # definitions of the causes of one's own the model may name (a terms file's)


@dataclass
class CalibrationRun:
    """One calibration as it goes through the stages.

    The first fields are what the caller gave; every later group is set by
    the stage named above it and read by those after it. ``notes`` collects
    what the result will say (:meth:`note`).
    """

    robot: Robot
    data: Measurements
    spec: str | Model                    # the model asked for: a specification or a built model
    options: Options
    prior: CalibrationResult | None = None   # a calibration taken further (the robot is its robot)
    notes: list[str] = field(default_factory=list)
    #: fix_unobservable: what rows that touch cannot see ({"what", "why", "parameters"} each)
    unobservable: list[dict] = field(default_factory=list)

    @property
    def user_terms(self) -> tuple:
        """The definitions a specification of this calibration may name: those given, and a calibration taken
        further carries its own."""
        return tuple(self.options.terms) + (self.prior.model.user_definitions if self.prior is not None else ())

    # prepare_data: the loss, and whether the fit is on the full pose
    loss: RobustLoss | None = None
    full_pose: bool = False
    measured_rot: np.ndarray | None = None   # full pose: the measured rotations (n, 3, 3)

    # read_model_spec: the terms asked for
    terms: list[ErrorTerm] = field(default_factory=list)
    built: Model | None = None           # the caller's own model (with the probe's mounting, for full pose)
    free_tool: bool = False              # ``+tool``: the tool offset is estimated too
    want_rbf: bool = False               # ``+rbf_compensator``: fitted after the model (add_rbf_compensator)
    want_gp: bool = False                # ``+gp_compensator``: fitted after the model (add_gp_compensator)

    # build_model: the model and its parameters, which of them are free
    model: Model | None = None
    params: Parameters | None = None
    kept: set[str] = field(default_factory=set)   # fixed, with their std from the calibration taken further

    # start_pose: the base pose (and the probe's mounting) in closed form
    base0: np.ndarray | None = None
    tool0: np.ndarray | None = None      # full pose: the probe's reference mounting R0
    rot: np.ndarray | None = None        # full pose: the measured rotations with R0 taken out
    cov: np.ndarray | None = None        # the model's covariates of the poses
    scale_at: np.ndarray | None = None   # start_from: the values the noise scale is first estimated at

    # analyse_identifiability
    ident: Identifiability | None = None

    # solve_parameters
    problem: CalibrationProblem | None = None
    solution: SolverResult | None = None
    solver_name: str = ""
    expected: frozenset = frozenset()    # correlations said in a note, not warned about again

    # estimate_precision: the linearisation at the solution, each pose's residual norm, the uncertainty
    lin: Linearization | None = None
    norms: np.ndarray | None = None
    uncertainty: Uncertainty | None = None

    # note_set_aside: the poses the robust loss set aside
    down: list[dict] = field(default_factory=list)

    # assemble_result, and the stages after it, which replace it
    result: CalibrationResult | None = None

    @property
    def per_pose(self) -> int:
        """Equations each pose gives: 3 (position), 6 (full pose)."""
        return 6 if self.full_pose else 3

    @property
    def equations(self) -> int:
        """Equations the poses give: ``per_pose`` each; rows that touch, their layout's (each group's unknowns
        used up: :attr:`casadical.rows.Layout.equations`)."""
        return self.data.layout.equations if self.data.touches else self.per_pose * len(self.data)

    @property
    def where(self) -> str:
        """The data file as a message's prefix (``"file: "``), or nothing."""
        return f"{self.data.path}: " if self.data.path else ""

    def note(self, text: str, category: type[Warning] = CasadicalWarning) -> None:
        """Add ``text`` to the notes (the result's once there is one) and, unless the caller said
        ``warn=False``, warn with it (at the line that called ``calibrate``)."""
        (self.result.notes if self.result is not None else self.notes).append(text)
        if self.options.warn:
            warnings.warn(text, category, stacklevel=_caller_level())
