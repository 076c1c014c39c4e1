"""Stage ``drop_redundant``: after the search, is every accepted cause still needed in the final model?

Causes are accepted one at a time, physical ones before periodic ones, so
an early cause can stand in for part of a later, stronger one (a
compliance of the joint whose gear error is found two rounds later). At
the end each named cause is tested again against the final model: the
model without it (its parameters at zero, the others refitted by one
Gauss-Newton step from the final fit) must fit significantly worse, at the
same corrected level and by BIC. The weakest cause that fails is refitted
without it for real; if that confirms, it is dropped and the test runs
again on the new model.

Reads the model under way (with more than one cause); returns it without the causes it drops, the findings
without theirs, and a note each (None: nothing to ask).
"""

from __future__ import annotations

import math

import numpy as np

from ..result import CalibrationResult
from ._candidates import Candidate, compose_terms, own_parameters
from ._state import DiagnosisRun, StageOutcome
from ._statistics import NestedTest, nested_test, noise_ssr
from ._validation import Linearized


def without_tests(current: CalibrationResult, lin: Linearized, accepted: list[Candidate], n_eq: int
                  ) -> list[tuple[Candidate, NestedTest]]:
    """For each accepted cause: the F-test of the final model against the model without it (linearised: ``lin``,
    ``current`` linearised on the calibration poses)."""
    N, _, p = lin.J.shape
    sw = np.repeat(np.sqrt(lin.weights), 3)
    X = lin.J.reshape(-1, p) * sw[:, None]
    r = lin.r.ravel() * sw
    ssr = float(r @ r)
    noise = noise_ssr(lin)
    out = []
    for cand in accepted:
        cols = [lin.names.index(n) for n in own_parameters(cand, accepted) if n in lin.names]
        if not cols:
            continue
        keep = [k for k in range(p) if k not in cols]
        # the cause switched off (its parameters at zero), the rest refitted by one step
        r0 = r - X[:, cols] @ np.array([current.parameters[lin.names[k]].value / lin.scale[k] for k in cols])
        Q, _ = np.linalg.qr(X[:, keep])
        r_red = r0 - Q @ (Q.T @ r0)
        out.append((cand, nested_test(float(r_red @ r_red), len(keep), ssr, p, n_eq, noise)))
    return out


def drop_redundant(run: DiagnosisRun) -> StageOutcome | None:
    """Drop, one at a time, the accepted causes the final model no longer needs (see the module)."""
    if len(run.accepted) <= 1:
        return None
    run.say("final check: is every cause still needed?")
    model, findings, notes = run.under_way(), run.findings, []
    while model.accepted:
        current, accepted = model.current, list(model.accepted)
        level = math.log10(run.s.alpha / max(run.n_tests(run.candidates(current, accepted)), 1))
        tests = without_tests(current, run.linearized(current), accepted, run.n_eq)
        failing = [(c, t) for c, t in tests if not (t.log10_p < level and t.delta_bic < 0)]
        if not failing:
            break
        cand, test = max(failing, key=lambda ct: ct[1].log10_p)
        rest = [a for a in accepted if a != cand]
        run.say(f"  {cand.label()} may no longer be needed: the model refitted without it")
        refit = run.fit(compose_terms(rest, model.geometric), start=current)
        full = run.compare(refit, current, current.loss)
        if full.log10_p < level and full.delta_bic < 0:
            break       # the one-step estimate was too pessimistic: it is still supported
        findings = [f for f in findings if f.candidate != cand]
        later = [a.label() for a in accepted[accepted.index(cand) + 1:]]
        notes.append(f"{cand.label()} was dropped at the end: with "
                     + (", ".join(later) if later else "the other causes")
                     + f" in the model it no longer explains anything ({full.text()})")
        run.say(f"  dropped {cand.label()}: not needed once the later causes are in the model ({full.text()})")
        model = model.holding(refit, rest)
    return StageOutcome(notes=tuple(notes), findings=tuple(findings), model=model)
