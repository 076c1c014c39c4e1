"""Stage ``drop_unphysical``: every named cause must still be physics in the final model.

The rules of :mod:`casadical.stats._physics` (inside its bounds, told apart from the geometry, significant,
physically meaningful over the data): a cause that breaks one is dropped, the model refitted without it, and
the check runs again. Reads the model under way; returns it without the causes it drops, the findings without
theirs, and a note each saying why it went (None: no cause to ask).
"""

from __future__ import annotations

from ..stats._physics import violations
from ._candidates import compose_terms, own_parameters
from ._state import DiagnosisRun, StageOutcome


def drop_unphysical(run: DiagnosisRun) -> StageOutcome | None:
    """Drop, one at a time, the named causes the final model holds that break a rule of
    :mod:`casadical.stats._physics` (the first such cause, in the order accepted), refitting without each."""
    if not run.accepted:
        return None
    run.say("final check: is every cause still physics?")
    model, findings, notes = run.under_way(), run.findings, []
    while model.accepted:
        accepted = list(model.accepted)
        broken = [(c, v) for c in accepted
                  if (v := violations(model.current, run.cal, own_parameters(c, accepted) or c.parameter_names(),
                                      alpha=run.s.alpha))]
        if not broken:
            break
        cand, vs = broken[0]
        rest = [a for a in accepted if a != cand]
        findings = [f for f in findings if f.candidate != cand]
        text = "; ".join(v.text for v in vs)
        notes.append(f"{cand.label()} was dropped at the end: in the final model it is not physics ({text})")
        run.say(f"  dropped {cand.label()}: {text}")
        model = model.holding(run.fit(compose_terms(rest, model.geometric), start=model.current), rest)
    return StageOutcome(notes=tuple(notes), findings=tuple(findings), model=model)
