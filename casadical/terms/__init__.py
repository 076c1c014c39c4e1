"""Error terms of the calibration model, one module each, found by name.

``make_term("joint_compliance", joints=[2, 3])`` or a model specification
such as ``"kinematic+compliance[2,3]+periodic[2:1]"`` (see
:func:`casadical.model._symbolic.parse_spec`).
"""

import typing as _typing

from .._lazy import lazy
from . import (  # noqa: F401
    _backlash,
    _bearing_compliance,
    _carriage_angle,
    _compliance,
    _drift,
    _encoder_scale,
    _geometric,
    _gp_compensator,
    _joint_coupling,
    _mount_compliance,
    _nonlinear_stiffness,
    _periodic,
    _rbf_compensator,
    _sessions,
    _straightness,
    _thermal,
    _tool_orientation,
    _tool_points,
    _warmup,
)
from ._base import REGISTRY, Context, ErrorTerm, ReferencedTerm, covariate_names, register
from ._cause import CAUSES, Cause, ordered, register_cause
from ._geometric import GEOMETRIC
from ._gp_compensator import UNEXPLAINED
from ._local import SessionLocal


def make_term(name: str, **kwargs) -> ErrorTerm:
    """Instantiate a registered term by name or alias."""
    from ..errors import ModelError
    try:
        cls = REGISTRY[name]
    except KeyError:
        raise ModelError(f"unknown error term {name!r}; known: {', '.join(sorted(REGISTRY))}") from None
    return cls(**kwargs)


__all__ = [
    "CAUSES", "CarriageAngle", "Cause", "Context", "Drift", "EFFECTS", "ErrorTerm", "GEOMETRIC", "Geometric",
    "JointCompliance", "JointCoupling", "JointPeriodic", "MIN_SIDE_POSES", "MIN_SIDE_SHARE", "NonlinearStiffness",
    "RBFCompensator", "REGISTRY", "ReferencedTerm", "SessionFrames", "SessionLocal", "Straightness",
    "ThermalExpansion", "ToolOrientation", "ToolPoints", "UNEXPLAINED", "USER", "UserTerm", "bearing_moments",
    "bernstein", "by_name", "check_tool_points", "covariate_names", "definitions_from_list", "features",
    "fitted_processes", "indicator", "make_term", "max_mount_moment", "mount_moments", "named_points", "ordered",
    "phase", "reach", "read_terms_file", "register", "register_cause", "session_parts", "sign_changes", "tool_column",
    "with_tool_points",
]

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"CarriageAngle": "_carriage_angle", "Drift": "_drift", "EFFECTS": "_definitions",
            "Geometric": "_geometric", "JointCompliance": "_compliance", "JointCoupling": "_joint_coupling",
            "JointPeriodic": "_periodic", "MIN_SIDE_POSES": "_backlash", "MIN_SIDE_SHARE": "_backlash",
            "NonlinearStiffness": "_nonlinear_stiffness", "RBFCompensator": "_rbf_compensator",
            "SessionFrames": "_sessions", "Straightness": "_straightness", "ThermalExpansion": "_thermal",
            "ToolOrientation": "_tool_orientation", "ToolPoints": "_tool_points", "USER": "_user", "UserTerm": "_user",
            "bearing_moments": "_bearing_compliance", "bernstein": "_mount_compliance", "by_name": "_definitions",
            "check_tool_points": "_tool_points", "definitions_from_list": "_definitions",
            "features": "_rbf_compensator", "fitted_processes": "_gp_compensator", "indicator": "_sessions",
            "max_mount_moment": "_mount_compliance", "mount_moments": "_mount_compliance",
            "named_points": "_tool_points", "phase": "_periodic", "reach": "_base", "read_terms_file": "_definitions",
            "session_parts": "_cause", "sign_changes": "_backlash", "tool_column": "_tool_points",
            "with_tool_points": "_tool_points"}

if _typing.TYPE_CHECKING:
    from ._backlash import MIN_SIDE_POSES, MIN_SIDE_SHARE, sign_changes
    from ._base import reach
    from ._bearing_compliance import bearing_moments
    from ._carriage_angle import CarriageAngle
    from ._cause import session_parts
    from ._compliance import JointCompliance
    from ._definitions import EFFECTS, by_name, definitions_from_list, read_terms_file
    from ._drift import Drift
    from ._geometric import Geometric
    from ._gp_compensator import fitted_processes
    from ._joint_coupling import JointCoupling
    from ._mount_compliance import bernstein, max_mount_moment, mount_moments
    from ._nonlinear_stiffness import NonlinearStiffness
    from ._periodic import JointPeriodic, phase
    from ._rbf_compensator import RBFCompensator, features
    from ._sessions import SessionFrames, indicator
    from ._straightness import Straightness
    from ._thermal import ThermalExpansion
    from ._tool_orientation import ToolOrientation
    from ._tool_points import ToolPoints, check_tool_points, named_points, tool_column, with_tool_points
    from ._user import USER, UserTerm
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
