"""Run a study: the repetitions not yet in the results folder, serially or on Dask.

Both backends run the same task (:func:`casadical.study._task.run_task`) and
hand its rows to the same writer in this process, which appends them to the
results folder in batches (when a repetition finishes ``flush_s`` seconds or
more after the last write, and whatever is finished when the run stops,
interrupted or not). A restarted run skips the repetitions already stored.

Dask (``dask.distributed``) is optional: a local cluster of worker
processes by default, or any running cluster given by its scheduler
address. Dask reschedules the tasks of a worker that dies; the writer
stores each repetition once, whichever worker finished it.
"""

from __future__ import annotations

import gc
import itertools
import logging
import secrets
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .. import __version__
from ..errors import CasadicalError, InputError
from ..runtime._interrupts import checkpoint, deferred
from ..runtime._threads import usable_cores
from ._protocol import Study
from ._store import ResultStore
from ._task import error_rows, run_task

#: tasks submitted to the Dask cluster per worker and not yet finished (the rest wait in this process)
IN_FLIGHT_PER_WORKER = 4

#: called after each finished repetition with (repetition, its rows); may raise to stop the run
Progress = Callable[[int, list], None]


@dataclass
class RunReport:
    """What a run did.

    Attributes
    ----------
    repetitions : int
        Repetitions of the study.
    skipped : int
        Already in the results folder when the run started.
    computed : int
        Finished and stored by this run.
    error_rows : int
        Rows with ``status`` ``error`` or ``lost`` among those stored by this run.
    time_s : float
    backend : str
        ``serial``, ``dask`` (a local cluster) or the scheduler address.
    workers : int
    """

    repetitions: int
    skipped: int
    computed: int = 0
    error_rows: int = 0
    time_s: float = 0.0
    backend: str = "serial"
    workers: int = 1


class _Writer:
    """Buffers finished repetitions and appends them to the store in batches."""

    def __init__(self, store: ResultStore, report: RunReport, flush_s: float):
        self.store, self.report, self.flush_s = store, report, flush_s
        self.rows: list[dict] = []
        self.last = time.monotonic()

    def add(self, rows: list[dict]) -> None:
        self.rows += rows
        self.report.computed += 1
        self.report.error_rows += sum(r["status"] != "ok" for r in rows)
        if time.monotonic() - self.last >= self.flush_s:
            self.flush()

    def flush(self) -> None:
        if self.rows:
            self.store.append(self.rows)
            self.rows = []
        self.last = time.monotonic()


def run_study(study: Study, out: str | Path, *, backend: str = "dask", workers: int | None = None,
              scheduler: str | None = None, client=None, force: bool = False, progress: Progress | None = None,
              flush_s: float = 10.0, on_start: Callable[[RunReport], None] | None = None) -> RunReport:
    """Run the repetitions of ``study`` that ``out`` does not hold yet.

    Parameters
    ----------
    study : Study
    out : path
        Results folder (created, or resumed if it holds this protocol's results).
    backend : {"dask", "serial"}
    workers : int, optional
        Worker processes of the local Dask cluster (default: one per core).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) instead of a local cluster.
    client : distributed.Client, optional
        A client to use as it is (not closed here).
    force : bool
        Discard what ``out`` holds and start over.
    progress : callable, optional
        Called in this process after each stored repetition.
    flush_s : float
        Write a batch when a repetition finishes this long or longer after the last write
        (0: each repetition at once).
    on_start : callable, optional
        Called with the report once the folder is open and the work is known.

    Returns
    -------
    RunReport

    Raises
    ------
    InputError
        The folder cannot take this study (see :meth:`ResultStore.for_study`).
    CasadicalError
        Dask or pyarrow is missing, or the cluster cannot run casadical.
    """
    if backend not in ("dask", "serial"):
        raise InputError(f"unknown backend {backend!r}; use 'dask' or 'serial'")
    if backend == "dask" and client is None:
        _distributed()            # a missing Dask fails before the results folder is touched
    own_client = None
    if backend == "dask" and client is None and scheduler:
        client = own_client = _connect(scheduler)    # an unreachable scheduler, too
    try:
        return _run(study, Path(out), backend, workers, scheduler, client, force, progress, flush_s, on_start)
    finally:
        if own_client is not None:
            own_client.close()


#: how long a client tries to reach a running Dask cluster (Dask retries a refused connection until then)
CONNECT_TIMEOUT_S = 20


def _connect(scheduler: str):
    """A client of the running Dask cluster at ``scheduler``.

    A client that fails to connect is freed here. Its exception's frames hold it, and left to the garbage collector
    its ``__del__`` runs whenever a collection comes. That may be inside another client's start, which holds the
    one lock of Dask's loop runners (``distributed.utils.LoopRunner._lock``) that the dying client's close takes:
    the process hangs (a test suite did, on the test after an unreachable scheduler's)."""
    distributed = _distributed()
    try:
        return distributed.Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError) as e:
        cause = e
    error, link = InputError(f"cannot reach the Dask scheduler: {cause}", file=scheduler), cause
    while link is not None:         # the exception and those it came from, without their frames
        link.__traceback__ = None
        link = link.__cause__ or link.__context__
    gc.collect()                    # the failed client is garbage now: its close runs here, holding no lock
    raise error from cause


