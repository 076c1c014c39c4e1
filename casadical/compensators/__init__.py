"""The compensators: what no named cause explains, learnt from the data.

After a model-based calibration, what is left of the measured position
error is learnt by a regressor mapping per-pose features ``X`` (n, d) to
residuals ``Y`` (n, 3). Every compensator lives in this package:

- the **GP compensator** (:mod:`._gp`, :class:`~._gp.ResidualGP`): a Gaussian
  process of the joint readings, one per session (fitted on a calibration,
  applied where it knows, judged on folds: :mod:`casadical.calibration._per_session`,
  above the calibration result it is made from); the model term
  ``gp_compensator``;
- the **RBF compensator** (:class:`RBFNetwork`): Gaussian radial-basis
  network (the GA paper: six effective joint torques -> residual error,
  eqs. 17-19); the model term ``rbf_compensator``;
- the **MLP compensator** (:class:`MLP`): one-hidden-layer network (the
  TLBO paper: 6-5-3 network on joint angles), trained by backprop, L-BFGS
  or TLBO.

:mod:`._guard` keeps a network only if cross-validation says it lowers the
held-out error. The RBF and MLP compensators both standardise inputs and
outputs internally, so features of ~1e3 N m and residuals of ~1e-4 m can be
passed unscaled, and both share the :class:`Compensator` interface: ``fit(X, Y) -> self``, ``predict(X) -> (n, k)``.
"""

from __future__ import annotations

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"Compensator": "_base", "Standardizer": "_base", "MLP": "_mlp", "RBFNetwork": "_rbf", "CHI3_95": "_gp",
            "FIT_ITERATIONS": "_gp", "FIT_POSES": "_gp", "JITTER": "_gp", "LENGTH_BOUNDS": "_gp",
            "MAX_STD_RATIO": "_gp", "ROBUST_NU": "_gp", "ResidualGP": "_gp", "fit_guarded": "_guard",
            "log_likelihood": "_gp", "squared_differences": "_gp"}



__all__ = [
    "CHI3_95", "Compensator", "FIT_ITERATIONS", "FIT_POSES", "JITTER", "LENGTH_BOUNDS", "MAX_STD_RATIO", "MLP",
    "RBFNetwork", "ROBUST_NU", "ResidualGP", "Standardizer", "fit_guarded", "log_likelihood", "squared_differences",
]

if _typing.TYPE_CHECKING:
    from ._base import Compensator, Standardizer
    from ._gp import (
        CHI3_95,
        FIT_ITERATIONS,
        FIT_POSES,
        JITTER,
        LENGTH_BOUNDS,
        MAX_STD_RATIO,
        ROBUST_NU,
        ResidualGP,
        log_likelihood,
        squared_differences,
    )
    from ._guard import fit_guarded
    from ._mlp import MLP
    from ._rbf import RBFNetwork
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
