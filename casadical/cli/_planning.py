"""``plan-poses`` and ``candidates``: which poses to measure."""

from __future__ import annotations

import argparse
import csv
import math
import time

import numpy as np

from ..errors import IdentifiabilityError, InputError
from ..runtime._files import atomic_open
from ._common import (
    Status,
    add_checks,
    add_fixture,
    add_force,
    add_json,
    add_quiet,
    add_terms,
    add_urdf_chain,
    check_options,
    check_outputs,
    fixtures,
    float_in,
    human_stream,
    int_at_least,
    robot_from_args,
    user_terms,
    write_json,
)
from ._programs import add_measurement_program, measurement_outputs, write_measurement_program


def register(sub) -> None:
    p = sub.add_parser(
        "plan-poses", help="select M poses to measure out of a candidate file",
        description="Select M poses out of CANDIDATES.csv (joint readings; other columns, e.g. "
                    "payload_kg, are kept and used) that identify the model's parameters best. "
                    "Writes the selected rows of the candidate file, in candidate order, and prints "
                    "the criterion, the observability indices O1..O5 and a certificate: an upper "
                    "bound on log det(J^T J) over all M-subsets and the selection's D-efficiency "
                    "against it.")
    p.add_argument("robot", metavar="ROBOT",
                   help="built-in robot (ys100, hh800, ur10), robot TOML or URDF file; or REPORT.json written by "
                        "diagnose --json: the M candidates that, added to the poses already measured, best answer "
                        "its open questions")
    p.add_argument("candidates", metavar="CANDIDATES.csv", help="candidate poses (q1_deg, ..., qN_deg)")
    p.add_argument("-m", dest="m", type=int_at_least(1), required=True, metavar="M", help="number of poses to select")
    p.add_argument("--out", required=True, metavar="SELECTED.csv", help="output CSV (selected rows)")
    p.add_argument("--measured", nargs="+", metavar="DATA.csv",
                   help="with REPORT.json: the poses the report was made from (default: the DATA files it names)")
    p.add_argument("--question", type=int_at_least(1), metavar="N",
                   help="with REPORT.json: plan for open question N alone (default: all of them)")
    p.add_argument("--session", metavar="S",
                   help="with REPORT.json of several sessions: the candidates are to be measured in session S (a "
                        "candidate file without a session column; default: the first session); SELECTED.csv gets "
                        "a session column saying so")
    p.add_argument("--random-sets", type=int_at_least(1), default=200, metavar="K",
                   help="with REPORT.json: random sets of M candidates the plan is compared with (default: 200)")
    method = p.add_argument("--method", type=_method, default="d-optimal",
                            help="d-optimal (certified relaxation + exchange), ga (the GA paper's selector, "
                                 "fitness O1) or random (default: %(default)s)")
    p.add_argument("--model", default="kinematic+compliance",
                   help="error model whose parameters the poses must identify (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the ga and random methods (default: 0)")
    p.add_argument("--relaxation", choices=("first-order", "cvxpy"), default="first-order",
                   help="solver of the continuous relaxation (default: %(default)s)")
    add_json(p, "the summary")
    add_measurement_program(p)
    add_fixture(p)
    add_checks(p)
    add_quiet(p)
    add_urdf_chain(p)
    add_terms(p)
    add_force(p)
    p.set_defaults(func=cmd_plan_poses)

    def complete_help(parser) -> None:   # the method names need the planning package: only for --help
        from ..planning._selectors import METHODS

        method.metavar = "{" + ",".join(METHODS) + "}"

    p.complete_help = complete_help

    p = sub.add_parser(
        "candidates", help="generate candidate poses within the joint limits and a workspace",
        description="Draw N joint-space poses uniformly within the joint limits (minus a margin), "
                    "keeping those whose tool point lies above the floor and inside the box "
                    "(robot base frame, metres). Writes q1_deg..qN_deg.")
    p.add_argument("robot", metavar="ROBOT", help="built-in robot (ys100, hh800, ur10), robot TOML or URDF file")
    p.add_argument("-n", dest="n", type=int_at_least(1), required=True, metavar="N", help="number of candidates")
    p.add_argument("--out", required=True, metavar="C.csv", help="output CSV")
    p.add_argument("--floor-z", default="0",
                   help="keep tool points above this height, m (default 0; 'none' disables)")
    p.add_argument("--box", default=None, metavar="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
                   help="keep tool points inside this box, m")
    p.add_argument("--margin-deg", type=float_in(0, 180, lo_open=False), default=5.0,
                   help="keep this far from the joint limits, degrees (millimetres for a prismatic joint, a linear "
                        "axis; default 5)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    add_urdf_chain(p)
    add_force(p)
    p.set_defaults(func=cmd_candidates)


def _method(text: str) -> str:
    """A ``--method``: one of the selectors' methods (checked here, not by argparse's ``choices``, so that the
    planning package is imported by the planning commands alone)."""
    from ..planning._selectors import METHODS

    if text not in METHODS:
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {', '.join(map(repr, METHODS))})")
    return text


