"""Monte Carlo studies: many simulated repetitions of pose plans x calibration methods.

- :mod:`~casadical.study._protocol` -- the study TOML (:func:`load_study`);
- :mod:`~casadical.study._task` -- one repetition (:func:`run_task`), the
  task every backend runs, deterministic from the study seed and its index;
- :mod:`~casadical.study._store` -- the results folder (a Parquet dataset,
  appended as repetitions finish, resumed after an interruption);
- :mod:`~casadical.study._runner` -- :func:`run_study`, serially or on Dask;
- :mod:`~casadical.study._summary` -- the comparison table and plots.

Dask and pyarrow are optional (``pip install 'casadical[study]'``) and
imported only when a study runs or its results are read.

>>> from casadical.study import load_study, run_study, summarize
>>> study = load_study("ca-ys100")                                   # doctest: +SKIP
>>> run_study(study, "out/ca.parquet", workers=2)                    # doctest: +SKIP
>>> print(summarize("out/ca.parquet", baseline="KM").table())       # doctest: +SKIP
"""

import typing as _typing

from .._lazy import lazy

#: public name -> its module, imported on first use (PEP 562): importing one module of the package
#: imports no other
_EXPORTS = {"MethodSpec": "_protocol", "PlanSpec": "_protocol", "Study": "_protocol", "load_study": "_protocol",
            "RunReport": "_runner", "run_study": "_runner", "ResultStore": "_store", "Summary": "_summary",
            "plot_summary": "_summary", "summarize": "_summary", "COLUMNS": "_task", "TIME_COLUMNS": "_task",
            "Repetition": "_task", "draw_repetition": "_task", "run_task": "_task", "CONNECT_TIMEOUT_S": "_runner",
            "METRICS": "_summary", "STUDY_DIR": "_protocol", "differing_columns": "_store"}

__all__ = [
    "COLUMNS", "CONNECT_TIMEOUT_S", "METRICS", "MethodSpec", "PlanSpec", "Repetition", "ResultStore", "RunReport",
    "STUDY_DIR", "Study", "Summary", "TIME_COLUMNS", "differing_columns", "draw_repetition", "load_study",
    "plot_summary", "run_study", "run_task", "summarize",
]

if _typing.TYPE_CHECKING:
    from ._protocol import STUDY_DIR, MethodSpec, PlanSpec, Study, load_study
    from ._runner import CONNECT_TIMEOUT_S, RunReport, run_study
    from ._store import ResultStore, differing_columns
    from ._summary import METRICS, Summary, plot_summary, summarize
    from ._task import COLUMNS, TIME_COLUMNS, Repetition, draw_repetition, run_task
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
