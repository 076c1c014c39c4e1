"""Stage ``drop_stand_ins``: a cause is named only where it explains the structure it stands for.

A catalogue cause fitted to structure that lives elsewhere lowers the error too: a joint's encoder scale
takes part of another joint's angle error that grows with this joint's reading; a compliance and a first
harmonic take part of an angle error quadratic in the reading. Naming such a stand-in is worse than naming
nothing: an engineer acts on it. So every joint cause the search accepted is asked, in the final model of the
named causes: switched off (its parameters at zero, linearised), where does the structure it took live? The
structure screen (:class:`.structure.StructureScreen`) finds the strongest pair of covariate and effect in
that residual. Where it is the cause's own shape (its joint's angle, against its own variable: the reading
for a scale or a gear error, the gravity torque for a compliance or a backlash), the cause stands for itself.
Where it is another pair, the cause must still be significant beside a flexible term of that pair (at the
diagnosis' level): otherwise it is only the closest catalogue approximation of that structure. It is then
dropped, the model refitted without it, and the check runs again; a note says what it approximated. The
structure itself is reported by the structure screen (:mod:`.structure`), with its size.

Reads and sets ``current`` and ``accepted``; drops the findings of the stand-ins and excludes them from the
search.
"""

from __future__ import annotations

import math

import numpy as np

from ..result import CalibrationResult
from .candidates import Candidate, compose_spec
from .redundancy import own_parameters
from .state import DiagnosisRun
from .statistics import NestedTest, nested_test
from .structure import Found, StructureScreen, _weighted, describe_pair
from .validation import Linearized

#: a joint cause's own variable: its joint's reading or its gravity torque
OWN_VARIABLE = {"joint_compliance": "tau", "nonlinear_stiffness": "tau", "backlash": "tau",
                "encoder_scale": "q", "joint_periodic": "q"}
#: causes that are the first-order part of any structure of their own variable
FIRST_ORDER = ("joint_compliance", "nonlinear_stiffness", "encoder_scale")


def stands_in(current: CalibrationResult, accepted: list[Candidate], cand: Candidate, scr: StructureScreen,
              alpha: float) -> tuple[Found, str] | None:
    """The structure ``cand`` only approximates in ``current`` and why, or None."""
    if cand.cause not in OWN_VARIABLE or cand.joint is None or cand.session is not None:
        return None
    lin = Linearized.of(current, scr.cal)
    names = own_parameters(cand, accepted)
    cols = [lin.names.index(n) for n in names if n in lin.names]
    if not cols:
        return None
    keep = [k for k in range(lin.J.shape[2]) if k not in cols]
    values = np.array([current.parameters[lin.names[k]].value / lin.scale[k] for k in cols])
    r0 = lin.r - lin.J[:, :, cols] @ values       # the cause switched off
    own = (f"{OWN_VARIABLE[cand.cause]}{cand.joint}", "angle", cand.joint)
    found = scr.strongest(lin.J[:, :, keep], r0, lin.weights)
    if found is None:
        return None
    sw = np.sqrt(np.repeat(lin.weights, 3))
    rw = r0.ravel() * sw
    rest, mine, flexible = lin.J[:, :, keep], lin.J[:, :, cols], scr.columns(*own)
    significant = lambda t: t.log10_p < math.log10(alpha) and t.delta_bic < 0    # noqa: E731
    if (found.covariate, found.effect, found.joint) == own:
        # structure of its own variable: a compliance or a scale is its first-order part (a flexible term of the
        # same variable holds it), a gear error or a play must follow it: it is an approximation where a flexible
        # term of the variable leaves something beside it and it adds nothing beside that term
        if cand.cause in FIRST_ORDER:
            return None
        left = _beside(rw, sw, np.concatenate([rest, mine], axis=2), flexible)
        adds = _beside(rw, sw, np.concatenate([rest, flexible], axis=2), mine)
        if significant(left) and not significant(adds):
            return found, (f"a flexible term of its own variable takes what it does and more ({left.text()}); beside "
                           f"that term it explains nothing more ({adds.text()})")
        return None
    # where the cause's own variable is (nearly) a function of the other pair's (a parallelogram arm's torque of
    # joint 2 and its reading), a flexible term of its own shape explains that structure as well: the data cannot
    # tell them apart, and the physical cause stands
    if not significant(_beside(rw, sw, np.concatenate([rest, flexible], axis=2), found.X)):
        return None
    # the cause beside a flexible term of that structure: does it still explain anything?
    test = _beside(rw, sw, np.concatenate([rest, found.X], axis=2), mine)
    if significant(test):
        return None
    return found, f"beside a flexible term of that structure it explains nothing more ({test.text()})"


def _beside(rw: np.ndarray, sw: np.ndarray, base: np.ndarray, extra: np.ndarray) -> NestedTest:
    """The F-test of the columns ``extra`` beside ``base`` ((N, 3, k) each) on the weighted residual ``rw``."""
    A0 = _weighted(base, sw)
    A1 = np.hstack([A0, _weighted(extra, sw)])
    ssr = [float(np.sum((rw - A @ np.linalg.lstsq(A, rw, rcond=None)[0]) ** 2)) for A in (A0, A1)]
    k = int(np.linalg.matrix_rank(A1)) - int(np.linalg.matrix_rank(A0))
    return nested_test(ssr[0], A0.shape[1], ssr[1], A0.shape[1] + max(k, 1), len(rw))


def drop_stand_ins(run: DiagnosisRun) -> None:
    if not run.s.structure or not run.accepted:
        return
    run.say("final check: does every named cause explain the structure it stands for?")
    while run.accepted:
        scr = StructureScreen(run.current, run.cal, run.torques(run.current), run.s.alpha, run.s.seed)
        hit = next(((c, h) for c in run.accepted
                    if (h := stands_in(run.current, run.accepted, c, scr, run.s.alpha)) is not None), None)
        if hit is None:
            break
        cand, (found, why) = hit
        rest = [a for a in run.accepted if a != cand]
        run.drop_finding(cand)
        run.unexplained.excluded_causes.add(cand)
        where = describe_pair(found.covariate, found.effect, found.joint)
        run.notes.append(f"{cand.label()} was dropped at the end: it is only the closest catalogue approximation of "
                         f"structure it does not explain ({where}; p = {10 ** found.log10_p:.2g}): {why}; the "
                         "structure screen reports that structure and its size")
        run.say(f"  dropped {cand.label()}: the closest catalogue approximation of structure it does not explain "
                f"({where})")
        run.current = run.fit(compose_spec(rest, run.geometric), start=run.current)
        run.accepted = rest