def cmd_plan_poses(args) -> int:
    if args.robot.lower().endswith(".json"):
        return cmd_plan_report(args)
    for opt, given in (("--measured", args.measured), ("--question", args.question), ("--session", args.session)):
        if given:
            raise InputError(f"{opt} is for plan-poses REPORT.json (a diagnosis report in place of ROBOT)")
    from ..data._checks import check_distinct_poses, check_poses
    from ..data._measurements import Measurements
    from ..model._symbolic import Model
    from ..planning._observability import JIT_MIN_CANDIDATES, design_problem
    from ..planning._selectors import PlanSettings, select_poses

    check_outputs({"--out": args.out, "--json": args.json, **measurement_outputs(args)}, [args.robot, args.candidates],
                  args.force)
    robot = robot_from_args(args.robot, args)
    data = Measurements.read_csv(args.candidates, robot=robot)
    if fixtures(args):
        data = data.with_fixtures(fixtures(args))
    N = len(data)
    if args.m > N:
        raise InputError(f"-m {args.m} asks for more poses than the {N} candidate rows", file=args.candidates)
    check_poses(data, robot, **check_options(args))
    if data.touches:
        return _plan_touches(args, robot, data)
    check_distinct_poses(data, args.m)
    # compiling the model (~1.5 s) pays only for large pools; the model decides whether it can
    model = Model(robot, args.model, jit=None if N >= JIT_MIN_CANDIDATES else False, user_terms=user_terms(args))
    status = Status(args.quiet)      # a phase says what it does once it has taken a second
    t0 = time.perf_counter()
    try:
        with status.slow(f"plan-poses: the model's Jacobian at the {N} candidate poses (model {model.spec})"):
            problem = design_problem(model, data.q, model.covariates(data))
    except IdentifiabilityError as e:
        raise InputError(str(e), file=args.candidates) from e
    t_jac = time.perf_counter() - t0
    if args.m < problem.min_poses:
        raise InputError(f"-m {args.m} poses give {3 * args.m} equations, fewer than the "
                         f"{problem.n_parameters} parameters of model {model.spec} these candidates "
                         f"can identify; use -m {problem.min_poses} or more "
                         f"(2 x {problem.n_parameters} = {2 * problem.n_parameters} is a good start)",
                         file=args.candidates)
    settings = PlanSettings(relaxation=args.relaxation)
    try:
        with status.slow(f"plan-poses: selecting {args.m} of {N} poses ({args.method}, {problem.n_parameters} "
                         "parameters)"):
            res = select_poses(model, None, args.m, args.method, seed=args.seed, settings=settings,
                               problem=problem)
    except (IdentifiabilityError, InputError) as e:
        if getattr(e, "file", None):
            raise
        raise InputError(str(e), file=args.candidates) from e
    res.jacobian_time_s = t_jac
    return _selected(args, robot, data, model, res,
                     f"model {model.spec} on {robot.name}: {problem.n_parameters} identifiable parameters from {N} "
                     f"candidates in {args.candidates}")


def _selected(args, robot, data, model, res, headline: str, extra: dict | None = None) -> int:
    """The selection written and said: the rows (with ``--program``, in the order of the measurement run, the
    program written), the summary, the JSON."""
    indices = _in_run_order(args, robot, data, res.indices)
    lines = _write_rows(args.candidates, indices, args.out, args.force)
    out = human_stream(args.json)         # --json -: standard output holds the JSON alone
    print(headline, file=out)
    print(res.summary(), file=out)
    print(f"selected rows -> {args.out}" + (" (in the order of the measurement run)" if args.program else ""),
          file=out)
    if args.program:
        print(f"measurement run -> {args.program}", file=out)
    if args.json:
        doc = {"robot": robot.name, "model": model.spec, "candidates": args.candidates, **(extra or {}),
               "file_lines": lines, **res.to_dict()}
        if args.program:
            doc["program"] = {"file": args.program, "order": [int(i) for i in indices]}
        write_json(args.json, doc, args.force)
        print(f"summary -> {'standard output' if args.json == '-' else args.json}", file=out)
    return 0


