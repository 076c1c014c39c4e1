"""Stage ``read_model_spec``: the terms a model specification asks for.

``+tool`` frees the tool offset; full-pose data add the probe's mounting
rotation (``tool_orientation``) to any model; a compensator that is still
to be fitted (``+rbf_compensator``, ``+gp_compensator``) is taken out of the
terms and fitted after the model (:mod:`._rbf_compensator`, :mod:`._gp_compensator`).
"""

from __future__ import annotations

from ..errors import InputError
from ..model._symbolic import Model, parse_spec
from ..terms import make_term
from ..terms._geometric import Geometric
from ..terms._rbf_compensator import RBFCompensator
from ..terms._tool_orientation import ToolOrientation
from ._state import CalibrationRun


def _to_fit_later(t) -> bool:
    """A compensator term without its fitted network or process: fitted after the model."""
    return (isinstance(t, RBFCompensator) and t.network is None) or \
        (t.name == "gp_compensator" and getattr(t, "gp", 0) is None)


def read_model_spec(run: CalibrationRun) -> None:
    """Sets ``terms``, ``built`` (the caller's own model, if given), ``free_tool``, ``want_rbf`` and
    ``want_gp``."""
    spec, data = run.spec, run.data
    if isinstance(spec, Model):
        terms, built = spec.terms, spec
    else:
        items = [i.strip() for i in spec.split("+")]
        run.free_tool = "tool" in items   # base+tool: the tool offset is estimated too (a re-mounted probe)
        terms, built = parse_spec("+".join(i for i in items if i != "tool") or "nominal", run.user_terms), None
    named_orientation = any(isinstance(t, ToolOrientation) for t in terms)
    if named_orientation and not run.full_pose and run.prior is None:
        raise InputError(f"model item tool_orientation needs measured orientations (rx_deg, ry_deg, rz_deg) "
                         f"{'and no --position-only' if data.has_orientation else 'in the data'}", file=data.path)
    if run.full_pose and not named_orientation:
        # the probe's mounting rotation: what full-pose data add to any model
        terms = list(terms) + [make_term("tool_orientation")]
        if built is not None:
            built = Model(run.robot, [t for t in terms if not isinstance(t, Geometric) or built.geometric_free],
                          jit=built.jit)
    later = [t for t in terms if _to_fit_later(t)]
    run.want_rbf = any(isinstance(t, RBFCompensator) for t in later)
    run.want_gp = any(t.name == "gp_compensator" for t in later)
    run.terms = [t for t in terms if t not in later]
    run.built = built
