"""``study``: Monte Carlo studies of pose plans x calibration methods, on Dask or serially."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError
from ..runtime._interrupts import answered, exit_code
from ._common import Status, add_json, add_quiet, check_outputs, human_stream, int_at_least, write_json


def register(sub) -> None:
    p = sub.add_parser(
        "study", help="run a Monte Carlo study of pose plans and methods (Dask), or summarise one",
        description="Run the repetitions of a study protocol (TOML, or a name in problems/studies) that "
                    "RESULTS does not hold yet: each draws a true robot, selects the calibration poses of "
                    "every plan and runs every method on them. Rows stream into RESULTS (a Parquet "
                    "folder) as repetitions finish; run the same command again to resume an interrupted "
                    "study. On a local Dask cluster by default (needs the 'study' extra). With --summary, "
                    "print the comparison table of RESULTS and write its plots.")
    p.add_argument("protocol", nargs="?", metavar="PROTOCOL.toml", help="study protocol (file or bundled name)")
    p.add_argument("--out", metavar="RESULTS", help="results folder (created, or resumed)")
    p.add_argument("--workers", type=int_at_least(1), default=None, metavar="N",
                   help="worker processes of the local Dask cluster (default: one per core)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="use the running Dask cluster at ADDRESS")
    p.add_argument("--serial", action="store_true", help="run in this process, without Dask")
    p.add_argument("--summary", metavar="RESULTS", help="summarise RESULTS instead of running a study")
    p.add_argument("--baseline", metavar="METHOD", help="method the win rates are against (default: the first)")
    p.add_argument("--metric", default=None,
                   help="float column to compare (default: val_mean_mm; val_consistency_mm for a study of touches; "
                        "e.g. val_true_mean_mm)")
    p.add_argument("--plot-dir", metavar="DIR", help="write errors.png (and poses.png) into DIR (created)")
    add_json(p, "the comparison table (and, after a run, what the run did)")
    add_quiet(p)
    p.add_argument("--force", action="store_true",
                   help="discard the results RESULTS holds (of this or another protocol) and start over; "
                        "replace existing plots")
    p.set_defaults(func=cmd_study)


def cmd_study(args) -> int:
    from ..study import load_study
    from ..study._summary import METRICS

    if args.metric is not None and args.metric not in METRICS:
        raise InputError(f"--metric: unknown column {args.metric!r}; choose from {', '.join(METRICS)}")
    if args.summary:
        given = [o for o, v in (("PROTOCOL.toml", args.protocol), ("--out", args.out), ("--workers", args.workers),
                                ("--scheduler", args.scheduler), ("--serial", args.serial)) if v]
        if given:
            raise InputError(f"study --summary takes RESULTS only, not {', '.join(given)}")
        _check_outputs(args)
        return _summary(args, args.summary)
    if not args.protocol or not args.out:
        raise InputError("study: give PROTOCOL.toml and --out RESULTS to run a study, or --summary RESULTS")
    if args.serial and (args.workers or args.scheduler):
        raise InputError("--serial runs without Dask: leave out --workers and --scheduler")
    if args.workers and args.scheduler:
        raise InputError("--workers starts a local cluster; a cluster given by --scheduler has its own workers")
    study = load_study(args.protocol)
    if args.baseline and args.baseline.strip().lower() not in {m.name.lower() for m in study.methods}:
        raise InputError(f"--baseline: no method {args.baseline!r} in this study; its methods: "
                         + ", ".join(m.name for m in study.methods), file=study.path)
    _check_outputs(args)
    return _run(args, study)


def _check_outputs(args) -> None:
    """--json and --plot-dir, before any work. In a run --force also discards the results, so there an output
    that exists is refused whatever --force says (``study --summary RESULTS ... --force`` replaces it)."""
    running = not args.summary
    existing = [Path(args.json)] if args.json and args.json != "-" else []
    existing += [Path(args.plot_dir) / name for name in ("errors.png", "poses.png")] if args.plot_dir else []
    for path in existing:
        if path.exists() and path.is_file() and (running or not args.force):
            raise InputError("exists already; " + (
                "choose another path, or replace it after the run with 'study --summary RESULTS ... --force' "
                "(in a run, --force discards the results)" if running else
                "choose another path or pass --force to replace it"), file=str(path))
    check_outputs({"--json": args.json}, [args.protocol] if args.protocol else [], args.force)
    if args.plot_dir:
        from ..methods._compare import pyplot
        pyplot()                   # a missing matplotlib fails before the work


def _run(args, study) -> int:
    from ..study import run_study

    status = Status(args.quiet)
    cells = study.cells()
    status.line(f"study {study.name}: {study.repetitions} repetitions x {len(cells)} plans x "
                f"{len(study.methods)} methods ({study.rows_per_repetition} rows per repetition), seed {study.seed}")
    state = {"bar": None, "stored": 0, "errors": 0}

    def started(report) -> None:
        where = "this process" if report.backend == "serial" else (
            f"a local Dask cluster of {_workers(report.workers)}" if report.backend == "dask"
            else f"the Dask cluster at {report.backend} ({_workers(report.workers)})")
        todo = report.repetitions - report.skipped
        status.line(f"{report.skipped} repetitions already in {args.out}; running {todo} on {where}")
        state["bar"] = status.bar(todo, "repetitions", unit="rep")
        state["stored"] = report.skipped

    def progress(rep: int, rows: list) -> None:
        state["stored"] += 1
        state["errors"] += sum(r["status"] != "ok" for r in rows)
        state["bar"].update(1)
        if state["errors"]:
            state["bar"].set_postfix(error_rows=state["errors"])

    if args.scheduler:          # Dask retries a refused connection until its timeout: say why nothing moves
        from ..study._runner import CONNECT_TIMEOUT_S
        status.line(f"connecting to the Dask scheduler at {args.scheduler} (trying for up to {CONNECT_TIMEOUT_S} s)")
    try:
        report = run_study(study, args.out, backend="serial" if args.serial else "dask", workers=args.workers,
                           scheduler=args.scheduler, force=args.force, progress=progress, on_start=started)
    except KeyboardInterrupt as e:
        answered()     # said here, with what the folder holds
        if state["bar"] is not None:
            state["bar"].close()
        what = "interrupted" if exit_code(e) == 130 else f"stopped by {e.args[0] if e.args else 'a signal'}"
        print(f"casadical: {what}: {state['stored']} of {study.repetitions} repetitions are in {args.out}; "
              "run the same command again to resume", file=sys.stderr)
        return exit_code(e)
    finally:
        if state["bar"] is not None:
            state["bar"].close()
    print(f"{report.computed} repetitions in {report.time_s:.1f} s ({report.error_rows} rows with errors); "
          f"{report.skipped + report.computed} of {report.repetitions} in {args.out}", file=human_stream(args.json))
    run = {"results": args.out, "computed": report.computed, "skipped": report.skipped,
           "repetitions": report.repetitions, "error_rows": report.error_rows, "time_s": report.time_s}
    return _summary(args, args.out, run)


def _workers(n: int) -> str:
    return f"{n} worker" + ("" if n == 1 else "s")


def _summary(args, results: str, run: dict | None = None) -> int:
    from ..study import plot_summary, summarize

    out = human_stream(args.json)          # --json -: standard output holds the JSON alone
    summary = summarize(results, baseline=args.baseline, metric=args.metric)
    print(file=out)
    print(summary.table(), file=out)
    if args.plot_dir:
        Path(args.plot_dir).mkdir(parents=True, exist_ok=True)
        for path in plot_summary(summary, args.plot_dir, overwrite=args.force):
            print(f"plot -> {path}", file=out)
    if args.json:
        doc = {"results": results, **summary.to_dict()}
        if run is not None:
            doc["run"] = run
        write_json(args.json, doc, args.force)
        print(f"summary -> {'standard output' if args.json == '-' else args.json}", file=out)
    return 0
