"""The run time under every layer: thread limits, Ctrl-C and SIGTERM, safe file writing."""

import typing as _typing

from .._lazy import lazy

#: public name -> its private module, imported on first use (PEP 562)
_EXPORTS = {"ENV": "_threads", "EVAL_ENV": "_threads", "EVAL_MAX": "_threads", "EXISTS": "_files", "Kept": "_kept",
            "answered": "_interrupts", "array_key": "_kept", "atomic_open": "_files", "atomic_write": "_files",
            "blas_threads": "_threads", "checkpoint": "_interrupts", "deferred": "_interrupts",
            "evaluation_pool": "_threads", "evaluation_threads": "_threads", "exit_code": "_interrupts",
            "finite_number": "_files", "get_threads": "_threads", "handle_signals": "_interrupts",
            "limited_threads": "_threads", "named_toml": "_files", "noticed": "_interrupts",
            "outputs_together": "_files", "pose_chunks": "_chunks", "read_toml": "_files", "set_threads": "_threads",
            "usable_cores": "_threads", "wanted": "_interrupts"}

__all__ = [
    "ENV", "EVAL_ENV", "EVAL_MAX", "EXISTS", "Kept", "answered", "array_key", "atomic_open", "atomic_write",
    "blas_threads", "checkpoint", "deferred", "evaluation_pool", "evaluation_threads", "exit_code", "finite_number",
    "get_threads", "handle_signals", "limited_threads", "named_toml", "noticed", "outputs_together", "pose_chunks",
    "read_toml", "set_threads", "usable_cores", "wanted",
]

if _typing.TYPE_CHECKING:
    from ._chunks import pose_chunks
    from ._files import EXISTS, atomic_open, atomic_write, finite_number, named_toml, outputs_together, read_toml
    from ._interrupts import answered, checkpoint, deferred, exit_code, handle_signals, noticed, wanted
    from ._kept import Kept, array_key
    from ._threads import (
        ENV,
        EVAL_ENV,
        EVAL_MAX,
        blas_threads,
        evaluation_pool,
        evaluation_threads,
        get_threads,
        limited_threads,
        set_threads,
        usable_cores,
    )
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
