"""Every cause of the user's own accounted for: what the diagnosis concluded of each term of a terms file.

A term given with ``--terms FILE`` is a candidate cause like the catalogue's (:meth:`._catalogue.Catalogue.
user_candidates`). Whatever comes of it, the report says it, in every output (terminal, JSON ``user_terms``,
HTML), for each of its candidates (the robot's and, with several sessions, each session's own):

- ``named``: in the final model, its finding's number and gain;
- ``dropped``: accepted, then dropped by a final check (why);
- ``rejected``: fitted and not accepted (the step's reason, its score test and held-out means);
- ``not supported``: screened in every round and never fitted: its best score test against the corrected
  level of that round (or, where it passed it, that other candidates of its tier came first);
- ``not screened``: no round screened it (why).

:func:`record_scores` is called by each round's screen (:mod:`._search`); :func:`accounts` by the report
(:mod:`._outcome`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..terms._definitions import by_name
from ._candidates import Candidate
from ._state import DiagnosisRun
from ._validation import KINDS, cv_text
from ._words import gain_words


@dataclass
class Score:
    """A user candidate's score test in one round (its best, if the round screened twice): log10 p, the round's
    corrected level (log10), the test in words."""

    log10_p: float
    level: float
    text: str

    def words(self, round_: int) -> str:
        if self.log10_p < self.level:
            return (f"its score test passed the corrected level in round {round_} ({self.text}; level "
                    f"{10 ** self.level:.2g}), but other candidates of its kind came first and it was not fitted")
        return (f"its best score test, in round {round_}: {self.text}; not significant at the round's corrected level "
                f"{10 ** self.level:.2g}")


def record_scores(run: DiagnosisRun, scored: list, level: float, n_steps: int) -> None:
    """What a round's score test said of each user candidate (by round), and where the round's steps begin
    (``n_steps``: the steps so far, the search's own among them)."""
    run.round_steps.setdefault(run.round, n_steps)
    for sc in scored:
        c = sc.candidate
        if c.user:
            rounds = run.user_scores.setdefault(c, {})
            if run.round not in rounds or sc.log10_p < rounds[run.round].log10_p:
                rounds[run.round] = Score(sc.log10_p, level, sc.test.text())


def accounts(run: DiagnosisRun) -> list[dict]:
    """Each user term known to the run, with its definition and, for each of its candidates, the outcome
    (see the module docstring); [] without a terms file."""
    terms = by_name(run.s.terms)
    if not terms:
        return []
    out = []
    for d in terms.values():
        cands = [c for c in dict.fromkeys([*run.user_scores, *(s.candidate for s in run.steps if s.candidate),
                                           *(f.candidate for f in run.findings)]) if c.user and c.cause == d.name]
        if not cands:
            cands = [Candidate(d.name, d.joints[0] if d.one_joint else None,
                               user=tuple(f"{d.name}.{p}" for p in d.parameter_names), definition=d)]
        doc = d.to_dict()
        doc["file"] = d.file
        doc["screen"] = [_outcome(run, c) for c in cands]
        out.append(doc)
    return out


def _round_of(run: DiagnosisRun, step: int) -> int | None:
    """The round whose screen fitted step ``step`` (1-based), None for a step before the search."""
    return max((r for r, first in run.round_steps.items() if first < step), default=None)


def _best(scores: dict, after: int = 0) -> tuple[int, Score] | None:
    """The round and score of the lowest p-value in the rounds after ``after``."""
    later = [(r, s) for r, s in scores.items() if r > after]
    return min(later, key=lambda rs: rs[1].log10_p) if later else None


def _outcome(run: DiagnosisRun, c: Candidate) -> dict:
    """What became of one user candidate."""
    out: dict = {"label": c.label()}
    if c.session is not None:
        out["session"] = c.session
    scores = run.user_scores.get(c, {})
    best = _best(scores)
    if best is not None:
        r, s = best
        out["score"] = {"round": r, "p": 10 ** s.log10_p, "level": 10 ** s.level, "test": s.text}
        out["rounds_screened"] = len(scores)
    steps = [(k, s) for k, s in enumerate(run.steps, 1) if s.candidate == c]
    if steps:
        out["steps"] = [k for k, _ in steps]
    finding = next((k for k, f in enumerate(run.findings, 1) if f.candidate == c and f.in_model), None)
    if finding is not None:
        f = run.findings[finding - 1]
        out.update(outcome="named", finding=finding, gain_mm=f.gain_mm,
                   text=f"named: finding {finding}, {gain_words(f.gain_mm)} on the validation poses")
        return out
    accepted = [k for k, s in steps if s.accepted]
    dropped = next((n.split(" was dropped at the end: ", 1)[1] for n in run.notes
                    if n.startswith(f"{c.label()} was dropped at the end: ")), None)
    if accepted and dropped is not None:
        out.update(outcome="dropped", text=f"accepted at step {accepted[-1]}, then dropped at the end: {dropped}")
        return out
    if steps:
        k, s = steps[-1]
        r = _round_of(run, k)
        when = f"fitted at step {k}" + (f" (round {r})" if r is not None else "")
        if s.reason:
            text = (f"{when} and not accepted: {s.reason}"
                    + (f"; its F-test {s.test.text()}" if s.test is not None and "F = " not in s.reason else ""))
        else:       # it passed every test of its round; the round chose another
            chosen = next((j for j, t in enumerate(run.steps, 1) if t.accepted and j != k and r is not None
                           and _round_of(run, j) == r), None)
            text = (f"{when}: it passed the tests of its round, but the round accepted "
                    + (f"{run.steps[chosen - 1].candidate.label()} (step {chosen})" if chosen else "another cause")
                    + ", which gains more where the model must extrapolate")
        held = _held(s.cv_mm)
        if held and "held-out" not in text:
            text += f"; held-out mean {held}"
        later = _best(scores, r or 0)
        if later is not None:
            n = sum(1 for q in scores if q > (r or 0))
            text += (f"; then screened in {n} later round{'s' * (n != 1)} and not fitted again: "
                     + later[1].words(later[0]))
        out.update(outcome="rejected", reason=s.reason, text=text)
        return out
    if best is not None:
        n = len(scores)
        out.update(outcome="not supported",
                   text=f"screened in {n} round{'s' * (n != 1)}, never supported: " + best[1].words(best[0]))
        return out
    why = ("no round of the search ran (--max-rounds 0)" if run.s.max_rounds == 0 else
           "no round of the search screened it (the search ended before it was a candidate)")
    out.update(outcome="not screened", text=f"not screened: {why}")
    return out


def _held(cv: dict | None) -> str:
    """A step's held-out means before and after (its :func:`._validation.cv_record`), by kind of fold, in words."""
    kinds = [k for k in KINDS if (cv or {}).get(k) is not None and cv.get(f"{k}_before") is not None]
    return cv_text({k: cv[f"{k}_before"] for k in kinds}, {k: cv[k] for k in kinds})
