"""Stage ``add_accuracy_layer`` (``+gp_compensator``): a Gaussian process of what the model leaves, per session.

The session compensator of :mod:`casadical.accuracy`, applied where it knows
the residual; the note says at how many of the calibration poses.
"""

from __future__ import annotations

from .state import CalibrationRun


def add_accuracy_layer(run: CalibrationRun) -> None:
    """With ``+gp_compensator``: replaces ``result`` by one with the layer added to its model."""
    if not run.want_gp:
        return
    from ..accuracy import fit_layer, layer_coverage, with_layer  # here: the layer, only for +gp_compensator

    result, data = run.result, run.data
    gps, _ = fit_layer(result, data)
    result = with_layer(result, gps, data, "gp_compensator: a Gaussian process of the residual per session, "
                                           "applied where it knows")
    known, total = layer_coverage(result, data)
    result.notes[-1] += f" ({known} of the {total} calibration poses)"
    run.result = result
