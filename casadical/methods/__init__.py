"""The seed papers' calibration methods, by name.

===================  ===========================================================
name                 what it does
===================  ===========================================================
``Nominal``          nominal geometry, only the base pose fitted
``KM``               kinematic calibration (iterative least squares)
``SKCM``             kinematics + joint compliance simultaneously (IPOPT, bounded)
``SKCM-CA``          CA paper: kinematic LS alternated with a cultural algorithm
                     over the stiffnesses of joints 2-5
``SKCM-GA``          the same with a genetic algorithm (the CA paper's baseline)
``GA-RBF``           GA paper: KM, then an RBF network from the six effective
                     torques to the residual position error
``NN-SKCM``          SKCM, then a 6-5-3 network on the joint angles (backprop)
``TLBO-NN-SKCM``     TLBO paper: the same network trained by TLBO on a
                     separate pose set
``SKCM-IPOPT-CA``    a cultural algorithm's best points start IPOPT (also
``-GA``, ``-TLBO``)  with GA and TLBO): global reach, local precision
===================  ===========================================================

>>> from casadical.methods import run_method, method_names
>>> from casadical.data import load_protocol
>>> proto = load_protocol("ca-ys100")
>>> sets, truth = proto.generate()
>>> r = run_method("SKCM-CA", proto.robot, sets["calibration"], sets["validation"])  # doctest: +SKIP
>>> r.validation.mean_mm, r.stiffness()                                               # doctest: +SKIP

Adding a method means one private module (``_name.py``) in this folder: subclass
:class:`~casadical.methods._base.Method`, decorate with
:func:`~casadical.methods._base.register`, and import the module below.
"""

from __future__ import annotations

import typing as _typing

from .._lazy import lazy
from ..data._measurements import Measurements
from ..errors import InputError
from ..robot import Robot
from . import _ga_rbf, _km, _nn_skcm, _nominal, _skcm, _skcm_ca, _skcm_ga, _skcm_ipopt, _tlbo_nn_skcm  # noqa: F401  (registration)
from ._base import REGISTRY, Inputs, Method, MethodResult, lookup, method_names, register


def make_method(name: str, **settings) -> Method:
    """A method by name (case-insensitive) with its settings.

    Raises
    ------
    InputError
        Unknown name (the message lists the valid ones) or unknown setting.
    """
    return lookup(name)(**settings)


def run_method(name: str, robot: Robot, cal: Measurements, val: Measurements | None = None,
               extra: Measurements | None = None, seed: int = 0, **settings) -> MethodResult:
    """Run one method: identify on ``cal`` (and ``extra``), evaluate on all sets.

    Parameters
    ----------
    name : str
        A registered method (:func:`method_names`).
    robot : Robot
    cal : Measurements
        Calibration poses (with positions).
    val : Measurements, optional
        Validation poses, never used for fitting.
    extra : Measurements, optional
        A further set for the compensators (the TLBO paper's Q2).
    seed : int
        Seed of every random choice: the same seed gives the same result.
    **settings
        Method settings (see each method's docstring).

    Returns
    -------
    MethodResult
    """
    for d, what in ((cal, "calibration"), (val, "validation"), (extra, "extra")):
        if d is not None and d.n_joints != robot.n:
            raise InputError(f"the {what} poses have {d.n_joints} joint columns but {robot.name} has "
                             f"{robot.n} joints", file=d.path)
    method = make_method(name, **settings)
    return method.run(Inputs(robot, cal, extra, int(seed)), val)


__all__ = [
    "Inputs", "Method", "MethodResult", "REGISTRY", "compare", "format_table", "global_start", "lookup", "make_method",
    "method_names", "new_result", "parse_methods", "plot", "pyplot", "register", "run_method", "save_png", "to_json",
    "two_phase",
]

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"compare": "_compare", "format_table": "_compare", "global_start": "_global_start", "new_result": "_base",
            "parse_methods": "_compare", "plot": "_compare", "pyplot": "_compare", "save_png": "_compare",
            "to_json": "_compare", "two_phase": "_two_phase"}

if _typing.TYPE_CHECKING:
    from ._base import new_result
    from ._compare import compare, format_table, parse_methods, plot, pyplot, save_png, to_json
    from ._global_start import global_start
    from ._two_phase import two_phase
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
