"""How well a calibrated model knows each pose: the uncertainty of its predicted position.

Two parts, independent and added in variance:

- the **parameters**: the named causes' (and the geometry's, the base's)
  covariance ``C`` from the fit, carried to the tool point by the model's
  Jacobian at the pose, ``Sigma = J C J^T`` (linearised; a Monte Carlo of
  ``C`` agrees within a few per cent where the model is nearly linear in its
  parameters, as calibration models are);
- the **accuracy layer** (a session compensator, :mod:`casadical.accuracy`):
  its Gaussian processes' predictive std where they know the residual,
  their prior std where they do not (there the layer adds nothing and the
  residual the named causes leave is all there is).

The figure per pose is ``sqrt(trace Sigma)``: the rms length of the 3-D
error of the prediction (not of a measurement: the tracker's own noise is
not in it).
"""

from __future__ import annotations

import numpy as np

from .data import Measurements
from .errors import InputError
from .result import CalibrationResult
from .terms import SessionLocal


def prediction_std(result: CalibrationResult, data: Measurements) -> tuple[np.ndarray, np.ndarray | None]:
    """Standard deviation (m) of the predicted tool point at each pose of ``data``.

    Returns
    -------
    params : ndarray, shape (N,)
        From the parameters' covariance: ``sqrt(trace(J C J^T))``.
    layer : ndarray, shape (N,) or None
        From the accuracy layer (None without one): ``sqrt`` of the sum of its three components' variances.

    Raises
    ------
    InputError
        The calibration holds no parameter covariance (a file written without one).
    """
    unc = result.uncertainty
    if unc is None:
        raise InputError("the calibration holds no parameter covariance (its 'uncertainty'): calibrate again with "
                         "this version to predict with --std")
    model = result.model
    _, J = model.predict_jacobian(data.q, result.parameters.values, model.covariates(data), result.base0)
    idx = [model.parameters.index(n) for n in unc.names]
    G = J[:, :, idx]                                   # (N, 3, k)
    var = np.einsum("nik,kl,nil->n", G, unc.covariance, G)
    params = np.sqrt(np.clip(var, 0.0, None))
    layer = None
    for t in model.terms:
        inner = t.inner if isinstance(t, SessionLocal) else t
        if inner.name != "gp_compensator" or inner.gp is None:
            continue
        rows = np.arange(len(data)) if not isinstance(t, SessionLocal) else (
            np.flatnonzero(data.sessions == t.session_name) if data.sessions is not None else np.zeros(0, int))
        if layer is None:
            layer = np.zeros(len(data))
        if len(rows):
            layer[rows] = np.sqrt(np.sum(inner.gp.predictive_std(data.q[rows]) ** 2, axis=1))
    return params, layer
