"""Stage ``analyse_identifiability``: enough poses for the model, and what these poses cannot identify.

The parameters many random poses identify (:func:`generic_identifiable`) are
what a good pose set could reach; of those, the ones these poses cannot
identify are named in a warning and stay at their start values; the rest
of the unidentifiable are structural (combinations of others in the model).
"""

from __future__ import annotations

import numpy as np

from ..data._simulate import sample_poses
from ..errors import IdentifiabilityError, IdentifiabilityWarning
from ..model._symbolic import Model
from ..parameters import Parameters
from ..problem import ROT_WEIGHT_PRIOR, jacobian_factor
from ..stats._identifiability import analyse
from ._state import CalibrationRun
from ._unobservable import whole_robot

_GENERIC: dict = {}


def generic_identifiable(model: Model, params: Parameters, cov: np.ndarray, seed: int = 0,
                         full_pose: bool = False) -> list[str]:
    """Parameters identifiable from many random poses (what a good pose set could reach).

    Cached per robot, model and free set: diagnosis and comparisons calibrate
    the same structure many times. ``full_pose``: with the orientation rows.
    """
    varies = tuple(bool(np.ptp(cov[:, k]) > 0) for k in range(cov.shape[1]))
    key = (id(model.robot), model.spec, tuple(params.free), varies) + ((True,) if full_pose else ())
    if key not in _GENERIC:
        rng = np.random.default_rng(seed)
        q = sample_poses(model.robot, 200, rng, floor_z=None)
        c = cov[rng.integers(len(cov), size=len(q))]
        if full_pose:   # measured = predicted orientation: the rows of the orientation residual at zero
            P = model.probe_rotation(q, params.nominal, c)
            _, J, _, Jo = model.pose_jacobian(q, P, params.nominal, c)
            J = np.concatenate([J, ROT_WEIGHT_PRIOR * Jo], axis=1)
        else:
            _, J = model.predict_jacobian(q, params.nominal, c)
        if len(_GENERIC) > 256:
            _GENERIC.clear()
        _GENERIC[key] = (model.robot, analyse(J, params).identifiable)  # robot kept: its id stays unique
    return _GENERIC[key][1]


def analyse_identifiability(run: CalibrationRun) -> None:
    """Sets ``ident`` and fixes the parameters these poses cannot identify (unless the caller said
    ``check_identifiability=False``); raises when the poses are too few for the model."""
    if not run.options.check_identifiability:
        return
    model, params, q, per_pose = run.model, run.params, run.data.q, run.per_pose
    generic = generic_identifiable(model, params, run.cov, full_pose=run.full_pose)
    needed = len(generic)
    if run.equations <= needed:
        raise IdentifiabilityError(
            f"{run.where}{len(q)} poses give {run.equations} equations for the {needed} identifiable parameters "
            f"of model {model.spec}: at least {needed // per_pose + 1} poses are needed, and 3-5 times that for "
            "a reliable fit")
    # structural question, at nominal values: at a perturbed start exact redundancies only look near-exact
    nominal = params.nominal
    if run.full_pose:   # the mounting's deviations have no nominal: at the reference R0
        for k in ("roll", "pitch", "yaw"):
            nominal[params.index(f"tool_{k}")] = params[f"tool_{k}"].value
    if run.data.touches:    # what touches cannot see is fixed already (fix_unobservable): not asked of the poses
        unseen = {n for u in run.unobservable for n in u["parameters"]}
        generic = [n for n in generic if n not in unseen]
        needed = len(generic)
    R = jacobian_factor(model, q, nominal, run.cov, run.base0, run.rot,
                        layout=run.data.layout if run.data.touches else None)
    ident = analyse(R, params, n_equations=run.equations)
    if run.data.touches and run.data.touching.all():      # touches alone: what moves the whole robot
        moving = np.linalg.norm(jacobian_factor(model, q, nominal, run.cov, run.base0), axis=0) > 0
        whole = whole_robot(ident, {n for n, m in zip(params.names, moving) if m}, run.unobservable)
        generic = [n for n in generic if n not in whole]
    lost = [u for u in ident.unidentifiable if u.name in generic]
    if lost:
        names = ", ".join(f"{u.name} ({u.reason})" for u in lost[:6])
        run.note(f"these poses cannot identify {len(lost)} parameter(s) that other poses could: "
                 f"{names}; they stay at their start values. Spread the poses over more of the "
                 "joint ranges (and loads) to identify them", IdentifiabilityWarning)
    for u in ident.unidentifiable:
        if u.name not in generic:
            u.reason = "structurally " + u.reason if not u.reason.startswith("has no") else u.reason
    ident.apply(params)
    run.ident = ident
