"""Plan the poses that answer a diagnosis report's open questions, given the poses already measured.

:func:`plan_next` takes the report's questions (:mod:`._questions`), builds
each one's model at the final model's values, its information from the
measured poses and the candidates' Jacobian blocks, and selects the M
candidates by the Ds criterion of all the questions together
(:mod:`._augment`, certified). It then says, per question, what the M poses
would give: the expected standard error of each parameter asked about and
the chance of telling the alternatives apart (the power of the test that
decides, if the true values are the report's), against M random
candidates (the median over many draws) and against the best D-optimal
augmentation for the whole model (every question's terms together).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..data._measurements import Measurements
from ..diagnosis._candidates import compose_terms
from ..errors import IdentifiabilityError, InputError, listing
from ..model._symbolic import Model, parse_spec
from ..robot import Robot
from ..runtime._threads import limited_threads
from ..stats._identifiability import analyse
from ..terms import UNEXPLAINED
from ._augment import Criterion, DsDesign, ds_design
from ._questions import Question


def parametric_spec(spec: str, user_terms=()) -> str:
    """The final model's specification without its GP compensator and session frames (planned for apart)."""
    keep = [t.spec() for t in parse_spec(spec, user_terms) if t.cause != UNEXPLAINED.name
            and t.name not in ("sessions", "tool_orientation")]
    return "+".join(keep)


@dataclass
class QuestionProblem:
    """One question's design problem: its model's identifiable parameters over measured poses and candidates."""

    question: Question
    model: Model
    names: list[str]
    A: np.ndarray               # (N, 3, p) scaled candidate blocks
    M0: np.ndarray              # (p, p) scaled information of the measured poses
    interest: np.ndarray        # columns
    tested: np.ndarray          # columns of the tested parameters
    tested_values: np.ndarray   # their sizes, scaled
    scales: np.ndarray
    sets: np.ndarray | None = None      # rows that touch: each candidate's touched set (planning.touches)
    least: np.ndarray | None = None     # and the fewest rows of each a selection holds if any
    n_nuisance: int = 0                 # the last columns: what the rows touch (and the whole robot's turn)

    def criterion(self) -> Criterion:
        return Criterion(self.A, self.M0, self.interest)

    def evaluate(self, X, sigma: float) -> dict:
        """Standard errors (SI) of the parameters asked about and the power of the deciding test after
        the measured poses plus candidates ``X`` (None: the measured poses alone)."""
        from scipy.stats import chi2, ncx2

        M = self.M0.copy()
        if X is not None and len(X):
            B = self.A[np.asarray(X, dtype=int)].reshape(-1, self.A.shape[2])
            M += B.T @ B
        lam, V = np.linalg.eigh((M + M.T) / 2)
        tiny = lam <= lam[-1] * 1e-14
        inv = (V[:, ~tiny] / lam[~tiny]) @ V[:, ~tiny].T
        cov = sigma ** 2 * inv
        std = np.sqrt(np.clip(np.diag(cov), 0, None)) * self.scales
        # a parameter the poses do not see at all: its variance grows as a ridge on the information shrinks
        # (tenfold per decade; a seen one's settles), whatever the rounding in the unseen directions' vectors
        if tiny.any():
            lam0 = np.clip(lam, 0.0, None)
            var = [(V ** 2) @ (1.0 / (lam0 + eps * lam[-1])) for eps in (1e-15, 1e-14)]
            std[var[0] > 3.0 * var[1]] = math.inf
        t = self.tested
        k = len(t)
        if k and np.all(np.isfinite(std[t])):
            C = cov[np.ix_(t, t)]
            nc = float(self.tested_values @ np.linalg.solve(C, self.tested_values))
            power = float(ncx2.sf(chi2.isf(self.question.level, k), k, max(nc, 1e-12)))
        else:
            power = float("nan") if not k else 0.0
        return {"std": {self.names[i]: float(std[i]) for i in self.interest}, "power": power}


