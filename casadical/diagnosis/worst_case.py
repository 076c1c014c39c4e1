"""Stage ``keep_worst_case``: where the final model's worst validation error is above the kinematic model's, which
correction to drop to restore it, and what that costs in the mean; with ``worst_case`` that is the final model.

Reads ``final``, ``parametric``, ``kinematic``, ``accepted``, ``geometric``, ``final_spec`` and the search's
``history`` (the accepted models of the named causes); adds a note when the final model's worst validation error
is more than :data:`~.never_worse.WORST_SHARE` above the kinematic model's: the first of these models whose
worst error is not (the final model without the GP compensator; then the latest models of the search, fewer
causes each; at last the kinematic model itself), what it drops and its validation mean beside the final
model's. With :attr:`~.settings.DiagnosisSettings.worst_case` (``diagnose --worst-case``) that model becomes
the final model (``final``, ``final_spec``, ``parametric``, ``current``, ``accepted``, ``geometric``; the
findings of what it drops removed). The validation poses judge here, as everywhere, and decide only when the
user asks it: a safe worst case chosen over a lower mean.
"""

from __future__ import annotations

from .candidates import compose_spec
from .never_worse import WORST_SHARE
from .state import DiagnosisRun


def keep_worst_case(run: DiagnosisRun) -> None:
    e_kin, e_final = run.val_errors(run.kinematic) * 1000, run.val_errors(run.final) * 1000
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
        e = run.val_errors(fit) * 1000
        if e.max() <= limit:
            break
    dropped = [a for a in run.accepted if a not in earlier]
    what = (["the GP compensator"] if compensated else []) + [a.label() for a in dropped]
    if fit is run.kinematic:
        what = ["every correction (the kinematic model)"]
    text = (f"worst case: the final model's worst validation error, {e_final.max():.4f} mm, is above the kinematic "
            f"model's {e_kin.max():.4f} mm by more than {WORST_SHARE:.0%}; without " + ", ".join(what)
            + f" it is {e.max():.4f} mm, at a cost in the validation mean of {e_final.mean():.4f} -> {e.mean():.4f} mm"
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
