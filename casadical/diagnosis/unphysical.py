"""Stage ``drop_unphysical``: every named cause must still be physics in the final model.

The rules of :mod:`casadical.stats.physics` (inside its bounds, told apart from the geometry, significant,
physically meaningful over the data): a cause that breaks one is dropped, the model refitted without it, and
the check runs again. Reads and sets ``current`` and ``accepted``; a dropped cause is never screened again
(``unexplained.excluded_causes``), and a note says why it went.
"""

from __future__ import annotations

from ..stats.physics import violations
from .candidates import compose_spec, own_parameters
from .state import DiagnosisRun


def drop_unphysical(run: DiagnosisRun) -> None:
    """Drop, one at a time, the named causes the final model holds that break a rule of
    :mod:`casadical.stats.physics` (the first such cause, in the order accepted), refitting without each."""
    if not run.accepted:
        return
    run.say("final check: is every cause still physics?")
    while run.accepted:
        accepted = run.accepted
        broken = [(c, v) for c in accepted
                  if (v := violations(run.current, run.cal, own_parameters(c, accepted) or c.parameter_names(),
                                      alpha=run.s.alpha))]
        if not broken:
            break
        cand, vs = broken[0]
        rest = [a for a in accepted if a != cand]
        run.drop_finding(cand)
        run.unexplained.excluded_causes.add(cand)
        text = "; ".join(v.text for v in vs)
        run.notes.append(f"{cand.label()} was dropped at the end: in the final model it is not physics ({text})")
        run.say(f"  dropped {cand.label()}: {text}")
        run.current = run.fit(compose_spec(rest, run.geometric), start=run.current)
        run.accepted = rest
