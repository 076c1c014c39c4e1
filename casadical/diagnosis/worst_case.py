"""Stage ``keep_worst_case``: where the final model's worst validation error is above the kinematic model's, which
correction to drop to restore it, and what that costs in the mean; with ``worst_case`` that is the final model.

Reads ``final``, ``parametric``, ``kinematic``, ``accepted``, ``geometric``, ``final_spec`` and the search's
``history`` (the accepted models of the named causes); adds a note when the final model's worst validation error
is more than :data:`~.never_worse.WORST_SHARE` above the kinematic model's, like with like (the poses both miss
by more than the noise, beyond each one's robust loss's half-weight radius :func:`~.never_worse.noise_band`, are left
out: a bad measurement or a transient no model of the robot predicts, which :func:`~.never_worse.validation_note`
names). The note names the first of these models whose worst error there is not: the final model without the
GP compensator; then the latest models of the search, fewer causes each; at last the kinematic model itself;
what it drops and its validation mean beside the final model's. With
:attr:`~.settings.DiagnosisSettings.worst_case` (``diagnose --worst-case``) that model becomes the final model
(``final``, ``final_spec``, ``parametric``, ``current``, ``accepted``, ``geometric``; the findings of what it
drops removed). The validation poses judge here, as everywhere, and decide only when the user asks it: a safe
worst case chosen over a lower mean.
"""

from __future__ import annotations

import numpy as np

from .candidates import compose_spec
from .never_worse import WORST_SHARE, noise_band
from .state import DiagnosisRun


def keep_worst_case(run: DiagnosisRun) -> None:
    e_kin, e_final = run.val_errors(run.kinematic) * 1000, run.val_errors(run.final) * 1000
    # beyond each model's own half-weight radius, as validation_note's "miss both models"
    b_kin, b_final = noise_band(run.kinematic) or np.inf, noise_band(run.parametric) or np.inf
    like = ~((e_kin > b_kin) & (e_final > b_final))
    if not like.any():
        return
    e_kin, e_final = e_kin[like], e_final[like]
    limit = e_kin.max() * (1 + WORST_SHARE)
    if e_final.max() <= limit:
        return
    compensated = run.final is not run.parametric
    options = []
    if compensated:
        options.append((run.parametric, list(run.accepted), run.geometric))
    options += [(fit, list(earlier), fit.model.geometric_free) for earlier, fit in reversed(run.history)
                if set(earlier) <= set(run.accepted) and fit is not run.parametric]
    options.append((run.kinematic, [], True))
    for fit, earlier, geo in options:
        e = run.val_errors(fit)[like] * 1000
        if e.max() <= limit:
            break
    dropped = [a for a in run.accepted if a not in earlier]
    what = (["the GP compensator"] if compensated else []) + [a.label() for a in dropped]
    if fit is run.kinematic:
        what = ["every correction (the kinematic model)"]
    n_out = int((~like).sum())
    mean0, mean1 = run.val_errors(run.final).mean() * 1000, run.val_errors(fit).mean() * 1000
    text = (f"worst case: the final model misses a validation pose by {e_final.max():.4f} mm, more than "
            f"{WORST_SHARE:.0%} above the kinematic model's worst {e_kin.max():.4f} mm"
            + (f" (leaving out {n_out} pose{'s' * (n_out > 1)} both miss by more than the noise, beyond "
               f"{b_kin:.4f} and {b_final:.4f} mm)"
               if n_out else "")
            + "; without " + ", ".join(what)
            + f" it is {e.max():.4f} mm, at a cost in the validation mean of {mean0:.4f} -> {mean1:.4f} mm"
            + ("; --worst-case made that the final model" if run.s.worst_case else
               "; diagnose --worst-case makes that the final model"))
    run.notes.append(text)
    run.say(f"  {text}")
    if not run.s.worst_case:
        return
    if compensated:
        run.findings = [f for f in run.findings if not (f.cause == "unexplained" and "shrink" in f.holds_up)]
    for a in dropped:
        run.drop_finding(a)
    run.final = run.parametric = run.current = fit
    run.accepted, run.geometric = earlier, geo
    run.final_spec = "kinematic" if fit is run.kinematic else compose_spec(earlier, geo)
