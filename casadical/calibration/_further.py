"""Taking a calibration further (part of stage ``build_model``): only what the model names is estimated again.

The calibration's terms are extended by the specification's (:func:`merge_terms`);
what describes the session the calibration was measured in is dropped
unless named; the base pose, the named terms and new parameters are free
(:func:`named_free`), every other value and std is the calibration's.
"""

from __future__ import annotations

from ..data._calibration_file import restore_term
from ..errors import CasadicalWarning
from ..model._symbolic import Model, spec_of
from ..parameters import Parameters
from ..terms import ErrorTerm, SessionLocal
from ..terms._geometric import Geometric
from ._for_data import set_references, with_sessions
from ._state import CalibrationRun


def merge_terms(prior: list[ErrorTerm], new: list[ErrorTerm]) -> tuple[list[ErrorTerm], set[str]]:
    """Terms of a calibration extended by a specification's terms; the names of the latter's terms.

    A term of the same kind as one already there is merged (its joints or
    harmonics joined); settings (reference temperature, network, ...) are kept.
    """
    out = list(prior)
    named: set[str] = set()
    for t in new:
        named.add(t.name)
        same = next((k for k, p in enumerate(out) if type(p) is type(t)), None)
        if same is None:
            out.append(t)
            continue
        p = out[same]
        if hasattr(t, "harmonics"):
            merged = sorted(set(p.harmonics) | set(t.harmonics))
            out[same] = restore_term(type(t)(merged), p.settings())
        elif hasattr(t, "pairs"):            # a joint coupling: (joint, source joint) pairs joined
            out[same] = type(t)(pairs=sorted(set(p.pairs) | set(t.pairs)))
        elif t.joints is not None and p.joints is not None and set(t.joints) - set(p.joints):
            out[same] = restore_term(type(t)(sorted(set(p.joints) | set(t.joints))), p.settings())
    return out, named


def named_free(params: Parameters, named: set[str], new_params: set[str]) -> list[str]:
    """Parameters re-estimated when a calibration is taken further: base, named terms (``tool``: the tool
    offset), new ones."""
    return [p.name for p in params if p.group == "base" or p.term in named or p.name in new_params
            or (p.group == "tool" and "tool" in named)]


def take_further(run: CalibrationRun) -> None:
    """Sets ``model``, ``params`` and ``kept`` from the calibration ``run.prior`` and the terms asked for."""
    prior, data, opts = run.prior, run.data, run.options
    merged, named = merge_terms(list(prior.model.terms), run.terms)
    # what describes the session the calibration was measured in (drift, a GP compensator) is not
    # the robot's: it is dropped, unless the model names it (then it is estimated for these poses)
    dropped = [t for t in merged if t.session and (t.name not in named or isinstance(t, SessionLocal)
                                                   or t.name == "sessions")
               and not (opts.keep_compensator and t.name == "gp_compensator")]
    merged = [t for t in merged if t not in dropped]
    if dropped:
        run.note(f"{', '.join(t.spec() for t in dropped)} dropped: "
                 f"{'it belongs' if len(dropped) == 1 else 'they belong'} to the measurement session of the "
                 "calibration, not to the robot; name it in the model to estimate it for these poses",
                 CasadicalWarning)
    if run.full_pose:   # the probe's mounting is estimated again, like the base pose
        named.add("tool_orientation")
    geometric = prior.model.geometric_free or Geometric.name in named
    session = [t for t in merged if t.session]     # named again: estimated for these poses, from zero
    set_references(session, data)
    merged = with_sessions(merged, data, opts.session_tools)
    session += [t for t in merged if t.name == "sessions"]
    # the same terms: the calibration's own model (its symbolic build and evaluators) serves again
    model = prior.model if spec_of(merged, geometric) == prior.model.spec and not session else \
        Model(run.robot, [t for t in merged if not isinstance(t, Geometric) or geometric], jit=prior.model.jit)
    old = {p.name for p in prior.parameters}
    params = model.parameters.copy()
    new_params = {p.name for p in params if p.name not in old}
    free = set(named_free(params, named | ({"tool"} if run.free_tool else set()), new_params))
    for p in params:
        if p.name in old and p.term not in {t.name for t in session}:
            src = prior.parameters[p.name]
            p.value, p.std, p.identifiable = src.value, src.std, src.identifiable
        p.fixed = p.name not in free
        if p.fixed:
            p.reason = "kept from the calibration"
        elif p.name in old and prior.parameters[p.name].fixed and p.group != "base":
            # what the calibration could not identify stays put unless these poses can
            p.reason = ""
    run.model, run.params = model, params
    run.kept = {p.name for p in params if p.fixed} - set(opts.fix)   # their std too comes from the calibration