def _in_run_order(args, robot, data, indices) -> np.ndarray:
    """The selected rows; with ``--program``, in the order of the measurement run (short joint moves), the program
    written."""
    indices = np.asarray(indices)
    if args.program:
        from ..planning._order import measurement_order

        values = np.column_stack([data.columns[c] for c in data.q_columns])[indices]
        order = measurement_order(values)
        indices = indices[order]
        write_measurement_program(args, values[order], robot.prismatic)
    return indices


def _plan_touches(args, robot, data) -> int:
    """``plan-poses ROBOT CANDIDATES.csv`` of candidates that touch (a ``point`` or ``plane`` column): the Ds
    criterion, what the rows cannot see held (:mod:`casadical.planning._touches`)."""
    from ..model._symbolic import Model
    from ..planning._selectors import PlanSettings
    from ..planning._touches import select_touches, touch_problem

    if args.method not in ("d-optimal", "random"):
        raise InputError(f"--method {args.method} judges rows measured by an instrument; candidates that touch (a "
                         "point or plane column) are selected by d-optimal (the Ds criterion) or random",
                         file=args.candidates)
    N = len(data)
    model = Model(robot, args.model, jit=False, user_terms=user_terms(args))
    status = Status(args.quiet)
    t0 = time.perf_counter()
    try:
        with status.slow(f"plan-poses: the model's Jacobian at the {N} candidate rows and what they touch "
                         f"(model {model.spec})"):
            problem = touch_problem(model, data)
    except IdentifiabilityError as e:
        raise InputError(str(e), file=args.candidates) from e
    t_jac = time.perf_counter() - t0
    p = problem.n_parameters
    with status.slow(f"plan-poses: selecting {args.m} of {N} rows ({args.method}, Ds criterion, {p} parameters)"):
        res = select_touches(problem, args.m, args.method, seed=args.seed,
                             settings=PlanSettings(relaxation=args.relaxation))
    if not math.isfinite(res.log_det):
        raise InputError(f"-m {args.m} rows cannot identify the {p} parameters of model {model.spec} these "
                         "candidates identify (each point touched takes 3 of a row's equations, and 4 rows of it at "
                         f"least): use a larger -m (3 x {p} = {3 * p} is a good start)", file=args.candidates)
    res.jacobian_time_s = t_jac
    n = len(problem.set_names)
    fixture = f" (fixture {', '.join(f.name for f in data.fixtures)})" if data.fixtures else ""
    return _selected(args, robot, data, model, res,
                     f"model {model.spec} on {robot.name}: {p} parameters identified by the {N} candidate rows of "
                     f"{args.candidates}, touching {n} point{'s' * (n != 1)} or plane{'s' * (n != 1)} of their "
                     f"sessions{fixture}", {"fixture": args.fixture} if args.fixture else {})


