"""Monte Carlo studies: many simulated repetitions of pose plans x calibration methods.

- :mod:`~casadical.study.protocol` -- the study TOML (:func:`load_study`);
- :mod:`~casadical.study.task` -- one repetition (:func:`run_task`), the
  task every backend runs, deterministic from the study seed and its index;
- :mod:`~casadical.study.store` -- the results folder (a Parquet dataset,
  appended as repetitions finish, resumed after an interruption);
- :mod:`~casadical.study.runner` -- :func:`run_study`, serially or on Dask;
- :mod:`~casadical.study.summary` -- the comparison table and plots.

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
_EXPORTS = {"MethodSpec": "protocol", "PlanSpec": "protocol", "Study": "protocol", "load_study": "protocol",
            "RunReport": "runner", "run_study": "runner", "ResultStore": "store", "Summary": "summary",
            "plot_summary": "summary", "summarize": "summary", "COLUMNS": "task", "TIME_COLUMNS": "task",
            "Repetition": "task", "draw_repetition": "task", "run_task": "task"}

__all__ = ["COLUMNS", "MethodSpec", "PlanSpec", "Repetition", "ResultStore", "RunReport", "Study", "Summary",
           "TIME_COLUMNS", "draw_repetition", "load_study", "plot_summary", "run_study", "run_task", "summarize"]

if _typing.TYPE_CHECKING:
    from .protocol import MethodSpec, PlanSpec, Study, load_study
    from .runner import RunReport, run_study
    from .store import ResultStore
    from .summary import Summary, plot_summary, summarize
    from .task import COLUMNS, TIME_COLUMNS, Repetition, draw_repetition, run_task
else:
    __getattr__, __dir__ = lazy(__name__, globals(), _EXPORTS)
