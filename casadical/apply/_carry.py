"""A calibration taken to new poses that checks what it carries.

``calibrate FINAL.json OTHER.csv --model kinematic`` estimates the geometry again on OTHER's poses and
carries every other cause of FINAL as it was fitted: a compliance, a gear error, an encoder scale of the
robot. A cause fitted in another session need not hold in this one (a gear error of one session, a
compliance that stood in for something else): carried blindly it can make the result worse than a plain
kinematic calibration of OTHER (issue 25: better in 21 of 36 UR10 session pairs, worse in 8).

:func:`carry` judges each carried cause on OTHER's own poses, on cross-validation folds there as the
diagnosis judges (random, time-blocked, joint-range-blocked: :mod:`casadical.diagnosis._validation`,
linearised at the transfer's fit): the cause **kept** as carried, **refitted** on these poses, or
**dropped**, whichever predicts OTHER's held-out poses best (the mean over the kinds of fold); it is kept
or refitted only when that beats dropping it. The chosen model is then fitted for real and compared on the
same folds with a kinematic calibration of OTHER from the robot: if it does worse, that calibration is the
result. Every cause's fate is a note of the result, with its held-out figures.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np

from ..calibration import calibrate
from ..data._calibration_file import restore_term
from ..data._measurements import Measurements
from ..errors import CasadicalWarning
from ..model._symbolic import Model
from ..result import CalibrationResult
from ..stats._physics import Cause, term_causes

#: cross-validation folds on the new poses
FOLDS = 5
#: fewer new poses than this: the causes are carried as they are, unjudged (a note says so)
MIN_POSES = 30
#: the fates of a carried cause, the simplest first: a fate within TIE of the best is preferred when simpler
#: (keep only what helps)
FATES = ("dropped", "kept", "refitted")
TIE = 0.005


def carry(prior: CalibrationResult, data: Measurements, model: str = "kinematic", *, seed: int = 0,
          warn: bool = True, fix: tuple[str, ...] = (), **options) -> CalibrationResult:
    """``calibrate(prior, data, model)``, each carried cause judged on ``data``'s folds (see the module).

    Parameters
    ----------
    prior : CalibrationResult
        The calibration taken further.
    data : Measurements
        The new poses (with measured positions).
    model : str
        What is estimated again (:func:`casadical.calibrate`); the causes are judged when it refits the
        geometry (``kinematic``), otherwise they are carried as they are.
    seed : int
        Of the random folds.
    warn : bool
        Warn with the notes on the causes dropped or refitted.
    fix, **options
        As :func:`casadical.calibrate` (solver, robust loss, checks, ...), for every fit.
    """
    frozen = calibrate(prior, data, model, warn=warn, fix=fix, **options)
    causes = [c for c in term_causes(frozen) if all(frozen.parameters[n].fixed for n in c.parameters)
              and any(frozen.parameters[n].value != frozen.parameters[n].nominal for n in c.parameters)]
    refits = any(p.group != "base" and not p.fixed for p in frozen.parameters.select(term="geometric"))
    if not causes or not refits:
        return frozen
    if len(data) < MIN_POSES:
        frozen.notes.append(f"carried as fitted, not judged: {len(data)} poses are too few to judge "
                            f"{', '.join(c.label for c in causes)} on these poses ({MIN_POSES} or more)")
        return frozen
    from ..diagnosis._validation import joint_levers, schemes

    folds = schemes(data.q, data.rows, FOLDS, seed, joint_levers(frozen.model.robot, data), sessions=data.sessions)
    judge = _Judge(frozen, causes, data, folds)
    fates = judge.choose()
    plain = calibrate(frozen.model.robot, data, model, warn=False, fix=fix, **_plain_options(options))
    if all(f == "kept" for f in fates):
        result = frozen
    else:
        result = _fit(prior, causes, fates, data, model, fix, options)
    mask = judge.mask & _kept(plain, data)
    mine, theirs = _held_mean(result, data, folds, mask), _held_mean(plain, data, folds, mask)
    notes = [judge.note(i, f) for i, f in enumerate(fates)]
    said = [n for n, f in zip(notes, fates) if f != "kept"]        # warned: what was not carried as fitted
    if mine > theirs:
        said.append(f"the calibration carried with these causes did worse on these poses' folds than a kinematic "
                    f"calibration of them (held-out mean {theirs:.4f} -> {mine:.4f} mm): the result is that "
                    "kinematic calibration, nothing carried")
        plain.notes += notes + said[-1:]
        result = plain
    else:
        result.notes += notes + [f"never worse than a kinematic calibration of these poses: held-out mean "
                                 f"{mine:.4f} mm against its {theirs:.4f} mm"]
    if warn:
        for n in said:
            warnings.warn(n, CasadicalWarning, stacklevel=2)
    return result


class _Judge:
    """The transfer's fit linearised with every carried cause's columns: each cause kept, refitted or dropped,
    judged on the folds by one Gauss-Newton step per fold."""

    def __init__(self, frozen: CalibrationResult, causes: list[Cause], data: Measurements, folds):
        from ..diagnosis._validation import Linearized

        params = frozen.parameters.copy()
        for c in causes:
            for n in c.parameters:
                params[n].fixed = False
        self.lin = Linearized.of(replace(frozen, parameters=params), data)
        names = self.lin.names
        self.cols = [[names.index(n) for n in c.parameters] for c in causes]
        own = {k for cs in self.cols for k in cs}
        self.base_cols = [k for k in range(len(names)) if k not in own]
        self.folds = folds
        self.mask = self.lin.weights >= 0.5
        self.causes = causes
        self.scores: dict = {}
        self.fates = ["kept"] * len(causes)

    def score(self, fates: list[str]) -> float:
        """Held-out mean (mm) over the kinds of fold with each cause's fate."""
        from ..diagnosis._validation import by_kind, linear_cv

        key = tuple(fates)
        if key not in self.scores:
            lin = self.lin
            cols = self.base_cols + [k for c, f in enumerate(fates) if f == "refitted" for k in self.cols[c]]
            r = lin.r.copy()
            for c, f in enumerate(fates):
                if f == "dropped":      # its parameters back at zero
                    r -= lin.J[:, :, self.cols[c]] @ lin.x0[self.cols[c]]
            means = by_kind(linear_cv(lin.J[:, :, cols], r, lin.weights, self.folds), self.mask)
            self.scores[key] = float(np.mean(list(means.values())))
        return self.scores[key]

    def choose(self) -> list[str]:
        """Each cause's fate, one cause at a time (the others at their fates so far), twice over."""
        fates = ["kept"] * len(self.causes)
        for _ in range(2):
            for c in range(len(fates)):
                scores = [self.score(fates[:c] + [f] + fates[c + 1:]) for f in FATES]
                fates[c] = next(f for f, sc in zip(FATES, scores) if sc <= min(scores) * (1 + TIE))
        self.fates = fates
        none = ["dropped"] * len(fates)
        return fates if self.score(fates) < self.score(none) else none

    def note(self, c: int, fate: str) -> str:
        """The fate of cause ``c`` in words, with its held-out figures (the other causes at their fates)."""
        words = {"kept": "kept as fitted", "refitted": "refitted on these poses",
                 "dropped": "dropped: it does not help on these poses"}[fate]
        with_it, without, refit = (self.score(self.fates[:c] + [f] + self.fates[c + 1:])
                                   for f in ("kept", "dropped", "refitted"))
        return (f"carried: {self.causes[c].label} {words} (held-out mean on these poses, the other causes as chosen: "
                f"{without:.4f} mm without it, {with_it:.4f} mm as fitted, {refit:.4f} mm refitted)")