def cmd_plan_report(args) -> int:
    """``plan-poses REPORT.json CANDIDATES.csv``: the poses that answer the report's open questions."""
    import json
    import os

    from ..data._checks import check_poses
    from ..data._measurements import Measurements, session_name
    from ..data._sessions import combine
    from ..errors import RobotFileError
    from ..model._symbolic import Model
    from ..planning._next_poses import parametric_spec, plan_next
    from ..planning._questions import open_questions
    from ..robot import robot_from_dict

    report_path = args.robot
    if args.program:
        raise InputError("--program is for plan-poses ROBOT; with a report, write the run from SELECTED.csv with "
                         "plan-poses ROBOT SELECTED.csv -m M --program ...")
    check_outputs({"--out": args.out, "--json": args.json}, [report_path, args.candidates, *(args.measured or [])],
                  args.force)
    if args.method != "d-optimal" or args.model != "kinematic+compliance":
        raise InputError("--method and --model are for plan-poses ROBOT; with a report the model is the report's "
                         "and the criterion the information about its open questions (Ds-optimal)")
    given = [f"--urdf-{k}" for k in ("base", "tip", "tool") if getattr(args, f"urdf_{k}", None) is not None]
    if given:
        raise InputError(f"{report_path}: {', '.join(given)} chooses the chain of a URDF robot; the report holds "
                         "its robot (drop the option)")
    try:
        with open(report_path, encoding="utf-8-sig") as fh:
            doc = json.load(fh)
    except FileNotFoundError:
        raise InputError("no such file", file=report_path) from None
    except (OSError, ValueError) as e:
        raise InputError(f"not a JSON report: {e}", file=report_path) from e
    if not isinstance(doc, dict) or not {"steps", "findings", "final"} <= set(doc):
        raise InputError("not a report written by diagnose --json (it needs steps, findings and final; a "
                         "calibration JSON is not a report)", file=report_path)
    if "robot_description" not in doc or "sigma_mm" not in (doc.get("final") or {}):
        raise InputError("the report was written by an older casadical (no robot_description or final.sigma_mm): "
                         "run diagnose again", file=report_path)
    try:
        robot = robot_from_dict(doc["robot_description"], report_path)
    except RobotFileError as e:
        raise InputError(e.message, file=report_path, column="robot_description") from e
    paths = args.measured
    if not paths:
        named = (doc.get("inputs") or {}).get("data") or []
        if not named:
            raise InputError("the report does not name the poses it was made from: give them with --measured "
                             "DATA.csv ...", file=report_path)
        here = os.path.dirname(os.path.abspath(report_path))
        paths = [p if os.path.isabs(p) else os.path.join(here, p) for p in named]
        missing = [p for p in paths if not os.path.exists(p)]
        if missing:
            raise InputError(f"the poses the report was made from are not at {missing[0]} (paths are relative to "
                             "the report's folder): give them with --measured DATA.csv ...", file=report_path)
    parts = [Measurements.read_csv(p, robot=robot) for p in paths]
    measured = parts[0] if len(parts) == 1 else combine(parts)
    candidates = Measurements.read_csv(args.candidates, robot=robot)
    fixture = _report_fixture(args, doc, report_path)
    if fixture:
        from ..rows import read_fixture_file

        measured, candidates = (d.with_fixtures(read_fixture_file(fixture)) for d in (measured, candidates))
    check_poses(candidates, robot, **check_options(args))
    known = measured.session_names
    if candidates.sessions is not None:
        if args.session is not None:
            raise InputError(f"--session {args.session}: the candidates name their sessions (column session); "
                             "drop the option, or the column", file=args.candidates)
        unknown = sorted(set(candidates.sessions) - set(known or [None]))
        # a candidate that touches may stand in a session of its own: a new placement of what it touches
        unknown = [u for u in unknown if not candidates.touching[candidates.sessions == u].all()]
        if unknown:
            i = int(np.flatnonzero(candidates.sessions == unknown[0])[0])
            raise InputError(f"session {unknown[0]!r} is none of the measured sessions "
                             f"({', '.join(known) or 'one unnamed'})", file=args.candidates,
                             row=candidates.line(i), column="session")
    elif args.session is not None:
        name = session_name(args.session)
        if name not in known:
            raise InputError(f"--session {args.session}: " + (
                f"none of the measured sessions ({', '.join(known)})" if known else
                "the report's poses are of one session: the candidates are measured in it (drop the option)"),
                file=report_path)
        candidates.sessions = np.full(len(candidates), name, dtype=object)
    final = doc["final"]
    spec = parametric_spec(final["model"], user_terms(args))
    params = Model(robot, spec, jit=False, user_terms=user_terms(args)).parameters
    values = {p["name"]: params[p["name"]].from_display(float(p["value"])) for p in final.get("parameters", [])
              if p["name"] in params and p.get("value") is not None}
    questions = open_questions(doc, values, report_path, terms=user_terms(args))
    if not questions:
        raise InputError("the report has no open question (no ambiguous cause, no unexplained structure, every "
                         "named parameter significant): nothing to plan for; plan-poses ROBOT plans a "
                         "calibration from scratch", file=report_path)
    if args.question is not None:
        if args.question > len(questions):
            raise InputError(f"--question {args.question}: the report has {len(questions)} open question"
                             f"{'s' * (len(questions) != 1)}: " + "; ".join(f"{q.number}. {q.text}"
                                                                       for q in questions), file=report_path)
        questions = [questions[args.question - 1]]
    status = Status(args.quiet)
    with status.slow(f"plan-poses: {len(questions)} open question{'s' * (len(questions) != 1)} of {report_path}, "
                     f"{len(candidates)} candidates"):
        plan = plan_next(robot, doc, questions, values, measured, candidates, args.m, relaxation=args.relaxation,
                         random_sets=args.random_sets, seed=args.seed,
                         session_tools=(doc.get("settings") or {}).get("session_tools", False))
    lines = _write_rows(args.candidates, plan.indices, args.out, args.force,
                        session=candidates.sessions[0] if args.session is not None else None)
    out = human_stream(args.json)
    if len(known) > 1:
        where = (f"session {candidates.sessions[0]} (--session)" if args.session is not None else
                 "the sessions their column names" if candidates.sessions is not None else
                 f"session {known[0]}, the first (--session S, or a session column, for another)")
        print(f"the candidates are measured in {where}", file=out)
    print(f"{report_path}: {len(plan.questions)} open question{'s' * (len(plan.questions) != 1)} of the "
          f"diagnosis of {robot.name} (final model {spec}), {len(measured)} measured poses", file=out)
    print(plan.summary(), file=out)
    print(f"selected rows -> {args.out}", file=out)
    if args.json:
        write_json(args.json, {"report": report_path, "robot": robot.name, "model": spec,
                               "candidates": args.candidates, "file_lines": lines, **plan.to_dict()}, args.force)
        print(f"summary -> {'standard output' if args.json == '-' else args.json}", file=out)
    return 0