@dataclass
class NextPlan:
    """What :func:`plan_next` chose and what it would give.

    Attributes
    ----------
    indices : ndarray of int
        Candidate rows (0-based), sorted.
    questions : list of Question
        The questions planned for.
    design : DsDesign
        The selection and its certificate.
    per_question : list of dict
        For each question: ``before`` (measured poses alone), ``planned``,
        ``random`` (median standard errors and mean power over
        ``random_sets`` draws) and ``d_optimal`` (the D-optimal augmentation of
        the whole model), each with ``std`` (display units) and ``power``.
    skipped : list of str
        Questions the candidates cannot answer, with why.
    """

    indices: np.ndarray
    questions: list[Question]
    design: DsDesign
    per_question: list[dict]
    n_candidates: int
    n_measured: int
    m: int
    sigma_mm: float
    random_sets: int
    d_optimal_indices: np.ndarray
    units: dict
    skipped: list[str] = field(default_factory=list)
    time_s: float = 0.0

    def summary(self) -> str:
        d = self.design
        rel = d.relaxation
        lines = [f"selected {self.m} of {self.n_candidates} candidates to add to the {self.n_measured} measured "
                 f"poses, for {len(self.questions)} open question{'s' * (len(self.questions) != 1)} "
                 f"(noise {self.sigma_mm:.4f} mm per axis, the report's)",
                 f"criterion: sum over the questions of log det(information about its parameters) per parameter "
                 f"= {d.value:.6g} (measured poses alone {d.measured_value:.6g})",
                 f"certificate: no {self.m} candidates reach more than {d.upper_bound:.6g} (relaxation bound); "
                 f"Ds-efficiency of this selection >= {d.efficiency:.4f} (geometric mean over the questions)",
                 f"  relaxation: {rel.method}, {rel.status}, {rel.iterations} iterations, {rel.time_s:.3g} s; "
                 f"exchange: best of {d.starts} starts, {d.swaps} swaps"]
        for s in self.skipped:
            lines.append(f"not planned: {s}")
        for q, r in zip(self.questions, self.per_question):
            lines += ["", f"question {q.number} ({q.kind}): {q.text}"]
            head = f"    {'':<16}" + "".join(f"{n:>16}" for n in q.interest) + f"{'chance to tell':>16}"
            lines.append(head + "   (standard errors in " + ", ".join(
                dict.fromkeys(self.units[n] for n in q.interest)) + ")")
            for key, label in (("before", "measured alone"), ("planned", f"+ {self.m} planned"),
                               ("random", f"+ {self.m} random"), ("d_optimal", f"+ {self.m} D-optimal")):
                e = r[key]
                lines.append(f"    {label:<16}" + "".join(f"{_g(e['std'][n]):>16}" for n in q.interest)
                             + f"{_pct(e['power']):>16}")
        lines += ["", f"random: median standard error and mean chance over {self.random_sets} random sets of "
                      f"{self.m} candidates; D-optimal: the certified D-optimal {self.m} candidates for the whole "
                      "model (every question's terms), added to the measured poses"]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        d = self.design
        return {"m": self.m, "n_candidates": self.n_candidates, "n_measured": self.n_measured,
                "indices": [int(i) for i in self.indices], "sigma_mm": self.sigma_mm,
                "criterion": {"value": d.value, "measured_value": d.measured_value, "upper_bound": d.upper_bound,
                              "ds_efficiency": d.efficiency, "relaxation": {
                                  "method": d.relaxation.method, "status": d.relaxation.status,
                                  "iterations": d.relaxation.iterations, "value": d.relaxation.value}},
                "random_sets": self.random_sets,
                "d_optimal_indices": [int(i) for i in self.d_optimal_indices],
                "questions": [{**q.to_dict(), "units": {n: self.units[n] for n in q.interest}, **r}
                              for q, r in zip(self.questions, self.per_question)],
                "skipped": self.skipped, "time_s": self.time_s}


def _g(x: float) -> str:
    return "not determined" if not math.isfinite(x) else f"{x:.3g}"


