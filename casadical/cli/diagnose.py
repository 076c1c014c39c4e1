"""``diagnose``: what the model gets wrong, why, and what each extension gains."""

from __future__ import annotations

from .common import (Status, add_checks, add_force, add_quiet, check_options, check_outputs, float_in, int_at_least,
                     write_json, write_text)


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="find what the model gets wrong, name the cause, measure the gain",
                       description="Calibrate on DATA step by step (nominal, geometric, then candidate "
                                   "causes: joint compliance, periodic gear error, encoder scale, backlash, "
                                   "thermal expansion, then a black-box compensator), judge every step on "
                                   "VAL (never fitted), and report the accepted causes with their evidence "
                                   "and validation gain.")
    p.add_argument("robot", metavar="ROBOT", help="built-in robot, robot TOML or URDF file")
    p.add_argument("data", metavar="DATA.csv", help="calibration poses")
    p.add_argument("--validate", required=True, metavar="VAL.csv", help="validation poses (never fitted)")
    p.add_argument("--json", required=True, metavar="REPORT.json", help="write the report as JSON")
    p.add_argument("--html", metavar="REPORT.html", help="also write a self-contained HTML report")
    p.add_argument("--alpha", type=float_in(0, 1), default=0.01,
                   help="family-wise significance level, in (0, 1) (default: %(default)s)")
    p.add_argument("--max-harmonic", type=int_at_least(1), default=60,
                   help="highest harmonic scanned, cycles per turn (default: %(default)s)")
    p.add_argument("--max-rounds", type=int_at_least(0), default=8,
                   help="most extensions accepted (default: %(default)s)")
    p.add_argument("--no-blackbox", action="store_true", help="skip the black-box compensator step")
    p.add_argument("--seed", type=int, default=0, help="seed of the cross-validation folds (default: %(default)s)")
    add_checks(p)
    add_quiet(p)
    add_force(p)
    p.set_defaults(func=run, inputs=("robot", "data", "validate"))


def run(args) -> int:
    from ..data import Measurements
    from ..diagnosis import DiagnosisSettings, diagnose
    from ..diagnosis.html import render
    from ..robot import load_robot

    check_outputs({"--json": args.json, "--html": args.html}, [args.robot, args.data, args.validate], args.force)
    robot = load_robot(args.robot)
    cal = Measurements.read_csv(args.data, n_joints=robot.n, require_positions=True)
    val = Measurements.read_csv(args.validate, n_joints=robot.n, require_positions=True)
    settings = DiagnosisSettings(alpha=args.alpha, max_harmonic=args.max_harmonic,
                                 max_rounds=args.max_rounds, blackbox=not args.no_blackbox, seed=args.seed)
    report = diagnose(robot, cal, val, settings, progress=Status(args.quiet).line, **check_options(args))
    print(report.text())
    write_json(args.json, report.to_dict(), args.force)
    print(f"\nreport -> {args.json}")
    if args.html:
        write_text(args.html, render(report), args.force)
        print(f"html report -> {args.html}")
    return 0