def _report_fixture(args, doc: dict, report_path: str) -> str | None:
    """The fixture file of ``plan-poses REPORT.json``: ``--fixture``, else the one the report names (its
    ``inputs.fixture``, relative to its folder), else none."""
    import os

    if args.fixture:
        return args.fixture
    named = (doc.get("inputs") or {}).get("fixture")
    if not named:
        return None
    path = named if os.path.isabs(named) else os.path.join(os.path.dirname(os.path.abspath(report_path)), named)
    if not os.path.exists(path):
        raise InputError(f"the fixture file the report was made with is not at {path} (paths are relative to the "
                         "report's folder): give it with --fixture FILE", file=report_path)
    return path


def _write_rows(source: str, indices: np.ndarray, out: str, force: bool, session: str | None = None) -> list[int]:
    """Copy the header and the selected data rows of ``source`` verbatim (field text unchanged), with a
    ``session`` column of ``session`` if given.

    Returns the file line numbers (header = 1) of the selected rows.
    """
    where = {int(i): k for k, i in enumerate(indices)}
    picked: list = [None] * len(where)
    with open(source, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        n = 0  # the same rows Measurements.read_csv counts: non-blank lines after the header
        for r in reader:
            if not "".join(r).strip():
                continue
            if n in where:
                picked[where[n]] = (reader.line_num, r)
            n += 1
    if session is not None:
        header = header + ["session"]
        picked = [(line, r + [session]) for line, r in picked]
    with atomic_open(out, "w", overwrite=force, newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(r for _, r in picked)
    return [line for line, _ in picked]


def _parse_box(text: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 6 or not all(math.isfinite(x) for x in v):
        raise InputError(f"--box needs six numbers xmin,ymin,zmin,xmax,ymax,zmax (m), got {text!r}")
    lo, hi = tuple(v[:3]), tuple(v[3:])
    if any(a >= b for a, b in zip(lo, hi)):
        raise InputError(f"--box: each minimum must be below its maximum, got {text!r}")
    return lo, hi


def cmd_candidates(args) -> int:
    from ..data._measurements import Measurements
    from ..data._simulate import sample_poses

    check_outputs({"--out": args.out}, [args.robot], args.force)
    floor = None if args.floor_z.strip().lower() == "none" else _float(args.floor_z, "--floor-z")
    box = _parse_box(args.box) if args.box else None
    robot = robot_from_args(args.robot, args)
    span = robot.file_limits[:, 1] - robot.file_limits[:, 0]     # deg, mm for a prismatic joint (its margin too)
    if 2 * args.margin_deg >= span.min():
        j = int(np.argmin(span)) + 1
        raise InputError(f"--margin-deg {args.margin_deg:g} leaves nothing of joint {j}'s range "
                         f"({span[j - 1]:g} {robot.joints[j - 1].unit}); use less than {span.min() / 2:g}",
                         file=args.robot)
    q = sample_poses(robot, args.n, np.random.default_rng(args.seed), floor_z=floor, box=box,
                     margin=math.radians(args.margin_deg))
    Measurements.from_arrays(q, prismatic=robot.prismatic).write_csv(args.out, overwrite=args.force)
    where = []
    if floor is not None:
        where.append(f"tool above z = {floor:g} m")
    if box is not None:
        where.append(f"inside box {box[0]}..{box[1]} m")
    print(f"{args.n} candidate poses of {robot.name} within the joint limits (margin "
          f"{args.margin_deg:g} deg{' or mm' if any(robot.prismatic) else ''})"
          f"{', ' + ', '.join(where) if where else ''} -> {args.out}")
    return 0


def _float(text: str, option: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"{option} must be a number or 'none', got {text!r}") from None
    if not math.isfinite(v):
        raise InputError(f"{option} must be finite, got {text!r}")
    return v
