"""Does a finding hold up on another measurement series?

The diagnosed model and the model without one finding at a time are taken
to another series the two ways a calibration travels:

- ``base``: only the base pose is estimated again, on a few poses of the
  other series (a new tracker set-up), and every other pose judges;
- ``refit``: the geometry is estimated again on part of the other series
  with the finding's parameters frozen (a new series of the same robot),
  and the rest judges.

A finding transfers when the model with it beats the model without it
both ways. The kinematic model taken there the same way is the baseline.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..calibration import calibrate
from ..data._measurements import Measurements
from ..errors import InputError
from ..result import CalibrationResult
from ._candidates import Candidate, compose_terms
from ._state import DiagnosisRun
from ._words import gain_words


@dataclass
class Split:
    """Which poses of the other series fit and which judge, for each way of travelling."""

    base_fit: np.ndarray
    base_test: np.ndarray
    refit_fit: np.ndarray
    refit_test: np.ndarray

    @classmethod
    def of(cls, n: int, n_base: int, n_refit: int, seed: int) -> "Split":
        perm = np.random.default_rng(seed).permutation(n)
        return cls(np.sort(perm[:n_base]), np.sort(perm[n_base:]), np.sort(perm[:n_refit]),
                   np.sort(perm[n_refit:]))


@dataclass
class Travel:
    """Mean errors (mm) of one model on the other series, both ways."""

    base_mm: float
    refit_mm: float

    def to_dict(self) -> dict:
        return {"base_mm": self.base_mm, "refit_mm": self.refit_mm}


def travel(model: CalibrationResult, other: Measurements, split: Split) -> Travel:
    # on the full pose where the model was fitted on it (and the other series has orientations)
    b = calibrate(model, other.subset(split.base_fit), "base", "lm", warn=False, position_only=not model.full_pose)
    r = calibrate(model, other.subset(split.refit_fit), "kinematic", "lm", warn=False,
                  position_only=not model.full_pose)
    return Travel(b.stats(other.subset(split.base_test)).mean_mm, r.stats(other.subset(split.refit_test)).mean_mm)


@dataclass
class TransferStudy:
    """The final and kinematic models on another series, and each finding's gain there."""

    file: str
    split: Split
    final: Travel
    kinematic: Travel
    gains: dict = field(default_factory=dict)   # finding index -> (base gain, refit gain), mm
    #: the other series touches alone: no base pose to re-estimate (its touched points fitted to its own rows)
    touches: bool = False

    def to_dict(self) -> dict:
        return {"file": self.file, "n_base": len(self.split.base_fit), "n_refit": len(self.split.refit_fit),
                "final": self.final.to_dict(), "kinematic": self.kinematic.to_dict(), "text": self.text()}

    def text(self) -> str:
        f, k = self.final, self.kinematic
        first = ("as calibrated (touches see no base pose: the touched points fitted to their own rows), mean"
                 if self.touches else f"base pose re-estimated on {len(self.split.base_fit)} poses, mean")
        return (f"taken to {self.file}: {first} "
                f"{f.base_mm:.4f} mm (kinematic {k.base_mm:.4f}); geometry refitted on "
                f"{len(self.split.refit_fit)} poses with the findings frozen, mean {f.refit_mm:.4f} mm "
                f"(kinematic refit {k.refit_mm:.4f})")


def finding_gain(with_it: Travel, without: Travel) -> dict:
    gb, gr = without.base_mm - with_it.base_mm, without.refit_mm - with_it.refit_mm
    tie = 1e-4  # mm: no difference there
    if abs(gb) < tie and abs(gr) < tie:
        verdict = "no difference"
    else:
        verdict = "transfers" if gb > 0 and gr > 0 else ("does not transfer" if gb <= 0 and gr <= 0 else "mixed")
    return {"base_gain_mm": gb, "refit_gain_mm": gr, "verdict": verdict,
            "text": f"{verdict}: {gain_words(gb)} with the base re-estimated, {gain_words(gr)} with the geometry "
                    "refitted"}