def _pct(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{100 * x:.0f} %"


def _jacobian(model: Model, values: np.ndarray, data: Measurements, sessions: np.ndarray) -> np.ndarray:
    """Position Jacobian (N, 3, P) of ``data``'s poses at ``values``, each pose in its session ``sessions``
    (a term of one session, ``...@S``, acts at that session's poses only)."""
    from ._observability import pool_jacobian

    model.parameters.values = values
    return pool_jacobian(model, data.q, _covariates(model, data, sessions))


def _covariates(model: Model, data: Measurements, sessions: np.ndarray) -> np.ndarray:
    """``data``'s covariates, each pose in its session ``sessions``: the model holds no session frames (planned
    for apart), its session indicators come from here."""
    from ..terms._sessions import indicator

    cov = model.covariates(data)
    for s in dict.fromkeys(sessions.tolist()):
        if indicator(s) in model.covariate_names:
            cov[:, model.covariate_names.index(indicator(s))] = sessions == s
    return cov


def _stacked(measured: Measurements, candidates: Measurements, meas_sessions: np.ndarray,
             cand_sessions: np.ndarray) -> Measurements:
    """The measured rows then the candidates as one data set, each row in its session: a candidate touching a
    point of a measured session touches the same point (its unknowns are shared). Columns one of them lacks are
    empty (NaN, or no text) on its rows."""
    n_m, n_c = len(measured), len(candidates)
    cols = {}
    for k in dict.fromkeys([*measured.columns, *candidates.columns]):
        a, b = measured.columns.get(k), candidates.columns.get(k)
        text = any(v is not None and v.dtype.kind not in "fiu" for v in (a, b))
        fill = (lambda n: np.full(n, "", dtype=object)) if text else (lambda n: np.full(n, np.nan))  # noqa: E731
        cols[k] = np.concatenate([fill(n_m) if a is None else a.astype(object if text else float),
                                  fill(n_c) if b is None else b.astype(object if text else float)])
    sessions = np.concatenate([meas_sessions, cand_sessions]).astype(object)
    return Measurements(cols, measured.path, sessions=None if not any(sessions) else sessions,
                        fixtures=measured.fixtures or candidates.fixtures)


def _touch_problem(model: Model, values: np.ndarray, q: Question, measured: Measurements,
                   candidates: Measurements, meas_sessions: np.ndarray, cand_sessions: np.ndarray) -> QuestionProblem:
    """A question's problem where the rows touch (:mod:`casadical.planning._touches`): the robot's parameters the
    measured rows and candidates identify (what they cannot see held), the nuisance (every touched point's,
    plane's, fixture's unknowns and the whole robot's turn) among the others."""
    from ._touches import touch_problem

    data = _stacked(measured, candidates, meas_sessions, cand_sessions)
    if data.layout.tracked.any() and len(set(data.sessions.tolist() if data.sessions is not None else [])) > 1:
        raise IdentifiabilityError(f"question {q.number}: rows of an instrument and rows that touch in several "
                                   "sessions are not planned for together yet")
    tp = touch_problem(model, data, values=values, cov=_covariates(model, data, data.sessions if data.sessions
                                                                    is not None else np.full(len(data), "")),
                       measured=len(measured))
    held = {n: u["what"] for u in tp.unobservable for n in u["parameters"]}
    lost = [n for n in q.interest if n not in tp.names]
    if lost:
        why = {n: f"not seen by rows that touch: {held[n]}" if n in held else "not identified by these rows"
               for n in lost}
        raise IdentifiabilityError(f"question {q.number}: the measured rows and the candidates do not identify "
                                   + listing([f"{n} ({why[n]})" for n in lost]))
    params = model.parameters
    k = tp.A.shape[2] - tp.n_parameters
    names = tp.names + [f"nuisance[{i}]" for i in range(k)]
    scales = np.concatenate([params.scales[[params.index(n) for n in tp.names]], np.ones(k)])
    interest = np.array([names.index(n) for n in q.interest])
    tested = np.array([names.index(n) for n in q.tested if n in tp.names], dtype=int)
    tv = np.array([q.tested[names[j]] for j in tested]) / scales[tested] if len(tested) else np.zeros(0)
    return QuestionProblem(q, model, names, tp.A, tp.M0, interest, tested, tv, scales, tp.sets, tp.least, k)


def _session_columns(J: np.ndarray, names: list[str], sessions: np.ndarray | None, order: list[str],
                     tools: bool | list) -> tuple[np.ndarray, list[str]]:
    """Each session other than the first its own base pose (and tool, where asked): the base (tool) columns
    split by session, as the calibration's session frames do (the information is that of its parametrisation
    up to a change of variables of the base, which the questions do not ask about)."""
    if sessions is None or len(order) < 2:
        return J, names
    own_tool = order[1:] if tools is True else list(tools or [])
    cols = [k for k, n in enumerate(names) if n.startswith("base_")]
    extra, extra_names = [], []
    for s in order[1:]:
        rows = sessions == s
        split = cols + ([k for k, n in enumerate(names) if n.startswith("tool_")] if s in own_tool else [])
        block = np.zeros(J.shape[:2] + (len(split),))
        block[rows] = J[rows][:, :, split]
        J = J.copy()
        J[np.ix_(rows, np.arange(J.shape[1]), split)] = 0.0
        extra.append(block)
        extra_names += [f"{names[k]}@{s}" for k in split]
    return np.concatenate([J] + extra, axis=2), names + extra_names


@limited_threads()
def build_problem(robot: Robot, base_spec: str, q: Question, final_values: dict[str, float],
                  measured: Measurements, candidates: Measurements, session_tools=False) -> QuestionProblem:
    """A question's model at the final values, its identifiable parameters and information.

    Raises
    ------
    IdentifiabilityError
        The measured poses and the candidates together do not identify a parameter the question asks about.
    """
    have = set(Model(robot, base_spec, jit=False, user_terms=q.terms).parameters.names)
    extra = [c for c in q.extra if not set(c.parameter_names()) <= have]
    model = Model(robot, parse_spec(base_spec, q.terms) + [t for c in extra for t in compose_terms([c], False)],
                  jit=False)
    params = model.parameters
    values = np.array([final_values.get(p.name, p.value) for p in params])
    order = measured.session_names
    # candidates without a session are the first session's (the CLI's --session names another)
    cand_sessions = candidates.sessions if candidates.sessions is not None else \
        np.full(len(candidates), order[0] if order else "", dtype=object)
    meas_sessions = measured.sessions if measured.sessions is not None else np.full(len(measured), "", dtype=object)
    if measured.touches or candidates.touches:
        return _touch_problem(model, values, q, measured, candidates, meas_sessions, cand_sessions)
    Jm = _jacobian(model, values, measured, meas_sessions)
    Jc = _jacobian(model, values, candidates, cand_sessions)
    ident = analyse(np.concatenate([Jm, Jc]), params)
    lost = [n for n in q.interest if n not in ident.identifiable]
    if lost:
        why = {u.name: u.reason for u in ident.unidentifiable}
        raise IdentifiabilityError(f"question {q.number}: the measured poses and the candidates do not identify "
                                   + listing([f"{n} ({why.get(n, 'not in the model')})" for n in lost]))
    idx = [params.index(n) for n in ident.identifiable]
    scales = params.scales[idx]
    names = list(ident.identifiable)
    Jm, Jc = Jm[:, :, idx] * scales, Jc[:, :, idx] * scales
    Jm, all_names = _session_columns(Jm, names, measured.sessions, order, session_tools)
    Jc, _ = _session_columns(Jc, names, cand_sessions, order, session_tools)
    scales = np.concatenate([scales, np.ones(len(all_names) - len(names))])
    Bm = Jm.reshape(-1, Jm.shape[2])
    interest = np.array([all_names.index(n) for n in q.interest])
    tested = np.array([all_names.index(n) for n in q.tested if n in all_names], dtype=int)
    tv = np.array([q.tested[all_names[k]] for k in tested]) / scales[tested] if len(tested) else np.zeros(0)
    return QuestionProblem(q, model, all_names, np.ascontiguousarray(Jc), Bm.T @ Bm, interest, tested, tv, scales)


def _display(model: Model, name: str):
    base = name.split("@")[0] if name not in model.parameters else name
    p = model.parameters[base] if base in model.parameters else None
    return (p.to_display, p.display_unit) if p is not None else ((lambda v: v), "")


@limited_threads()
def plan_next(robot: Robot, report: dict, questions: list[Question], final_values: dict[str, float],
              measured: Measurements, candidates: Measurements, m: int, *, relaxation: str = "first-order",
              random_sets: int = 200, seed: int = 0, session_tools=False,
              progress=None) -> NextPlan:
    """Select the M candidates that best answer ``questions`` given the ``measured`` poses.

    Parameters
    ----------
    robot : Robot
    report : dict
        The parsed REPORT.json (its final model and noise).
    questions : list of Question
        From :func:`casadical.planning._questions.open_questions` (all, or the one asked for).
    final_values : dict
        The final model's values (SI).
    measured, candidates : Measurements
        The poses the report was made from; the poses to choose from.
    m : int
    random_sets : int
        Random M-sets of the baseline.

    Raises
    ------
    InputError
        No question the candidates can answer, M larger than the candidates.
    """
    t0 = time.perf_counter()
    say = progress or (lambda _: None)
    if m > len(candidates):
        raise InputError(f"-m {m} asks for more poses than the {len(candidates)} candidate rows")
    final = report.get("final") or {}
    sigma_mm = final.get("sigma_mm")
    if not sigma_mm:
        raise InputError("the report has no final.sigma_mm (the final model's residual): run diagnose again")
    sigma = float(sigma_mm) / 1000
    base = parametric_spec(final["model"], questions[0].terms if questions else ())
    problems, kept, skipped = [], [], []
    for q in questions:
        say(f"question {q.number}: the Jacobian at {len(measured)} measured poses and "
            f"{len(candidates)} candidates")
        try:
            problems.append(build_problem(robot, base, q, final_values, measured, candidates, session_tools))
            kept.append(q)
        except IdentifiabilityError as e:
            skipped.append(str(e))
    if not problems:
        raise InputError("no open question these candidates can answer: " + "; ".join(skipped)
                         if skipped else "the report has no open question")
    say(f"selecting {m} of {len(candidates)} candidates (Ds criterion, {len(problems)} questions)")
    # rows that touch: each point none or enough rows (the same sets in every question: the same rows)
    touch = {"groups": problems[0].sets, "least": problems[0].least} if problems[0].sets is not None else {}
    design = ds_design([p.criterion() for p in problems], m, relaxation=relaxation, seed=seed, **touch)
    # the whole model: every question's terms at once, D-optimal (every parameter of interest)
    say("the D-optimal augmentation of the whole model, for comparison")
    whole_q = Question(0, "whole", "", list(dict.fromkeys(c for q in kept for c in q.extra)), [], {}, 0.05, -1,
                       terms=kept[0].terms)
    wp = build_problem(robot, base, whole_q, final_values, measured, candidates, session_tools)
    whole = np.arange(wp.A.shape[2] - wp.n_nuisance)
    dopt = ds_design([Criterion(wp.A, wp.M0, whole)], m, seed=seed, **touch).indices
    rng = np.random.default_rng(seed)
    if touch:
        from ._touches import random_rows

        sets = [random_rows(touch["groups"], touch["least"], m, rng) for _ in range(random_sets)]
    else:
        sets = [np.sort(rng.choice(len(candidates), m, replace=False)) for _ in range(random_sets)]
    per, units = [], {}
    for p in problems:
        conv = {n: _display(p.model, n) for n in p.question.interest}
        units.update({n: conv[n][1] for n in conv})

        def shown(e):
            return {"std": {n: conv[n][0](v) for n, v in e["std"].items()}, "power": e["power"]}
        rand = [p.evaluate(X, sigma) for X in sets]
        rnd = {"std": {n: float(np.median([r["std"][n] for r in rand])) for n in p.question.interest},
               "power": float(np.mean([r["power"] for r in rand]))}
        per.append({"before": shown(p.evaluate(None, sigma)), "planned": shown(p.evaluate(design.indices, sigma)),
                    "random": shown(rnd), "d_optimal": shown(p.evaluate(dopt, sigma))})
    return NextPlan(design.indices, kept, design, per, len(candidates), len(measured), m, float(sigma_mm),
                    random_sets, dopt, units, skipped, time.perf_counter() - t0)
