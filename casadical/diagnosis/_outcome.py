"""Stage ``assemble_report``: the :class:`~._report.DiagnosisReport` of the run.

Reads every field the stages before set (the steps, findings, notes, the final model and its validation,
the transfer study); sets ``report``.
"""

from __future__ import annotations

import time

from ._report import DiagnosisReport
from ._state import DiagnosisRun
from ._user_terms import accounts


def assemble_report(run: DiagnosisRun) -> None:
    final = run.final
    plots = {"val_errors_nominal_mm": (run.val_errors(run.nominal) * 1000).tolist(),
             # the headline's comparison, each pose: the final model against the kinematic calibration
             "val_errors_kinematic_mm": (run.val_errors(run.kinematic) * 1000).tolist(),
             "val_errors_final_mm": (run.final_errors * 1000).tolist(),
             "val_lines": run.val.lines.tolist()}   # the figures' hover titles: each pose's CSV line
    structure = run.set_aside
    terms = accounts(run)
    settings = run.s.record()
    if terms:       # the terms file is a setting of the run: the causes it screens beside the catalogue's
        settings["terms"] = sorted({u["file"] for u in terms if u["file"]})
    run.report = DiagnosisReport(
        run.robot.name, run.steps, run.findings, run.final_spec, run.final_val, final, run.catalogue.periodograms,
        plots, run.notes, time.perf_counter() - run.t0,
        next(st.validation for st in run.steps if st.model == "kinematic"),
        run.study.to_dict() if run.study is not None else {}, settings,
        final_sessions=final.session_stats(run.val) if len(run.sessions) > 1 else {},
        final_orientation=run.val_angles(final),
        set_aside={**(structure.to_dict() if structure.n_set_aside else {}),
                   **({"structure_misses": [{"finding": n, "lines": v} for n, v in run.structure_misses.items()]}
                      if run.structure_misses else {})},
        not_tried=[n.to_dict() for n in run.not_tried], noise=run.noise.to_dict() if run.noise is not None else {},
        interval_coverage=run.interval_coverage, user_terms=terms,
        gravity=run.gravity.to_dict() if run.gravity is not None else {})
