"""Error terms of the calibration model, one module each, found by name.

``make_term("joint_compliance", joints=[2, 3])`` or a model specification
such as ``"kinematic+compliance[2,3]+periodic[2:1]"`` (see
:func:`casadical.model.symbolic.parse_spec`).
"""

from . import (  # noqa: F401
    backlash,
    bearing_compliance,
    carriage_angle,
    compliance,
    drift,
    encoder_scale,
    geometric,
    gp_compensator,
    joint_coupling,
    mount_compliance,
    nonlinear_stiffness,
    periodic,
    rbf_compensator,
    sessions,
    straightness,
    thermal,
    tool_orientation,
    tool_points,
    warmup,
)
from .base import REGISTRY, Context, ErrorTerm, ReferencedTerm, covariate_names, register
from .cause import CAUSES, Cause, ordered, register_cause
from .geometric import GEOMETRIC
from .gp_compensator import UNEXPLAINED
from .local import SessionLocal


def make_term(name: str, **kwargs) -> ErrorTerm:
    """Instantiate a registered term by name or alias."""
    from ..errors import ModelError
    try:
        cls = REGISTRY[name]
    except KeyError:
        raise ModelError(f"unknown error term {name!r}; known: {', '.join(sorted(REGISTRY))}") from None
    return cls(**kwargs)


__all__ = ["CAUSES", "GEOMETRIC", "REGISTRY", "UNEXPLAINED", "Cause", "Context", "ErrorTerm", "ReferencedTerm",
           "SessionLocal", "covariate_names", "make_term", "ordered", "register", "register_cause"]
