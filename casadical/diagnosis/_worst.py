"""The rules every check of a final model's worst case shares (the never-worse check, the GP compensator's, the
worst case's and the judge's): how much a worst error may rise without a word, the band the noise alone gives a
pose, held-out errors by kind of fold, and the note on a worst validation error above the kinematic model's."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import listing
from ..result import CalibrationResult
from ._validation import CVResult, kinds

#: the worst held-out (or validation) error may rise by this share at most without a word
WORST_SHARE = 0.05
#: a robust weight below this: a pose no model of the robot predicts (as the calibration's set-aside poses)
SET_ASIDE_WEIGHT = 0.5


@dataclass
class Held:
    """Held-out errors (mm) of a model on the calibration poses' folds, by kind: mean and worst."""

    mean: dict[str, float]
    worst: dict[str, float]

    @classmethod
    def of(cls, cv: CVResult, mask: np.ndarray) -> "Held":
        errs = {k: cv.kind_errors(k)[mask] * 1000 for k in kinds(cv)}
        return cls({k: float(e.mean()) for k, e in errs.items()}, {k: float(e.max()) for k, e in errs.items()})

    def worse_than(self, ref: "Held", band: float = 0.0) -> list[str]:
        """What is worse than ``ref``: a mean above it; a worst error more than :data:`WORST_SHARE` above it and
        beyond the noise ``band`` (mm, :func:`noise_band`: a worst error inside it is a draw of the noise), where
        the mean does not drop by more than that share (:meth:`traded`)."""
        out = [f"mean {k} {ref.mean[k]:.4f} -> {self.mean[k]:.4f} mm" for k in ref.mean
               if self.mean[k] > ref.mean[k] * (1 + 1e-9)]
        traded = self.traded(ref, band)
        out += [f"worst {k} {ref.worst[k]:.4f} -> {self.worst[k]:.4f} mm" for k in self.rises(ref, band)
                if k not in traded]
        return out

    def rises(self, ref: "Held", band: float = 0.0) -> list[str]:
        """Kinds of fold where the worst error is more than :data:`WORST_SHARE` above ``ref``'s and beyond ``band``."""
        return [k for k in ref.worst if self.worst[k] > max(ref.worst[k] * (1 + WORST_SHARE), band)]

    def traded(self, ref: "Held", band: float = 0.0) -> list[str]:
        """Kinds of fold where the worst error rises (:meth:`rises`) while the mean drops by more than
        :data:`WORST_SHARE`: a trade the report states, not a model worse than ``ref``. (Two sessions
        of an arm, one holding joint 1 within 6 deg: its encoder scale, fitted on that session alone, raised the
        worst error of the other session's fold 8 % and dropped its mean 21 %; the validation mean 0.136 ->
        0.032 mm.)"""
        return [k for k in self.rises(ref, band) if self.mean[k] < ref.mean[k] * (1 - WORST_SHARE)]


def noise_band(*fits: CalibrationResult) -> float:
    """The largest error (mm) the noise alone gives a pose as the robust loss sees it: where its weight falls to
    :data:`SET_ASIDE_WEIGHT` (``sqrt(3) c sigma``, about 5 sigma per axis), the narrowest of ``fits``'.

    Within it the worst held-out error of a few dozen poses is the noise of one of them (the largest of 80
    noise vectors is 3-4 sigma): a model that predicts every pose better can move it by a few um either way,
    and that says nothing of the model's worst case."""
    out = math.inf
    for f in fits:
        sigma = f.loss.sigma if f.loss.robust else (f.uncertainty.sigma if f.uncertainty is not None else 0.0)
        if sigma > 0:
            out = min(out, math.sqrt(1 / SET_ASIDE_WEIGHT ** 2 - 1) * f.loss.c * sigma * 1000)
    return out if math.isfinite(out) else 0.0


def validation_note(final: CalibrationResult, kinematic: CalibrationResult, extended: CalibrationResult | None,
                    val, val_errors, held_text: str = "", structure: tuple | None = None) -> str | None:
    """A note (judge only) when the final model's worst validation error is more than :data:`WORST_SHARE` above
    the kinematic model's, or above that of the model the GP compensator extends (``extended``; None: no
    compensator): where, how much, what the folds said (``held_text``), and the poses no model of the robot predicts.

    ``val_errors(res)``: a model's position errors (m) on ``val``. ``structure``: (the validation poses that
    structure the screen found accounts for, its finding's number and words): those poses are its largest misses,
    not bad measurements.
    """
    e_final, e_kin = val_errors(final) * 1000, val_errors(kinematic) * 1000
    rises = []
    if e_final.max() > e_kin.max() * (1 + WORST_SHARE):
        rises.append(f"{(e_final.max() / e_kin.max() - 1):.0%} above the kinematic model's {e_kin.max():.4f} mm")
    if extended is not None and extended is not final:
        e_ext = val_errors(extended) * 1000
        if e_final.max() > e_ext.max() * (1 + WORST_SHARE):
            rises.append(f"{(e_final.max() / e_ext.max() - 1):.0%} above the {e_ext.max():.4f} mm of the model the "
                         "GP compensator extends")
    if not rises:
        return None
    i = int(np.argmax(e_final))
    text = (f"judge only: the final model's worst validation error, {e_final[i]:.4f} mm at {_where(val, i)}, is "
            + " and ".join(rises))
    if held_text:
        text += f"; on the calibration poses' folds {held_text}"
    # poses no model of the robot predicts: beyond the robust loss's limit under the final model and the kinematic
    r = final.residuals(val)
    away = (final.loss.weight(np.einsum("ij,ij->i", r, r)) < SET_ASIDE_WEIGHT) & \
           (kinematic.loss.weight((e_kin / 1000) ** 2) < SET_ASIDE_WEIGHT)
    if away[i]:
        k = int(away.sum())
        order = np.flatnonzero(away)[np.argsort(-e_final[away])]
        text += (f"; that pose{f' and {k - 1} more' if k > 1 else ''} ("
                 + listing([_where(val, j) for j in order], 5)
                 + ") miss both models by far more than the noise (beyond the robust loss's limit): ")
        if structure is not None and structure[0][i]:
            text += (f"the largest misses of the structure in finding {structure[1]} ({structure[2]}), which no "
                     "term of the model holds")
        else:
            text += "likely bad measurements or a transient no model of the robot predicts"
        if k < len(e_final):
            text += (f"; without {'them' if k > 1 else 'it'} the worst error is {e_final[~away].max():.4f} mm "
                     f"(kinematic {e_kin[~away].max():.4f} mm)")
    return text


def _where(data, i: int) -> str:
    return f"{data.file(i)}:{data.line(i)}"
