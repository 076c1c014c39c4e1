"""Stage ``describe_findings``: each finding's values, evidence and figure, from the final model.

Reads ``findings``, ``support``, ``before``, ``final``, ``not_tried`` and ``unexplained``; fills every accepted
finding (:func:`._findings.describe`), says where a joint's named cause may be its untried compliance
(:func:`._gaps.untried_alternatives`), sets each finding's scope: of the robot (one value serves every session) or
of one session; returns the findings with the structure that cannot be named (one ``unexplained`` finding per
joint).
"""

from __future__ import annotations

from ._findings import describe
from ._gaps import untried_alternatives
from ._state import DiagnosisRun, StageOutcome


def describe_findings(run: DiagnosisRun) -> StageOutcome:
    run.say("findings: their values, evidence and figures in the final model")
    describe(run.findings, run.support, run.before, run.final, run.cal)
    untried_alternatives(run.findings, run.not_tried)      # a joint's named cause may be its untried compliance
    findings = (*run.findings, *run.unexplained.by_joint.values())
    for f in findings:   # of the robot (one value serves every session) or of one session
        f.scope = f.scope or f.candidate.scope or ("robot" if len(run.sessions) > 1 and f.in_model
                                                   and not f.candidate.kind.unexplained else None)
    return StageOutcome(findings=findings)