def study(final: CalibrationResult, kinematic: CalibrationResult, without: Callable[[int], CalibrationResult | None],
          n_findings: int, other: Measurements, n_base: int, n_refit: int, seed: int,
          progress: Callable[[str], None], labels: list[str] | None = None, todo: list[int] | None = None
          ) -> TransferStudy:
    """Take ``final``, ``kinematic`` and ``without(k)`` (the final model fitted without finding k) to ``other``.

    ``labels``: what is taken there for each finding, in a few words, and ``todo``: the findings ``without`` gives
    a model for, for the progress lines (one per finding taken there).
    """
    split = Split.of(len(other), n_base, n_refit, seed)
    progress(f"transfer: taking the final and the kinematic model to {other.path} (base pose re-estimated on "
             f"{n_base} poses, geometry refitted on {n_refit})")
    out = TransferStudy(other.path, split, travel(final, other, split), travel(kinematic, other, split),
                        touches=other.touches and bool(other.touching.all()))
    ks = list(range(n_findings)) if todo is None else todo
    for i, k in enumerate(ks, 1):
        if labels is not None:
            progress(f"transfer: {i} of {len(ks)}, {labels[k]}, fitted here and taken there")
        model = without(k)
        if model is not None:
            out.gains[k] = travel(model, other, split)
    return out


def transfer_findings(run: DiagnosisRun) -> None:
    """Stage ``transfer_findings``: with another series (``other``), take the findings there and set each
    finding's verdict (``transfer``) and ``study``; reads ``final``, ``parametric``, ``accepted``, ``geometric``,
    ``kinematic`` and ``findings``."""
    if run.other is not None:
        run.study = findings_study(run, run.final, run.parametric, run.accepted, run.geometric, run.other)


def findings_study(run: DiagnosisRun, final: CalibrationResult, parametric: CalibrationResult,
                   accepted: list[Candidate], geometric: bool, other: Measurements) -> TransferStudy:
    """Take a diagnosis (``run``: its findings, fits and kinematic model) to ``other``; set each finding's verdict.

    ``parametric`` is the model of the named causes (``final`` without the GP compensator); a named finding is
    judged against the model refitted without it, structure kept out against the model refitted with it.
    """
    s = run.s
    named = [k for k, f in enumerate(run.findings) if f.in_model and f.candidate.kind.named]
    n_refit = s.transfer_refit_poses or min(len(run.cal), len(other) // 2)
    if not s.transfer_base_poses < len(other) or not n_refit < len(other):
        raise InputError(f"has {len(other)} poses: too few to re-estimate the base on "
                         f"{s.transfer_base_poses} and the geometry on {n_refit} and judge on the rest",
                         file=other.path)

    def without(k: int) -> CalibrationResult | None:
        f = run.findings[k]
        key = (f.candidate.joint, f.candidate.session)
        if f.candidate.kind.unexplained and not f.in_model and key in run.unexplained.strongest:
            # structure left out: what would it have done there?
            return run.fit(compose_terms(accepted + [run.unexplained.strongest[key]], geometric), start=parametric)
        if k not in named:
            return None
        c = f.candidate
        # without the cause, and without those that need it (a progressive spring its joint's compliance)
        rest = [a for a in accepted if a != c and not (c.cause in a.kind.requires and a.joint == c.joint)]
        return run.fit(compose_terms(rest, geometric), start=parametric)

    # structure kept out that no single cause stood for (the structure screen's, joint None) has no model to try
    todo = [k for k, f in enumerate(run.findings) if k in named or (
        f.candidate.kind.unexplained and not f.in_model
        and (f.candidate.joint, f.candidate.session) in run.unexplained.strongest)]
    labels = [f"{f.label()}: the model without it" if f.in_model else
              f"the structure kept out of joint {f.candidate.joint}: the model with it" for f in run.findings]
    out = study(final, run.kinematic, without, len(run.findings), other, s.transfer_base_poses, n_refit, s.seed,
                run.say, labels=labels, todo=todo)
    # the named causes alone there (the final model unless the GP compensator was added)
    if parametric is not final:
        run.say("transfer: the named causes alone, without the GP compensator")
    named_only = out.final if parametric is final else travel(parametric, other, out.split)
    for k, f in enumerate(run.findings):
        if k in out.gains:
            with_it, without_it = ((out.final, out.gains[k]) if f.in_model else (out.gains[k], named_only))
            f.transfer = finding_gain(with_it, without_it)
        elif f.candidate.kind.unexplained and f.in_model:
            f.transfer = finding_gain(out.final, named_only)
    return out
