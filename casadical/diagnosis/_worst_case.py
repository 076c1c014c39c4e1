"""Stage ``keep_worst_case``: where the final model's worst validation error is above the kinematic model's, which
corrections to drop to restore it, and what that costs in the mean; with ``worst_case`` that is the final model.

Reads ``final``, ``parametric``, ``kinematic``, ``accepted``, ``geometric`` and ``final_spec``; adds a note when the
final model's worst validation error is more than :data:`~._worst.WORST_SHARE` above the kinematic model's,
like with like (the poses both miss by more than the noise, beyond each one's robust loss's half-weight radius
:func:`~._worst.noise_band`, are left out: a bad measurement or a transient no model of the robot predicts,
which :func:`~._worst.validation_note` names). The note names the corrections whose dropping restores it at
the least cost in the validation mean, among: the GP compensator alone; the named causes, dropped one at a time
(backward, each time the one whose dropping lowers the worst error most, at most :data:`MAX_DROPS`; of the
causes still kept only the :data:`SCREENED` a linearised screen ranks first are refitted in full, :func:`_screened`),
the model refitted without them, with the GP compensator kept (its process, hyperparameters and shrinkage the same,
conditioned on the refitted model's residuals) and without it; at last the kinematic model itself. It names the
worst pose and, where it can be said, why the corrections dropped raise the error there (:func:`unchecked_terms`: a
term no calibration pose checks there: a periodic term in a gap of its joint's readings, a compliance or an encoder
scale beyond the range of its torque or reading). (A correction
can raise the worst error without extrapolating beyond its data: on UR10 series A, seeds 0 and 2, the worst
validation poses have joint 2 at -169 deg, inside the calibration poses' -176 .. 5 deg, where few of them are,
and the periodic terms of joints 1-3 add up there; the GP compensator lowers it, so dropping it first, as the
note did, cost the mean 0.160 -> 0.267 mm.) With :attr:`~._settings.DiagnosisSettings.worst_case`
(``diagnose --worst-case``) that model becomes the final model (``final``, ``final_spec``, ``parametric``,
``current``, ``accepted``, ``geometric``; the findings of what it drops removed). The validation poses judge
here, as everywhere, and decide only when the user asks it: a safe worst case chosen over a lower mean.
"""

from __future__ import annotations

import numpy as np

from ..calibration._per_session import with_gp_compensator
from ..compensators._gp import ResidualGP
from ..data._measurements import session_index
from ..terms import SessionLocal
from ._candidates import compose_terms, model_spec, own_parameters
from ._state import DiagnosisRun, FinalModel, StageOutcome
from ._validation import Linearized
from ._worst import WORST_SHARE, noise_band

#: the named causes dropped one at a time at most this many times before the kinematic model is the answer
MAX_DROPS = 4
#: in each round only this many named causes are refitted without in full (:func:`_screened`)
SCREENED = 4


def _processes(result) -> dict:
    """The GP compensator's processes of ``result``'s model, by session (None: the data's one session)."""
    out = {}
    for t in result.model.terms:
        inner = t.inner if isinstance(t, SessionLocal) else t
        if inner.name == "gp_compensator" and inner.gp is not None:
            out[t.session_name if isinstance(t, SessionLocal) else None] = inner.gp
    return out


def _rows(data, s: str | None) -> np.ndarray:
    """The rows of ``data`` in session ``s`` (None: every row, a cause or process of the data's one session or of
    the robot)."""
    return np.arange(len(data)) if s is None else session_index(data).get(s, np.zeros(0, int))


def _learnt_at(g, cal, s) -> np.ndarray:
    """The calibration poses (rows) the process ``g`` of session ``s`` learnt from, in its order."""
    rows = _rows(cal, s)
    where = {q.tobytes(): i for i, q in zip(rows, np.ascontiguousarray(cal.q[rows]))}
    return np.array([where[q.tobytes()] for q in np.ascontiguousarray(g.X)])


def _conditioned(g, Y: np.ndarray):
    """The process ``g`` (hyperparameters, shrinkage, weights, interval factor) conditioned on residuals ``Y``."""
    std = Y.std(axis=0)
    return ResidualGP(g.X, Y, g.length_scales, g.signal_var, g.noise_var, Y.mean(axis=0), np.where(std > 0, std, 1.0),
                      g.max_std_ratio, g.shrink, g.interval_k, g.pose_weights, g.nu)


def _reconditioned(gps: dict, fit, cal) -> dict:
    """The same processes conditioned on ``fit``'s residuals at the poses each learnt from."""
    r = fit.residuals(cal)
    return {s: _conditioned(g, r[_learnt_at(g, cal, s)] @ fit.base_matrix(s)[:3, :3]) for s, g in gps.items()}


