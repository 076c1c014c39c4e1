"""``diagnose``: what the model gets wrong, why, and what each extension gains."""

from __future__ import annotations

import math

from ..errors import InputError
from ._common import (
    STDOUT,
    Status,
    add_checks,
    add_fixture,
    add_force,
    add_levelled,
    add_quiet,
    add_row_spacing,
    add_session_tool,
    add_terms,
    add_urdf_chain,
    check_options,
    check_outputs,
    float_in,
    human_stream,
    int_at_least,
    robot_from_args,
    timed,
    user_terms,
    write_json,
    write_text,
)


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="find what the model gets wrong, name the cause, measure the gain",
                       description="Calibrate on DATA step by step (nominal, geometric, then candidate causes: "
                                   "joint compliance and progressive stiffness, encoder scale, backlash, thermal "
                                   "expansion, drift, periodic gear errors, then the GP compensator). A "
                                   "cause is accepted only when the calibration data support it: significance "
                                   "(F-test, BIC) and held-out errors on folds that must extrapolate (time "
                                   "blocks, joint-range blocks) as well as interpolate; a periodic error must "
                                   "also be resolved and agree over the halves of its joint's range, or it is "
                                   "reported as unexplained structure. VAL judges every step and never decides; "
                                   "--transfer takes every finding to another measurement series. Several DATA "
                                   "files are several measurement sessions of one robot: each has its own base "
                                   "pose, and every cause is asked whether one value serves all sessions (a "
                                   "cause of the robot) or not (a property of a session).")
    p.add_argument("robot", metavar="ROBOT", help="built-in robot, robot TOML or URDF file")
    p.add_argument("data", metavar="DATA.csv", nargs="+", help="calibration poses; several files: one session each")
    p.add_argument("--validate", required=True, metavar="VAL.csv", nargs="+",
                   help="validation poses (never fitted, never decide); with several DATA files one per DATA file "
                        "in the same order (each of that file's session), or one with a session column")
    p.add_argument("--json", metavar="REPORT.json",
                   help="write the report as JSON ('-': standard output, which then holds the JSON alone)")
    p.add_argument("--html", metavar="REPORT.html",
                   help="write a self-contained HTML report, findings first ('-': standard output)")
    p.add_argument("--map-joints", metavar="J,K", default=None,
                   help="the two joints of the HTML report's map of where the model is accurate (default: the two "
                        "along which its predicted uncertainty varies most)")
    p.add_argument("--out", metavar="FINAL.json",
                   help="write the final model as a calibration JSON (compensator included), for predict, "
                        "compensate, export and calibrate FINAL.json (at least one of --json, --html, --out)")
    p.add_argument("--verbose", "-v", action="store_true",
                   help="print the evidence too: every step with its gain against the model it extends, each "
                        "model's full specification, why a step was not accepted, each finding's checks; and "
                        "every candidate's progress line")
    p.add_argument("--transfer", metavar="OTHER.csv",
                   help="another measurement series of the same robot: report each finding's gain there, with "
                        "the base pose re-estimated on a few of its poses and with the geometry refitted")
    p.add_argument("--transfer-base-poses", type=int_at_least(6), default=None,
                   help="poses of OTHER.csv the base pose is re-estimated on (default: 30)")
    p.add_argument("--transfer-refit-poses", type=int_at_least(10), default=None,
                   help="poses of OTHER.csv the geometry is refitted on (default: as many as DATA.csv has, at most "
                        "half of OTHER.csv)")
    p.add_argument("--alpha", type=float_in(0, 1), default=0.001,
                   help="family-wise significance level of each round, in (0, 1) (default: %(default)s)")
    p.add_argument("--max-harmonic", type=int_at_least(1), default=60,
                   help="highest harmonic scanned, cycles per turn (default: %(default)s)")
    p.add_argument("--max-rounds", type=int_at_least(0), default=40,
                   help="safety cap on the rounds; the search stops by itself when nothing more is supported "
                        "(default: %(default)s)")
    p.add_argument("--robust", default="huber", choices=["huber", "none"],
                   help="loss of every fit, as for calibrate (default: %(default)s)")
    p.add_argument("--solver", default="lm", choices=["lm", "ipopt", "gn", "auto"],
                   help="solver of every fit, as for calibrate: lm (Levenberg-Marquardt), ipopt (bounded), gn "
                        "(Gauss-Newton), auto (lm, then ipopt if a bound is crossed) (default: %(default)s)")
    p.add_argument("--no-blackbox", "--no-layer", action="store_true",
                   help="skip the GP compensator (a Gaussian process, one per session, of what the named causes leave)")
    p.add_argument("--worst-case", action="store_true",
                   help="where the final model's worst validation error is more than 5 %% above a kinematic "
                        "calibration's, end with the model the report names to restore it (without the GP "
                        "compensator, or fewer causes): a safe worst case over a lower mean")
    p.add_argument("--no-structure", action="store_true",
                   help="skip the structure screen (what the named causes leave, against every joint's reading and "
                        "torque, time and the instrument's view: docs/diagnosis.md)")
    p.add_argument("--noise-mm", type=float_in(0, math.inf), metavar="SIGMA", default=None,
                   help="the instrument's noise per axis (mm, 1 sigma): the report gives what the final model leaves "
                        "in units of it (without it: from repeated poses, where the data hold some)")
    p.add_argument("--position-only", action="store_true",
                   help="fit on the positions alone; without it, data with a measured orientation (rx_deg, ry_deg, "
                        "rz_deg) are fitted on the full pose, as by calibrate (the screening of candidates works on "
                        "the positions either way)")
    p.add_argument("--seed", type=int, default=0, help="seed of the cross-validation folds (default: %(default)s)")
    add_session_tool(p)
    add_levelled(p)
    add_row_spacing(p)
    add_checks(p)
    add_quiet(p)
    add_urdf_chain(p)
    add_terms(p)
    add_fixture(p)
    add_force(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..data._measurements import Measurements
    from ..data._sessions import combine, file_session_names
    from ..diagnosis import DiagnosisSettings, diagnose

    if not (args.json or args.html or args.out):
        raise InputError("nothing to write: give --json REPORT.json, --html REPORT.html and/or --out FINAL.json")
    check_outputs({"--json": args.json, "--html": args.html, "--out": args.out},
                  [args.robot, *args.data, *args.validate, args.transfer], args.force)
    if not args.transfer and (args.transfer_base_poses is not None or args.transfer_refit_poses is not None):
        raise InputError("--transfer-base-poses and --transfer-refit-poses are for the transfer study: give "
                         "--transfer OTHER.csv, or leave them out")
    robot = robot_from_args(args.robot, args)
    map_joints = _joint_pair(args.map_joints, robot.n) if args.map_joints else None

    def read(path):
        return timed(Measurements.read_csv(path, robot=robot, require_positions=True), args)

    cals, vals = [read(p) for p in args.data], [read(p) for p in args.validate]
    cal = cals[0] if len(cals) == 1 else combine(cals)
    if len(vals) == len(cals):     # each validation file is of the session of its DATA file
        val = vals[0] if len(vals) == 1 else combine(vals, names=file_session_names(args.data))
    elif len(vals) == 1 and vals[0].sessions is not None:
        val = vals[0]
    else:
        raise InputError(f"{len(cals)} DATA files and {len(vals)} --validate files: give one validation file per "
                         "DATA file, in the same order, or one with a session column", file=args.validate[0])
    other = read(args.transfer) if args.transfer else None
    settings = DiagnosisSettings(alpha=args.alpha, max_harmonic=args.max_harmonic, max_rounds=args.max_rounds,
                                 blackbox=not args.no_blackbox, seed=args.seed, robust=args.robust,
                                 position_only=args.position_only,
                                 transfer_base_poses=args.transfer_base_poses or DiagnosisSettings.transfer_base_poses,
                                 transfer_refit_poses=args.transfer_refit_poses, session_tools=args.session_tool,
                                 structure=not args.no_structure, noise_mm=args.noise_mm,
                                 worst_case=args.worst_case, solver=args.solver, terms=user_terms(args),
                                 levelled=args.levelled)
    status = Status(args.quiet)
    say = status.timed_line()
    report = diagnose(robot, cal, val, settings, progress=say if args.verbose else _brief(say), other=other,
                      **check_options(args))
    report.inputs = _inputs(args)
    out = human_stream(args.json, args.html)      # '-': stdout holds that output alone, the words go to stderr
    print(report.text(verbose=args.verbose), file=out)
    print(file=out)
    if args.json:
        doc = report.to_dict()
        # the poses the report was made from, for plan-poses REPORT.json (relative to the report's folder)
        doc["inputs"].update(data=[_beside(p, args.json) for p in args.data],
                             validate=[_beside(p, args.json) for p in args.validate],
                             **({"fixture": _beside(args.fixture, args.json)} if args.fixture else {}))
        write_json(args.json, doc, args.force)
        print(f"report -> {'standard output' if args.json == STDOUT else args.json}", file=out)
    if args.html:
        from ..html import diagnosis_html

        write_text(args.html, diagnosis_html(report, progress=say, poses=cal, map_joints=map_joints), args.force)
        print(f"html report -> {'standard output' if args.html == STDOUT else args.html}", file=out)
    if args.out:
        report.final.save(args.out, overwrite=args.force)
        print(f"final model -> {args.out}", file=out)
    return 0


#: what the command line gave that the report's inputs name on their own (the rest are its options)
_GIVEN = ("robot", "data", "validate", "transfer", "terms")


def _inputs(args) -> dict:
    """What the user gave, for the record: the robot, the files, and every option of the command line (as given
    or by default; outputs and the words' options too)."""
    options = {k: v for k, v in sorted(vars(args).items())
               if k not in (*_GIVEN, "func", "command", "debug") and not k.startswith("_")}  # not what was read
    return {**{k: getattr(args, k) for k in _GIVEN}, "options": options}


def _joint_pair(text: str, n: int) -> tuple[int, int]:
    try:
        a, b = (int(x) for x in text.split(","))
    except ValueError:
        raise InputError(f"--map-joints needs two joint numbers J,K, got {text!r}") from None
    if not (1 <= a <= n and 1 <= b <= n and a != b):
        raise InputError(f"--map-joints: two different joints of 1..{n}, got {text!r}")
    return a, b


def _beside(path: str, report: str) -> str:
    """``path`` relative to the folder of ``report`` (absolute when the report goes to standard output or
    to another drive)."""
    import os

    if report == STDOUT:
        return os.path.abspath(path)
    try:
        return os.path.relpath(os.path.abspath(path), os.path.dirname(os.path.abspath(report)))
    except ValueError:
        return os.path.abspath(path)


def _brief(say):
    """Progress without the line of every candidate tried (``--verbose`` shows them): the steps, the rounds,
    what was accepted or dropped, and every phase of a second or more."""
    def brief(text: str) -> None:
        t = text.lstrip()
        detail = text.startswith("    ") and not t.startswith(("accepted", "dropped"))
        if detail or t.startswith(("fitting ", "no cause is supported")):
            return
        say(text)
    return brief