def _run(study: Study, out: Path, backend: str, workers, scheduler, client, force: bool, progress, flush_s: float,
         on_start) -> RunReport:
    t0 = time.perf_counter()
    with ResultStore.for_study(out, study, force) as store:
        done = store.finished()
        todo = [r for r in range(study.repetitions) if r not in done]   # protocol: at most MAX_REPETITIONS
        report = RunReport(study.repetitions, study.repetitions - len(todo))
        writer = _Writer(store, report, flush_s)

        def finished(rep: int, rows: list[dict]) -> None:
            writer.add(rows)
            if progress is not None:
                progress(rep, rows)
            checkpoint("repetition")

        try:
            try:
                if backend == "serial" or not todo:
                    if on_start:
                        on_start(report)
                    for rep in todo:
                        finished(rep, run_task(study, rep))
                else:
                    _run_dask(study, todo, finished, report, workers, scheduler, client, on_start)
            finally:
                writer.flush()
                report.time_s = time.perf_counter() - t0
        except BaseException:
            store.discard_if_empty()   # a failed start leaves nothing behind (a folder this run made, empty)
            raise
    return report


def _distributed():
    try:
        import distributed
    except ImportError:
        raise CasadicalError("running a study on Dask needs dask.distributed, which is not installed: "
                             "pip install 'casadical[study]' (or use --serial)") from None
    return distributed


def _run_dask(study: Study, todo: list[int], finished, report: RunReport, workers, scheduler, client,
              on_start) -> None:
    distributed = _distributed()
    own_client = own_cluster = None
    try:
        if scheduler:
            if client is None:
                client = own_client = _connect(scheduler)
            report.backend = scheduler
        elif client is None:
            # an interrupt while the cluster starts waits until it has started, and is then raised here: a
            # cluster cut short in its start cannot be closed (its workers would print tracebacks at exit)
            with deferred():
                # workers log at CRITICAL only: a task's own failure comes back through its future (a lost
                # row), and a worker whose scheduler closed first at a signal logged a heartbeat traceback
                own_cluster = distributed.LocalCluster(n_workers=workers or usable_cores(), threads_per_worker=1,
                                                       processes=True, dashboard_address=":0",
                                                       silence_logs=logging.CRITICAL)
                checkpoint("cluster")
                client = own_client = distributed.Client(own_cluster)
                client.register_plugin(_ignore_interrupts(distributed)(), name="casadical-ignore-sigint")
            report.backend = "dask"
        _check_workers(client)
        report.workers = len(client.scheduler_info()["workers"])
        if on_start:
            on_start(report)
        run = secrets.token_hex(4)   # keys of an earlier, interrupted run on the same cluster may linger
        futures: dict = {}
        pending = iter(todo)

        def submit(rep: int):
            fut = client.submit(run_task, study, rep, key=f"casadical-study-{run}-{rep}")
            futures[fut] = rep
            return fut

        # a bounded number of tasks in flight: the scheduler, the client and this loop hold a few per worker,
        # not one per repetition (a million repetitions would take gigabytes)
        first = [submit(rep) for rep in itertools.islice(pending, max(IN_FLIGHT_PER_WORKER * report.workers, 8))]
        queue = distributed.as_completed(first, with_results=True, raise_errors=False)
        try:
            for fut, result in queue:
                rep = futures.pop(fut)
                if fut.status != "finished":
                    # the task itself failed, e.g. it kept killing its workers (KilledWorker): kept as lost
                    # rows, computed again by a resumed run
                    result = error_rows(study, rep, fut.exception() if fut.status == "error" else str(result),
                                        status="lost")
                fut.release()
                finished(rep, result)
                nxt = next(pending, None)
                if nxt is not None:
                    queue.add(submit(nxt))
        finally:
            client.cancel(list(futures))
    finally:
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()


def _ignore_interrupts(distributed):
    """A worker plugin: Ctrl-C is for the process that runs the study, which stops the workers itself.

    The local cluster's workers share the terminal's process group; without
    this each would print a KeyboardInterrupt traceback, and the run's own
    one-line message would drown.
    """
    class IgnoreInterrupts(distributed.WorkerPlugin):
        def setup(self, worker) -> None:
            import signal
            signal.signal(signal.SIGINT, signal.SIG_IGN)

    return IgnoreInterrupts


def _check_workers(client) -> None:
    """Every worker must import casadical; a different version is worth a warning."""
    import importlib.metadata
    import warnings

    from ..errors import CasadicalWarning

    try:
        versions = client.run(importlib.metadata.version, "casadical")
    except importlib.metadata.PackageNotFoundError as e:
        raise CasadicalError("a Dask worker cannot import casadical: install it (with the same version, "
                             f"{__version__}) where the workers run") from e
    other = {v for v in versions.values() if v != __version__}
    if other:
        warnings.warn(f"Dask workers run casadical {', '.join(sorted(other))}, this process {__version__}: "
                      "their rows may differ from a local run", CasadicalWarning, stacklevel=3)