def _screened(run: DiagnosisRun, fit, gps: dict, kept: list, like: np.ndarray) -> list:
    """The :data:`SCREENED` causes of ``kept`` worth refitting without in full: for each, ``fit`` without it refitted
    by one Gauss-Newton step on the calibration poses (linearised at ``fit``: its parameters switched off, the
    others' step from the normal equations with its rows and columns taken out), the GP compensator's processes
    ``gps`` conditioned on the residuals that leaves (their hyperparameters the same, as the full search keeps
    them), and both taken to the validation poses (linearised there too); those whose worst error over ``like``
    is lowest. A screen, not a decision: the ones it keeps are refitted in full."""
    if len(kept) <= SCREENED:
        return list(kept)
    lc, lv = run.linearized(fit), Linearized.of(fit, run.val)
    p = lc.J.shape[2]
    Jw = (lc.J * np.sqrt(lc.weights)[:, None, None]).reshape(-1, p)
    A, g = Jw.T @ Jw, Jw.T @ (lc.r * np.sqrt(lc.weights)[:, None]).reshape(-1)
    x = np.array([fit.parameters[n].value for n in lc.names]) / lc.scale
    procs = []    # per process: its learnt rows, base rotation, validation rows, weights and kernels there
    for s, gp in gps.items():
        rows = _rows(run.val, s)
        q = run.val.q[rows]
        procs.append((gp, _learnt_at(gp, run.cal, s), fit.base_matrix(s)[:3, :3], rows, gp.weight(q),
                      [gp.kernel(q, gp.X, a) for a in range(3)]))

    def worst_without(a) -> float:
        cols = [lc.names.index(n) for n in own_parameters(a, kept) if n in lc.names]
        if not cols:
            return np.inf
        rest = np.setdiff1d(np.arange(p), cols)
        d = -np.linalg.lstsq(A[np.ix_(rest, rest)], g[rest] - A[np.ix_(rest, cols)] @ x[cols], rcond=None)[0]
        rc = lc.r + lc.J[:, :, rest] @ d - lc.J[:, :, cols] @ x[cols]
        rv = lv.r + lv.J[:, :, rest] @ d - lv.J[:, :, cols] @ x[cols]
        for gp, learnt, R, rows, w, K in procs:
            new = _conditioned(gp, rc[learnt] @ R)
            Z = np.column_stack([K[k] @ new.alpha[:, k] for k in range(3)]) * new.y_std + new.y_mean
            rv[rows] -= (Z * w[:, None]) @ R.T
        return float(np.linalg.norm(rv[like], axis=1).max())
    return sorted(kept, key=worst_without)[:SCREENED]


def _errors(run: DiagnosisRun, fit, gps: dict | None) -> np.ndarray:
    """Validation position errors (mm) of ``fit`` plus the processes ``gps`` (None: none), computed without
    building the model."""
    if not gps:
        return run.val_errors(fit) * 1000
    r = fit.residuals(run.val)
    for s, g in gps.items():
        rows = _rows(run.val, s)
        if len(rows):
            q = run.val.q[rows]
            w = g.weight(q)     # first: its uncertainty keeps the posterior's answer, which predict then takes
            r[rows] -= (g.predict(q) * w[:, None]) @ fit.base_matrix(s)[:3, :3].T
    return np.linalg.norm(r, axis=1) * 1000


def unchecked_terms(run: DiagnosisRun, i: int, dropped: list) -> str:
    """Why dropping ``dropped`` lowers the worst error at validation pose ``i``, where it can be said: a term among
    them that no calibration pose checks there.

    - A periodic term whose joint reads there inside a gap of the calibration poses' readings (of its session, for
      a session's own term) wider than half the term's period, or beyond them by more than a quarter of it: a
      harmonic's value there follows from its amplitude and phase, fitted elsewhere on the joint's range, where a
      gear's error need not repeat (UR10 series A, seed 0: joint 2 at -168.9 deg, in a gap from -175.2 to -141.9
      deg, harmonic 32's period 11.25 deg).
    - A term linear in its covariate (a compliance and its progressive part in the joint's gravity torque, an
      encoder scale in its reading) whose covariate there lies beyond the calibration poses' range by more than a
      tenth of it: the term extrapolates, where a drive's stiffness need not stay linear.

    "" when none is."""
    cal, val = run.cal, run.val
    prismatic = run.kinematic.model.robot.prismatic
    torques = None
    said = []
    for a in dropped:
        by = a.kind.unchecked_by        # how a cause can go unchecked: its torque, reading or period
        if a.joint is None or by is None:
            continue
        j = a.joint - 1
        rows = _rows(cal, a.session)
        unit, f = ("mm", 1000.0) if prismatic[j] else ("deg", 180 / np.pi)
        if by == "torque":
            if torques is None:
                m, v = run.final.model, run.final.parameters.values
                torques = (run.torques(run.final), m.torques(val.q[i:i + 1], v, m.covariates(val.subset([i]))))
            qc, qv, unit, f, what = torques[0][rows, j], torques[1][0, j], "N m", 1.0, "gravity torque"
        else:
            qc, qv, what = cal.q[rows, j], val.q[i, j], "reading"
        lo, hi = qc.min(), qc.max()
        if by != "period":
            beyond = max(lo - qv, qv - hi)
            if not beyond > 0.1 * (hi - lo):
                continue
            said.append(f"joint {a.joint}'s {what} there, {qv * f:.1f} {unit}, lies beyond the calibration poses' "
                        f"({lo * f:.1f} .. {hi * f:.1f} {unit}): {a.label()} extrapolates there, where no "
                        "calibration pose checks it")
            continue
        period = (1.0 if prismatic[j] else 2 * np.pi) / a.harmonic
        below, above = qc[qc <= qv], qc[qc >= qv]
        if len(below) and len(above):
            if above.min() - below.max() <= period / 2:
                continue
            where = (f"in a gap of the calibration poses' readings from {below.max() * f:.1f} to "
                     f"{above.min() * f:.1f} {unit}, wider than half the period of {a.label()} ({period * f:.2f} "
                     f"{unit})")
        else:
            near = below.max() if len(below) else above.min()
            if abs(qv - near) <= period / 4:
                continue
            where = (f"{abs(qv - near) * f:.1f} {unit} beyond every calibration pose's reading, more than a quarter "
                     f"of the period of {a.label()} ({period * f:.2f} {unit})")
        said.append(f"joint {a.joint} reads {qv * f:.1f} {unit} there, {where}: no calibration pose checks that term "
                    "over it")
    return "; ".join(said)


