"""What a cause's acceptance or rejection carries: :class:`Support` and :class:`Evidence`."""

from __future__ import annotations

from dataclasses import dataclass

from ._candidates import Candidate
from ._statistics import NestedTest


@dataclass
class Support:
    """Why a cause was accepted: its test against the model it extends (the one-step fit), the held-out means
    (mm, by kind of fold) before and after it, and the checks a named cause passes (:mod:`._nameable`)."""

    test: NestedTest
    cv_before: dict
    cv_after: dict
    checks: dict


@dataclass
class Evidence:
    """Significant structure a candidate fitted that cannot be named as that cause: its values, why it was
    supported, what it would gain on the validation poses (mm) and why it is not a cause."""

    candidate: Candidate
    values: dict
    support: Support
    potential_gain_mm: float
    why: str
