"""Stage ``fit_nominal``: step 1, the nominal model with its base pose (and probe mounting) fitted.

Reads the calibration and validation poses; sets ``nominal``; returns the first step. The nominal model also
checks that each session's validation poses are in their own tracker frame
(:func:`casadical.data._checks.check_validation_frames`).
"""

from __future__ import annotations

from ..data._checks import check_validation_frames
from ._candidates import compose_terms
from ._report import Step
from ._state import DiagnosisRun, StageOutcome


def fit_nominal(run: DiagnosisRun) -> StageOutcome:
    run.say("step 1: nominal model (base pose only)")
    nominal = run.nominal = run.fit(compose_terms([], geometric=False))
    step = Step("nominal", nominal.calibration, run.val_stats(nominal), True, orientation=run.val_angles(nominal))
    # each session's validation poses in its own tracker frame (files out of order would be judged in another)
    check_validation_frames(run.val, run.val_errors(nominal), nominal.calibration.mean_mm,
                            run.checks.get("allow_mismatch", False))
    run.say(f"  validation mean {step.validation.mean_mm:.4f} mm (judge only)")
    return StageOutcome(steps=(step,), recorded=((nominal, 0, None),))
