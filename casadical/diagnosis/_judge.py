"""Stage ``judge_final_model``: what the validation poses say of the final model, and what it leaves.

Reads ``final``, ``parametric`` and ``kinematic``; sets ``final_errors`` and ``final_val`` (its validation
errors), ``interval_coverage`` (the share of the validation poses inside the final model's 95 % interval of a
measured point, :func:`casadical.prediction.prediction_interval`) and ``set_aside`` (the poses the final
fit set aside, tested for shared structure before they are called bad measurements: :mod:`casadical.stats._outliers`;
those the structure screen brings back within the robust loss's limit are the largest misses of that structure,
``structure_misses``), and returns the notes: a worst
validation error above the kinematic model's (:func:`._worst.validation_note`), the remaining residual
(in units of the instrument's noise where it is known: ``noise``, :mod:`._noise`), the sag the model
predicts, the set-aside poses.
"""

from __future__ import annotations

import math

import numpy as np

from ..result import learning_mask
from ..stats._outliers import of_fit
from ..stats._physics import sag_note
from ._gaps import set_aside_note
from ._noise import noise_floor
from ._state import DiagnosisRun, StageOutcome
from ._worst import SET_ASIDE_WEIGHT, validation_note


def judge_final_model(run: DiagnosisRun) -> StageOutcome:
    final, cal = run.final, run.cal
    notes = []
    run.final_errors = run.val_errors(final)
    run.final_val = final_val = run.val_stats(final)
    structure = None
    if run.structures:     # the validation poses the structure the screen found brings back within the loss' limit
        _, finding = run.structures[0]
        r = run.structures[-1][0].val_left
        structure = (final.loss.weight(np.einsum("ij,ij->i", r, r)) >= SET_ASIDE_WEIGHT,
                     next(k for k, f in enumerate(run.findings, 1) if f is finding), finding.where)
    note = validation_note(final, run.kinematic, run.parametric, run.val, run.val_errors, run.held_text, structure)
    if note:
        notes.append(note)
    if final.uncertainty is not None:
        from ..prediction import prediction_interval

        radius = prediction_interval(final, run.val)
        inside = run.final_errors <= radius
        run.interval_coverage = float(inside.mean())
        notes.append(f"95 % intervals of a measured point (predict --std's interval_mm, median "
                     f"{np.median(radius) * 1000:.4f} mm) hold {int(inside.sum())} of the {len(inside)} "
                     f"validation poses ({run.interval_coverage:.1%})")
        notes.append(f"remaining calibration residual {final.uncertainty.sigma * 1000:.4f} mm per axis (rms); "
                     f"validation rms {final_val.rms_mm / math.sqrt(3):.4f} mm per axis")
    run.noise = noise_floor(cal, run.s.noise_mm, final_val.rms_mm)
    if run.noise is not None:
        notes.append(run.noise.text())
    sag = sag_note(final, cal)
    if sag:
        notes.append(sag)
    # the poses the final fit set aside: the largest misses of structure the screen found, bad measurements, or
    # structure it lacks (casadical.stats._outliers)
    set_aside = learning_mask(final, cal) == 0
    misses = {}
    for structure, finding in run.structures:
        poses = np.setdiff1d(structure.misses[set_aside[structure.misses]],
                             np.concatenate([np.zeros(0, int), *misses.values()]))
        if len(poses):
            misses[next(k for k, f in enumerate(run.findings, 1) if f is finding)] = poses
    run.set_aside = of_fit(run.parametric, cal, set_aside)
    run.set_aside.accounted = np.concatenate([np.zeros(0, int), *misses.values()])
    run.structure_misses = {n: [cal.line(int(i)) for i in poses] for n, poses in misses.items()}
    if run.set_aside.n_set_aside:
        notes.append(set_aside_note(run.set_aside, run.not_tried, cal.path, run.structure_misses,
                                    {n: run.findings[n - 1].where for n in misses}))
    return StageOutcome(notes=tuple(notes))