def _fit(prior: CalibrationResult, causes: list[Cause], fates: list[str], data: Measurements,
         model: str, fix: tuple[str, ...], options: dict) -> CalibrationResult:
    """The transfer with the dropped causes out of the model and the refitted ones estimated again."""
    dropped = {n for c, f in zip(causes, fates) if f == "dropped" for n in c.parameters}
    refit = {n for c, f in zip(causes, fates) if f == "refitted" for n in c.parameters}
    m = prior.model
    terms = [t for t in (_without(t, dropped, m) for t in m.terms) if t is not None]
    built = Model(m.robot, terms if m.geometric_free else terms[1:], jit=m.jit)
    params = built.parameters.copy()
    for p in params:            # every value, std and flag of the calibration's
        src = prior.parameters[p.name]
        p.value, p.std, p.fixed, p.identifiable, p.reason = src.value, src.std, src.fixed, src.identifiable, src.reason
    pruned = replace(prior, model=built, parameters=params)
    named = [t for t in pruned.model.terms if any(p.name in refit for p in t.parameters(m.robot))]
    hold = tuple(p.name for t in named for p in t.parameters(m.robot) if p.name not in refit)
    spec = "+".join([model] + [t.spec() for t in named])
    return calibrate(pruned, data, spec, warn=False, fix=tuple(fix) + hold, **options)


def _without(term, dropped: set[str], model: Model):
    """``term`` without the parameters ``dropped`` (a joint, a harmonic); None when none is left."""
    names = [p.name for p in term.parameters(model.robot)]
    gone = [n for n in names if n in dropped]
    if not gone:
        return term
    if len(gone) == len(names):
        return None
    if hasattr(term, "harmonics"):
        left = [jh for jh, s in zip(term.harmonics, names[0::2]) if s not in dropped]
        return type(term)(left)
    if hasattr(term, "pairs"):           # a joint coupling: one parameter per (joint, source joint) pair
        return type(term)(pairs=[jk for jk, n in zip(term.pairs, names) if n not in dropped])
    left = [p.joint for p in term.parameters(model.robot) if p.name not in dropped]
    return restore_term(type(term)(joints=sorted(set(left))), term.settings())


def _plain_options(options: dict) -> dict:
    """The options of a calibration from the robot (a calibration's own ones left out)."""
    return {k: v for k, v in options.items() if k != "keep_compensator"}


def _kept(res: CalibrationResult, data: Measurements) -> np.ndarray:
    r = res.residuals(data)
    return res.loss.weight(np.einsum("ij,ij->i", r, r)) >= 0.5


def _held_mean(res: CalibrationResult, data: Measurements, folds, mask: np.ndarray) -> float:
    from ..diagnosis._validation import Linearized, by_kind

    means = by_kind(Linearized.of(res, data).cv(folds), mask)
    return float(np.mean(list(means.values()))) if means else math.inf
