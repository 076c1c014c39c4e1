"""Measurements and the files around them: the CSV contract, sessions, simulated data with known truth,
plausibility checks of poses, and the validation of a calibration file."""

import typing as _typing

from .._lazy import lazy

#: public name -> its module; imported on first use, so that importing one module of the package does not
#: import the others (PEP 562)
_EXPORTS = {"Measurements": "_measurements", "Effects": "_simulate", "MAX_POSES": "_simulate",
            "MIN_TOUCH_ROWS": "_measurements", "NUMERIC_OPTIONAL": "_measurements", "REACH_SHARE": "_checks",
            "RXYZ": "_measurements", "TomlValidator": "_simulate", "Truth": "_simulate", "XYZ": "_measurements",
            "another_session": "_simulate", "base_fitted_errors": "_checks", "check_calibration_fits": "_checks",
            "check_distinct_poses": "_checks", "check_held_out": "_checks", "check_other_series": "_checks",
            "check_poses": "_checks", "check_validation_frames": "_checks", "combine": "_sessions",
            "effects_from_table": "_simulate", "file_session_names": "_sessions", "first_rows": "_poses",
            "load_protocol": "_simulate", "looks_like_radians": "_measurements", "own_columns": "_covariates",
            "pose_covariates": "_covariates", "pose_index": "_poses", "read_sessions": "_sessions",
            "resolve_path": "_simulate", "restore_term": "_calibration_file", "restored_terms": "_calibration_file",
            "sample_poses": "_simulate", "session_covariates": "_covariates", "session_index": "_measurements",
            "session_name": "_measurements", "simulate": "_simulate", "spread": "_checks",
            "touch_rows": "_simulate_touches", "true_model": "_simulate", "user_definitions": "_calibration_file",
            "validate_calibration_document": "_calibration_file", "workspace_from_table": "_simulate"}

__all__ = [
    "Effects", "MAX_POSES", "MIN_TOUCH_ROWS", "Measurements", "NUMERIC_OPTIONAL", "REACH_SHARE", "RXYZ",
    "TomlValidator", "Truth", "XYZ", "another_session", "base_fitted_errors", "check_calibration_fits",
    "check_distinct_poses", "check_held_out", "check_other_series", "check_poses", "check_validation_frames",
    "combine", "effects_from_table", "file_session_names", "first_rows", "load_protocol", "looks_like_radians",
    "own_columns", "pose_covariates", "pose_index", "read_sessions", "resolve_path", "restore_term", "restored_terms",
    "sample_poses", "session_covariates", "session_index", "session_name", "simulate", "spread", "touch_rows",
    "true_model", "user_definitions", "validate_calibration_document", "workspace_from_table",
]

if _typing.TYPE_CHECKING:
    from ._calibration_file import restore_term, restored_terms, user_definitions, validate_calibration_document
    from ._checks import (
        REACH_SHARE,
        base_fitted_errors,
        check_calibration_fits,
        check_distinct_poses,
        check_held_out,
        check_other_series,
        check_poses,
        check_validation_frames,
        spread,
    )
    from ._covariates import own_columns, pose_covariates, session_covariates
    from ._measurements import (
        MIN_TOUCH_ROWS,
        NUMERIC_OPTIONAL,
        RXYZ,
        XYZ,
        Measurements,
        looks_like_radians,
        session_index,
        session_name,
    )
    from ._poses import first_rows, pose_index
    from ._sessions import combine, file_session_names, read_sessions
    from ._simulate import (
        MAX_POSES,
        Effects,
        TomlValidator,
        Truth,
        another_session,
        effects_from_table,
        load_protocol,
        resolve_path,
        sample_poses,
        simulate,
        true_model,
        workspace_from_table,
    )
    from ._simulate_touches import touch_rows
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
