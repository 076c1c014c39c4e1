"""The calibration model: kinematics and named parameters (what the error terms build on), the symbolic
model the terms are assembled into (:mod:`._symbolic`), the superset every candidate model is a mask of,
and the compiled functions kept on disk."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module; imported on first use, so that importing one module of the package does not
#: import the others (PEP 562)
_EXPORTS = {"Model": "_symbolic", "parse_spec": "_symbolic", "BLOCK_MIN": "_symbolic", "Batch": "_batch",
            "Mapping": "_superset", "announcing": "_jitcache", "assemble_terms": "_symbolic",
            "base0_to_pose": "_symbolic", "batch": "_batch", "compiler_available": "_symbolic",
            "jit_setting": "_jitcache", "max_bytes": "_jitcache", "outputs": "_superset", "pose_to_base0": "_symbolic",
            "spec_of": "_symbolic", "superset_for": "_superset"}

__all__ = [
    "BLOCK_MIN", "Batch", "Mapping", "Model", "announcing", "assemble_terms", "base0_to_pose", "batch",
    "compiler_available", "jit_setting", "max_bytes", "outputs", "parse_spec", "pose_to_base0", "spec_of",
    "superset_for",
]

if _typing.TYPE_CHECKING:
    from ._batch import Batch, batch
    from ._jitcache import announcing, jit_setting, max_bytes
    from ._superset import Mapping, outputs, superset_for
    from ._symbolic import (
        BLOCK_MIN,
        Model,
        assemble_terms,
        base0_to_pose,
        compiler_available,
        parse_spec,
        pose_to_base0,
        spec_of,
    )
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
