"""Stage ``build_model``: the model for these data and its parameters, which of them are free.

A new calibration builds the model of the terms asked for
(:func:`~._for_data.model_for`: covariate references from the data, a base
pose per session); one taken further builds on the calibration's model
(:mod:`._further`). Then the caller's start values and fixed parameters, and
a check that a compliance has gravity torques to act on.
"""

from __future__ import annotations

import numpy as np

from ..data._measurements import Measurements
from ..errors import DataWarning, InputError
from ..model._symbolic import Model
from ..robot import Robot
from ..terms._compliance import JointCompliance
from ..terms._nonlinear_stiffness import NonlinearStiffness
from ..terms._tool_points import check_tool_points, tool_column
from ._for_data import model_for
from ._further import take_further
from ._state import CalibrationRun


def check_loads(model: Model, robot: Robot, data: Measurements) -> None:
    """A compliance asked of a robot that carries no mass: no gravity torque can deflect any joint.

    Without it every compliance would be fixed as having "no effect at
    these poses", which hides the cause (a URDF without ``<inertial>``).
    """
    torque_terms = [t.spec() for t in model.terms
                    if isinstance(getattr(t, "inner", t), (JointCompliance, NonlinearStiffness))]
    if not torque_terms:
        return
    payload = data.get("payload_kg")
    carried = robot.payload_mass if payload is None else float(np.max(payload, initial=0.0))
    if sum(j.mass for j in robot.joints) > 0 or carried > 0:
        return
    raise InputError(f"model {model.spec} asks for {', '.join(torque_terms)}, but robot {robot.name} has no link "
                     "masses and the poses no payload, so no gravity torque deflects a joint; give the links their "
                     "masses (<inertial> in a URDF, mass_kg in a robot TOML) or the poses a payload_kg column, or "
                     "leave the compliance out (--model kinematic)", file=robot.source or None)


def build_model(run: CalibrationRun) -> None:
    """Sets ``model``, ``params`` (start values and free set) and ``kept``."""
    opts = run.options
    if run.prior is not None:
        take_further(run)
    else:
        run.model = run.built if run.built is not None else model_for(run.robot, run.terms, run.data,
                                                                      session_tools=opts.session_tools)
        run.params = run.model.parameters.copy()
        if run.free_tool:
            for p in run.params.select(term="geometric"):
                if p.group == "tool":
                    p.fixed, p.reason = False, ""
    params = run.params
    said = check_tool_points(run.data, run.robot)
    if said:
        run.note(f"{run.robot.source or run.robot.name}: {said}", DataWarning)
    if run.model.term("tool_points") is not None and (tool_column(run.data) != "").all():
        # every row names its tool point: the robot file's [tool] (the geometry's tool_*) is no row's
        for p in params.select(term="geometric"):
            if p.group == "tool" and ":" not in p.name and "@" not in p.name:
                p.fixed, p.reason = True, "no row measures it: every row names its tool point (tool column)"
    unknown = [n for n in list(opts.fix) + list(opts.start) if n not in params]
    if unknown:
        names = params.names
        raise InputError(f"no parameter {', '.join(map(repr, sorted(set(unknown))))} in model {run.model.spec} "
                         f"(its parameters: {', '.join(names[:12])}{', ...' if len(names) > 12 else ''})")
    for name, v in opts.start.items():
        params[name].value = float(v)
    params.fix(opts.fix, reason="fixed by the user")
    check_loads(run.model, run.robot, run.data)