def keep_worst_case(run: DiagnosisRun) -> StageOutcome | None:
    e_kin, e_final = run.val_errors(run.kinematic) * 1000, run.val_errors(run.final) * 1000
    # beyond each model's own half-weight radius, as validation_note's "miss both models"
    b_kin, b_final = noise_band(run.kinematic) or np.inf, noise_band(run.parametric) or np.inf
    like = ~((e_kin > b_kin) & (e_final > b_final))
    if not like.any():
        return None
    limit = e_kin[like].max() * (1 + WORST_SHARE)
    if e_final[like].max() <= limit:
        return None
    gps = _processes(run.final) if run.final is not run.parametric else {}
    # options: (what it drops, the named causes kept, the fit of the named causes, its processes, its errors)
    options = []
    if gps:
        options.append(([], list(run.accepted), run.parametric, None, run.val_errors(run.parametric) * 1000))
    kept, dropped, at = list(run.accepted), [], run.parametric
    for _ in range(min(MAX_DROPS, len(run.accepted))):
        if any(e[like].max() <= limit for *_, e in options):
            break
        tried = []
        for a in _screened(run, at, gps, kept, like):
            rest = [b for b in kept if b is not a]
            fit = run.fit(compose_terms(rest, run.geometric), start=run.parametric)
            new = _reconditioned(gps, fit, run.cal) if gps else None
            tried.append((dropped + [a], rest, fit, new, _errors(run, fit, new)))
            if gps:
                tried.append((dropped + [a], rest, fit, None, run.val_errors(fit) * 1000))
        options += tried
        best = min((t for t in tried if t[3] is not None or not gps), key=lambda t: t[4][like].max())
        dropped, kept, at = best[0], best[1], best[2]
    options.append((list(run.accepted), [], run.kinematic, None, e_kin))
    restoring = [o for o in options if o[4][like].max() <= limit]
    what_dropped, earlier, fit, new, e = min(restoring, key=lambda o: o[4].mean())
    geo = run.geometric if fit is not run.kinematic else True
    what = (["the GP compensator"] if gps and new is None else []) + [a.label() for a in what_dropped]
    if fit is run.kinematic:
        what = ["every correction (the kinematic model)"]
    n_out = int((~like).sum())
    mean0, mean1 = e_final.mean(), e.mean()
    i = int(np.flatnonzero(like)[np.argmax(e_final[like])])
    why = unchecked_terms(run, i, what_dropped)
    text = (f"worst case: the final model misses a validation pose ({run.val.file(i)}:{run.val.line(i)}) by "
            f"{e_final[like].max():.4f} mm, more than "
            f"{WORST_SHARE:.0%} above the kinematic model's worst {e_kin[like].max():.4f} mm"
            + (f" (leaving out {n_out} pose{'s' * (n_out > 1)} both miss by more than the noise, beyond "
               f"{b_kin:.4f} and {b_final:.4f} mm)"
               if n_out else "")
            + "; without " + ", ".join(what)
            + (" (the GP compensator kept, conditioned on the model refitted without them)" if new else "")
            + f" it is {e[like].max():.4f} mm, at a cost in the validation mean of {mean0:.4f} -> {mean1:.4f} mm"
            + (f"; why: {why}" if why else "")
            + ("; --worst-case made that the final model" if run.s.worst_case else
               "; diagnose --worst-case makes that the final model"))
    run.say(f"  {text}")
    if not run.s.worst_case:
        return StageOutcome(notes=(text,))
    findings = run.findings
    if gps and new is None:
        findings = [f for f in findings if not (f.candidate.kind.unexplained and "shrink" in f.holds_up)]
    elif not gps:
        new = None
    findings = [f for f in findings if f.candidate not in what_dropped]
    final = with_gp_compensator(fit, new, run.cal, "gp_compensator: the GP compensator (one per session)") \
        if new else fit
    spec = "kinematic" if fit is run.kinematic else model_spec(earlier, geo)
    return StageOutcome(notes=(text,), findings=tuple(findings),
                        final=FinalModel(run.under_way().holding(fit, earlier, geo), final,
                                         spec + ("+gp_compensator" if new else "")))
