"""Settings of the diagnosis (:func:`casadical.diagnosis.diagnose`)."""

from __future__ import annotations

from dataclasses import dataclass, fields

from ..errors import InputError

#: the solvers a diagnosis may fit with
SOLVERS = ("lm", "ipopt", "gn", "auto")


@dataclass
class DiagnosisSettings:
    """Settings of :func:`casadical.diagnosis.diagnose`.

    Parameters
    ----------
    alpha : float
        Family-wise significance level of the F-tests (Bonferroni over the
        candidates of a round, harmonics scanned included).
    max_harmonic : int
        Highest harmonic of the periodogram (cycles per joint turn).
    folds : int
        Folds of each cross-validation scheme.
    max_rounds : int
        Safety cap on the rounds; the search stops when no candidate is
        supported, and a note says if the cap stopped it instead.
    confirm : int
        Candidates fitted for real per round and tier (best scores first).
    blackbox : bool
        Try the GP compensator (one per session) on what remains
        (:mod:`casadical.diagnosis._compensator`).
    stability_alpha : float
        Level of the test that a periodic error's amplitude and phase agree
        on the two halves of the joint's range.
    robust : {"huber", "none"}
        Loss of every fit (see :func:`casadical.calibrate`).
    position_only : bool
        Fit on the positions alone even when the data have measured
        orientations (``rx_deg, ry_deg, rz_deg``); otherwise every full fit
        of such data is a full-pose one (see :func:`casadical.calibrate`).
        The screening of candidates works on the positions either way.
    transfer_base_poses : int
        With another series: poses on which the base pose is re-estimated there.
    transfer_refit_poses : int or None
        With another series: poses on which the geometry is refitted there
        (default: as many as the calibration poses, at most half the series).
    seed : int
    session_tools : bool
        With several sessions: each session after the first has its own
        tool offset too (the probe was re-mounted).
    structure : bool
        Screen what the named causes leave for structure no catalogue cause
        explains (:mod:`casadical.diagnosis._structure`), and check that every
        named cause explains the structure it stands for
        (:mod:`casadical.diagnosis._stand_ins`).
    worst_case : bool
        Where the final model's worst validation error is more than 5 % above
        the kinematic model's, end with the model the report names to restore
        it (without the GP compensator, or fewer causes:
        :mod:`casadical.diagnosis._worst_case`), a safe worst case chosen over
        a lower mean; without it the report only says so.
    noise_mm : float or None
        The instrument's noise per axis (mm, 1 sigma), as the user states it:
        the report gives the final model's leftover in units of it (None: from
        repeated poses where the data hold some, :mod:`casadical.diagnosis._noise`).
    solver : {"lm", "ipopt", "gn", "auto"}
        The solver of every fit of a model to the calibration poses (see :func:`casadical.calibrate`):
        Levenberg-Marquardt (unbounded, the default), IPOPT (within the parameters' bounds), Gauss-Newton, or
        LM then IPOPT where a bound is crossed.
    terms : tuple of TermDefinition
        Causes of one's own (a terms file's, :func:`casadical.terms._definitions.read_terms_file`): screened
        beside the catalogue's, by the same tests and rules.
    levelled : bool or None
        The instrument was levelled (True), was not (False), or infer it where every session's base pose
        agrees on one vertical (None): the robot file's gravity is checked against its down
        (:mod:`casadical.calibration._gravity`).
    """

    alpha: float = 0.001
    max_harmonic: int = 60
    folds: int = 5
    max_rounds: int = 40
    confirm: int = 3
    blackbox: bool = True
    stability_alpha: float = 0.001
    robust: str = "huber"
    position_only: bool = False
    transfer_base_poses: int = 30
    transfer_refit_poses: int | None = None
    seed: int = 0
    session_tools: bool = False
    structure: bool = True
    noise_mm: float | None = None
    worst_case: bool = False
    solver: str = "lm"
    terms: tuple = ()
    levelled: bool | None = None

    def record(self) -> dict:
        """The settings for a report (the user terms by their names: their definitions are the report's own)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "terms"}

    def __post_init__(self) -> None:
        self.terms = tuple(self.terms)
        if not 0 < self.alpha < 1 or not 0 < self.stability_alpha < 1:
            raise InputError(f"alpha and stability_alpha must be in (0, 1), got {self.alpha}, "
                             f"{self.stability_alpha}")
        for name in ("max_harmonic", "folds", "confirm", "transfer_base_poses"):
            if getattr(self, name) < (2 if name == "folds" else 1):
                raise InputError(f"{name} must be at least {2 if name == 'folds' else 1}, got {getattr(self, name)}")
        if self.noise_mm is not None and not 0 < self.noise_mm < float("inf"):
            raise InputError(f"noise_mm must be a positive number of mm, got {self.noise_mm}")
        if self.solver not in SOLVERS:
            raise InputError(f"solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")
        if self.max_rounds < 0:
            raise InputError(f"max_rounds must not be negative, got {self.max_rounds}")
