"""Exceptions and warnings raised by casadical.

Every error a user can cause by bad input derives from :class:`CasadicalError`;
the command line prints such errors as one line and exits non-zero.
"""

from __future__ import annotations


class CasadicalError(Exception):
    """Base class of every error casadical raises on purpose."""


class InputError(CasadicalError, ValueError):
    """Bad user input located in a file.

    Parameters
    ----------
    message : str
        What is wrong, and ideally how to fix it.
    file : str, optional
        The file at fault.
    row : int, optional
        1-based line number in the file (the header is line 1 of a CSV).
    column : str, optional
        Column (CSV) or ``table.key`` (TOML) at fault.
    """

    def __init__(self, message: str, file: str | None = None,
                 row: int | None = None, column: str | None = None):
        self.message = message
        self.file = file
        self.row = row
        self.column = column
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.file is not None:
            where.append(str(self.file))
        if self.row is not None:
            where.append(f"row {self.row}")
        if self.column is not None:
            where.append(f"column {self.column!r}")
        prefix = ", ".join(where)
        return f"{prefix}: {self.message}" if prefix else self.message


class RobotFileError(InputError):
    """A robot description (TOML) is malformed; ``column`` holds ``table.key``."""


class DataFileError(InputError):
    """A measurement CSV is malformed."""


class ColumnMapError(InputError):
    """A column mapping (TOML file, preset or ``--map key=value``) is invalid; ``column`` holds the key."""


class TermsFileError(InputError):
    """A terms file (causes of one's own, TOML) or the definitions a calibration JSON carries is invalid.

    One line naming the file, the term, the key and the token at fault: ``terms.toml, term 'axis_wobble', key
    'frame[3]': '__import__' is not a name an expression may use (...)``.
    """

    def __init__(self, message: str, file: str | None = None, term: str | None = None, key: str | None = None):
        self.term, self.key = term, key
        super().__init__(message, file=file)

    def _format(self) -> str:
        where = [str(self.file)] if self.file is not None else []
        if getattr(self, "term", None) is not None:
            where.append(f"term {self.term!r}")
        if getattr(self, "key", None) is not None:
            where.append(f"key {self.key!r}")
        return ", ".join(where) + ": " + self.message if where else self.message


class ProgramError(InputError):
    """A robot program (URScript, KUKA KRL, ABB RAPID) that ``compensate`` cannot read or correct.

    One line naming the file, the line and the token at fault: ``cell.src, line 12, token 'SPTP': ...``.
    """

    def __init__(self, message: str, file: str | None = None, line: int | None = None, token: str | None = None):
        self.token = token
        super().__init__(message, file=file, row=line)

    def _format(self) -> str:
        where = [str(self.file)] if self.file is not None else []
        if self.row is not None:
            where.append(f"line {self.row}")
        if getattr(self, "token", None) is not None:
            where.append(f"token {self.token!r}")
        return ", ".join(where) + ": " + self.message if where else self.message


class ModelError(CasadicalError):
    """A model cannot be built from the given robot and error terms."""


class IdentifiabilityError(CasadicalError):
    """The poses cannot identify the requested parameters (too few, degenerate)."""


class SolverError(CasadicalError):
    """A solver failed in a way that leaves no usable result."""


class SimulationError(CasadicalError):
    """A simulation cannot make what it was asked (a touch the simulated robot cannot reach)."""


class CalibrationFileError(InputError):
    """A calibration JSON written by ``calibrate`` cannot be read back."""


class SettingError(CasadicalError, ValueError):
    """A setting (environment variable or Python setting) has a value casadical cannot use."""


class CasadicalWarning(UserWarning):
    """Base class of casadical's warnings."""


class DataWarning(CasadicalWarning):
    """Suspicious but usable input data (e.g. angles that look like radians)."""


class ConvergenceWarning(CasadicalWarning):
    """A solver stopped before meeting its convergence test."""


class IdentifiabilityWarning(CasadicalWarning):
    """The poses leave parameters unidentified that better poses could identify."""


class ExtrapolationWarning(CasadicalWarning):
    """Poses outside the joint ranges (or far from the poses) a calibration was fitted on."""


class PhysicsWarning(CasadicalWarning):
    """A term of the model that, as fitted, is not the physical cause its name says (casadical.stats._physics)."""


class CorrelationWarning(CasadicalWarning):
    """Identified parameters are strongly correlated or sit at a bound."""


class ParallelAxesWarning(CasadicalWarning):
    """Consecutive joint axes of a robot file are parallel and the link has no Hayati ``beta_deg``: a small tilt
    between them cannot be calibrated, and the link's offset along the axes is ill-conditioned."""


class GravityWarning(CasadicalWarning):
    """The robot file's gravity disagrees with the levelled instrument's down as the fitted base pose puts it (the
    arm described with another mounting: casadical.calibration._gravity)."""


class SignificanceWarning(CasadicalWarning):
    """Parameters of an error term are not significant: the poses do not determine what the term models."""


def listing(items, k: int = 8) -> str:
    """The first ``k`` items, comma separated, and how many more there are (for messages)."""
    items = [str(x) for x in items]
    return ", ".join(items[:k]) + (f" and {len(items) - k} more" if len(items) > k else "")
