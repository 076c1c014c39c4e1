"""Stage ``drop_stand_ins``: a cause is named only where it explains the structure it stands for.

A catalogue cause fitted to structure that lives elsewhere lowers the error too: a joint's encoder scale
takes part of another joint's angle error that grows with this joint's reading; a compliance and a first
harmonic take part of an angle error quadratic in the reading; a first harmonic of joint 1 takes the
instrument's azimuth error. Naming such a stand-in is worse than naming nothing: an engineer acts on it. So
every joint cause (and a mount compliance) the search accepted is asked, in the final model of the named
causes, with its parameters switched off (linearised at the fit) and a flexible term of the structure screen
(:mod:`._structure`) beside it, three questions (each test at the diagnosis' level):

1. **Where does the structure it took live?** The strongest pair of covariate and effect in that residual.
   Where it is another pair than the cause's own shape (its joint's angle against its own variable: the
   reading for a scale or a gear error, the gravity torque for a compliance or a play, the source joint's
   reading for a coupling; the base's tilt against the moment of the weights for a mount compliance), and
   that pair explains more than a flexible term of the cause's own shape does (where the two variables are
   nearly functions of each other, a parallelogram arm's torque of joint 2 and its reading, the data cannot
   tell them apart and the physical cause stands), the cause must still be significant beside a flexible
   term of that pair.
2. **Does it follow its own variable?** Where the strongest pair is its own shape, a gear error or a play
   must add something beside a flexible term of its variable, or that term must leave nothing beside it (a
   fourth harmonic standing for an error quadratic in the reading does neither). A compliance or a scale is
   the first-order part of any structure of its own variable and is not asked. A coupling and a mount
   compliance are asked: each is one of many pairs the search tries, and a straight line in another joint's
   reading (or in the moment) must not stand for a curve in it.
3. **On one session, can it be told from the instrument?** The instrument's own errors (its azimuth,
   elevation, distance) move the point as the robot's joints do; a cause that explains nothing beside a
   flexible term of one of them, where that term is significant, cannot be told from it on these data.

A cause that fails is only the closest catalogue approximation of that structure: it is dropped, the model
refitted without it, and the check runs again; a note says what it approximated and why. The structure screen
then reports the structure itself, with its size.

Reads the model under way; returns it without the stand-ins, the findings without theirs, and a note each (None:
no cause to ask).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..result import CalibrationResult
from ._candidates import Candidate, compose_terms, own_parameters
from ._state import DiagnosisRun, StageOutcome
from ._statistics import NestedTest, nested_test, set_aside_share
from ._structure import INSTRUMENT, MAX_STRUCTURES, Found, StructureScreen, describe_pair, weighted
from ._validation import Linearized


def own_shape(cand: Candidate) -> tuple[str, str, int | None] | None:
    """The (covariate, effect, joint) of the structure screen that is ``cand``'s own shape: its cause's own
    variable (:meth:`~casadical.terms._cause.Cause.own_shape`: its joint's reading or its gravity torque; a joint
    coupling's, its source joint's reading, effect joint j's angle; a mount compliance's, the moment of the
    weights, effect the base's tilt, no joint)."""
    return cand.kind.own_shape(cand)


def stands_in(current: CalibrationResult, lin: Linearized, accepted: list[Candidate], cand: Candidate,
              scr: StructureScreen, alpha: float) -> tuple[Found, str] | None:
    """The structure ``cand`` only approximates in ``current`` (``lin``: linearised at it on the calibration poses)
    and why (see the module), or None."""
    if cand.kind.axis_shape and cand.session is None:
        return _axis_stand_in(current, lin, accepted, cand, scr, alpha)
    own = own_shape(cand)
    own = None if own is None else (*own, cand.session)     # a session's own cause: its shape in that session
    if own is None or own not in scr.tried:
        return None
    cols = [lin.names.index(n) for n in own_parameters(cand, accepted) if n in lin.names]
    if not cols:
        return None
    keep = [k for k in range(lin.J.shape[2]) if k not in cols]
    values = np.array([current.parameters[lin.names[k]].value / lin.scale[k] for k in cols])
    r0 = lin.r - lin.J[:, :, cols] @ values       # the cause switched off
    sw = np.sqrt(np.repeat(lin.weights, 3))
    share = np.repeat(set_aside_share(lin.weights), 3)
    ask = _Questions(r0.ravel() * sw, sw, lin.J[:, :, keep], lin.J[:, :, cols], math.log10(alpha),
                     share if np.any(share < 1) else None)
    flexible = scr.columns(*own)
    found = scr.strongest(ask.rest, r0, lin.weights)
    if found is not None and (found.covariate, found.effect, found.joint, found.session) != own:
        # 1. the structure lives elsewhere, beyond what its own shape can take: does the cause add anything beside
        # it, and beside the structures next to it that its own shape cannot take either (a tilting floor read by
        # two sensors is two structures: a gear error took a part of the second one's beside the first; beside
        # several, at the screen's level divided among its pairs, as the search's tests are among its candidates)
        X, tried, gate = found.X, {_pair(found)}, ask.beside(flexible, found.X)
        while ask.significant(gate):
            test = ask.beside(X, ask.mine)
            if not ask.significant(test, scr.level if len(tried) > 1 else None):
                return found, (f"beside a flexible term of that structure{' and those beside it' * (len(tried) > 1)}"
                               f" it explains nothing more ({test.text()})")
            # only beside a sensor's structure, the structures of the sensors of one's own (a tilt sensor's two
            # axes): beside the flexible terms of several structures of the robot's covariates any cause explains
            # nothing more (the real UR10's compliance of joint 2, t = 33 on 2,000 poses of series A: p = 0.16)
            sensors = [pair for pair in scr.tried if pair[0] in scr.own and pair not in tried and pair != own]
            more = scr.strongest(np.concatenate([ask.rest, X], axis=2), r0, lin.weights, only=sensors) \
                if sensors and found.covariate in scr.own else None
            if more is None or len(tried) == MAX_STRUCTURES:
                break
            # a structure next to it counts where the cause's own shape cannot take it either
            gate = ask.beside(np.concatenate([X, flexible], axis=2), more.X)
            X, tried = np.concatenate([X, more.X], axis=2), tried | {_pair(more)}
    elif found is not None and not cand.kind.first_order:
        # 2. structure of its own variable: does the cause follow it?
        left = ask.beside(ask.mine, flexible)
        adds = ask.beside(flexible, ask.mine)
        if ask.significant(left) and not ask.significant(adds):
            return found, (f"a flexible term of its own variable takes what it does and more ({left.text()}); "
                           f"beside that term it explains nothing more ({adds.text()})")
    if scr.cal.sessions is None and cand.session is None:
        # 3. one session: can it be told from the instrument's own error?
        for pair in (p for p in scr.tried if p[0] in INSTRUMENT):
            X = scr.columns(*pair)
            alone, test = ask.beside(None, X), ask.beside(X, ask.mine)
            if ask.significant(alone) and not ask.significant(test):
                return Found(*pair, X, alone.log10_p, alone.text(), 0.0), (
                    f"on one session it cannot be told from the instrument's own error ({alone.text()}): beside it "
                    f"it explains nothing more ({test.text()})")
    return None


def _pair(found: Found) -> tuple:
    return found.covariate, found.effect, found.joint, found.session


def _axis_stand_in(current: CalibrationResult, lin: Linearized, accepted: list[Candidate], cand: Candidate,
                   scr: StructureScreen, alpha: float) -> tuple[Found, str] | None:
    """A linear axis' straightness or carriage angle that only approximates structure of another shape: the
    strongest structure in what it takes (the cause switched off) explains more than the cause does (a flexible
    term of it is significant beside the cause's), and beside that term the cause explains nothing more (a
    carriage's yaw standing for a column's position error along it: the tool's reach forward turns the yaw
    into a vertical move)."""
    cols = [lin.names.index(n) for n in own_parameters(cand, accepted) if n in lin.names]
    if not cols:
        return None
    keep = [k for k in range(lin.J.shape[2]) if k not in cols]
    values = np.array([current.parameters[lin.names[k]].value / lin.scale[k] for k in cols])
    r0 = lin.r - lin.J[:, :, cols] @ values
    sw = np.sqrt(np.repeat(lin.weights, 3))
    share = np.repeat(set_aside_share(lin.weights), 3)
    ask = _Questions(r0.ravel() * sw, sw, lin.J[:, :, keep], lin.J[:, :, cols], math.log10(alpha),
                     share if np.any(share < 1) else None)
    found = scr.strongest(ask.rest, r0, lin.weights)
    if found is None:
        return None
    if not ask.significant(ask.beside(ask.mine, found.X)):
        return None         # the structure is no more than the cause takes: the cause's own (its term is flexible)
    test = ask.beside(found.X, ask.mine)
    if not ask.significant(test):
        return found, f"beside a flexible term of that structure it explains nothing more ({test.text()})"
    return None


@dataclass
class _Questions:
    """F-tests on the residual ``rw`` (weighted, the cause switched off) of columns beside the model's other
    parameters (``rest``) and more: ``mine``, the cause's own columns."""

    rw: np.ndarray
    sw: np.ndarray
    rest: np.ndarray
    mine: np.ndarray
    level: float
    #: per equation, how much a pose's term counts in the tests' noise scale (:func:`._statistics.set_aside_share`)
    share: np.ndarray | None = None
    #: the fits made, by the column blocks beside the rest (their ids; the blocks held, so no id is reused)
    fits: dict = field(default_factory=dict)

    def significant(self, test: NestedTest, level: float | None = None) -> bool:
        return test.log10_p < (self.level if level is None else level) and test.delta_bic < 0

    def fit(self, blocks: tuple) -> tuple[np.ndarray, int]:
        """:func:`_fit` of ``rw`` on the rest and the column ``blocks`` beside it, in that order; made once: the
        questions ask the same fits again (the rest alone before each of the instrument's pairs, the rest and that
        pair's term for both of its tests)."""
        key = tuple(id(b) for b in blocks)
        if key not in self.fits:
            A = weighted(np.concatenate([self.rest, *blocks], axis=2) if blocks else self.rest, self.sw)
            self.fits[key] = blocks, _fit(A, self.rw)
        return self.fits[key][1]

    def beside(self, more: np.ndarray | None, extra: np.ndarray) -> NestedTest:
        """The test of ``extra`` beside the rest of the model and ``more`` ((N, 3, k) each)."""
        base = () if more is None else (more,)
        (r0, k0), (r1, k1) = self.fit(base), self.fit((*base, extra))
        n0 = self.rest.shape[2] + sum(b.shape[2] for b in base)
        res = [r0, r1]
        ssr = [float(r @ r) for r in res]
        k = k1 - k0
        # a robust fit's set-aside poses count in the noise scale by their influence, as in the search's tests
        noise = None if self.share is None else float((res[1] ** 2) @ self.share)
        return nested_test(ssr[0], n0, ssr[1], n0 + max(k, 1), len(self.rw), noise)


def _fit(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int]:
    """The least-squares residual of ``b`` on the columns ``A`` and their rank, from one singular value
    decomposition (``lstsq``'s and ``matrix_rank``'s default cut-off: machine epsilon times the larger
    dimension times the largest singular value)."""
    U, sv, _ = np.linalg.svd(A, full_matrices=False)
    Uk = U[:, sv > np.finfo(float).eps * max(A.shape) * sv[0]] if sv.size else U[:, :0]
    return b - Uk @ (Uk.T @ b), Uk.shape[1]


def drop_stand_ins(run: DiagnosisRun) -> StageOutcome | None:
    if not run.s.structure or not run.accepted:
        return None
    run.say("final check: does every named cause explain the structure it stands for?")
    model, findings, notes = run.under_way(), run.findings, []
    while model.accepted:
        current, accepted = model.current, list(model.accepted)
        scr = StructureScreen(current, run.cal, run.torques(current), run.s.alpha, run.s.seed)
        lin = run.linearized(current)      # once a round: every cause is asked at the same fit
        hit = next(((c, h) for c in accepted
                    if (h := stands_in(current, lin, accepted, c, scr, run.s.alpha)) is not None), None)
        if hit is None:
            break
        cand, (found, why) = hit
        rest = [a for a in accepted if a != cand]
        findings = [f for f in findings if f.candidate != cand]
        where = describe_pair(found.covariate, found.effect, found.joint, found.joint is not None
                              and run.robot.joints[found.joint - 1].prismatic, found.session)
        notes.append(f"{cand.label()} was dropped at the end: it is only the closest catalogue approximation of "
                     f"structure it does not explain ({where}; p = {10 ** found.log10_p:.2g}): {why}; the "
                     "structure screen reports that structure and its size")
        run.say(f"  dropped {cand.label()}: the closest catalogue approximation of structure it does not explain "
                f"({where})")
        model = model.holding(run.fit(compose_terms(rest, model.geometric), start=current), rest)
    return StageOutcome(notes=tuple(notes), findings=tuple(findings), model=model)
