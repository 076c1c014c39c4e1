"""The compensators: what no named cause explains, learnt from the data.

After a model-based calibration, what is left of the measured position
error is learnt by a regressor mapping per-pose features ``X`` (n, d) to
residuals ``Y`` (n, 3). Every compensator lives in this package:

- the **GP compensator** (:mod:`.gp`, :class:`~.gp.ResidualGP`): a Gaussian
  process of the joint readings, one per session (fitted on a calibration,
  applied where it knows, judged on folds: :mod:`casadical.calibration.per_session`,
  above the calibration result it is made from); the model term
  ``gp_compensator``;
- the **RBF compensator** (:class:`RBFNetwork`): Gaussian radial-basis
  network (the GA paper: six effective joint torques -> residual error,
  eqs. 17-19); the model term ``rbf_compensator``;
- the **MLP compensator** (:class:`MLP`): one-hidden-layer network (the
  TLBO paper: 6-5-3 network on joint angles), trained by backprop, L-BFGS
  or TLBO.

:mod:`.guard` keeps a network only if cross-validation says it lowers the
held-out error. The RBF and MLP compensators both standardise inputs and
outputs internally, so features of ~1e3 N m and residuals of ~1e-4 m can be
passed unscaled, and both share the :class:`Compensator` interface: ``fit(X, Y) -> self``, ``predict(X) -> (n, k)``.
"""

from __future__ import annotations

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"Compensator": "base", "Standardizer": "base", "MLP": "mlp", "RBFNetwork": "rbf"}



__all__ = ["Compensator", "MLP", "RBFNetwork", "Standardizer"]

if _typing.TYPE_CHECKING:
    from .base import Compensator, Standardizer
    from .mlp import MLP
    from .rbf import RBFNetwork
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
