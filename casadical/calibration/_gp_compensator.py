"""Stage ``add_gp_compensator`` (``+gp_compensator``): the GP compensator, a Gaussian process of what the model
leaves, one per session.

Fitted by :mod:`casadical.calibration._per_session` and applied where it
knows the residual; the note says at how many of the calibration poses.
"""

from __future__ import annotations

from ._state import CalibrationRun


def add_gp_compensator(run: CalibrationRun) -> None:
    """With ``+gp_compensator``: replaces ``result`` by one with the GP compensator added to its model."""
    if not run.want_gp:
        return
    # here, not at import: the compensators, only for +gp_compensator
    from ._per_session import fit_gp_compensator, gp_compensator_coverage, with_gp_compensator

    result, data = run.result, run.data
    gps, _ = fit_gp_compensator(result, data)
    result = with_gp_compensator(result, gps, data, "gp_compensator: a Gaussian process of the residual per "
                                                    "session, applied where it knows")
    known, total = gp_compensator_coverage(result, data)
    result.notes[-1] += f" ({known} of the {total} calibration poses)"
    run.result = result
