"""``compare``: the seed papers' calibration methods side by side."""

from __future__ import annotations

import sys

from ._common import (
    Status,
    add_checks,
    add_force,
    add_json,
    add_quiet,
    add_urdf_chain,
    check_options,
    check_outputs,
    human_stream,
    robot_from_args,
    write_json,
)


def register(sub) -> None:
    p = sub.add_parser(
        "compare", help="run the seed papers' calibration methods side by side",
        description="Run calibration methods on the same data and print the seeds' accuracy table "
                    "(mean / max / std of the position error in mm, calibration and validation poses) "
                    "with the time per method. Methods: {names}.")
    p.add_argument("robot", metavar="ROBOT", help="built-in robot (ys100, hh800, ur10), robot TOML or URDF file")
    p.add_argument("cal", metavar="CAL.csv", help="calibration poses (with x_mm, y_mm, z_mm)")
    p.add_argument("--validate", metavar="VAL.csv", help="validation poses, never used for fitting")
    add_json(p, "the results")
    methods = p.add_argument("--methods", default="", help="comma-separated methods (default all: {names})")
    p.add_argument("--extra", metavar="EXTRA.csv",
                   help="further measured poses the network methods train on (the TLBO paper's Q2)")
    p.add_argument("--plot", metavar="OUT.png", help="per-pose error bars per method (PNG, needs matplotlib)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice (default: %(default)s)")
    add_checks(p)
    add_quiet(p)
    add_urdf_chain(p)
    add_force(p)
    p.set_defaults(func=cmd_compare)

    def complete_help(parser) -> None:   # the names need every method imported: only for --help
        from ..methods import method_names

        names = ", ".join(method_names())
        parser.description = parser.description.format(names=names)
        methods.help = methods.help.format(names=names)

    p.complete_help = complete_help


def cmd_compare(args) -> int:
    from ..data._checks import check_held_out, check_poses, check_validation_frames
    from ..data._measurements import Measurements
    from ..methods._base import MethodResult
    from ..methods._compare import compare, format_table, parse_methods, plot, pyplot, to_json

    methods = parse_methods(args.methods)        # bad names fail before any work
    inputs = [args.cal, args.validate, args.extra]
    check_outputs({"--json": args.json, "--plot": args.plot}, [args.robot, *inputs], args.force)
    if args.plot:
        pyplot()                               # a missing matplotlib fails before the work, too
    robot = robot_from_args(args.robot, args)

    def read(path):
        if path is None:
            return None
        data = Measurements.read_csv(path, robot=robot, require_positions=True)
        check_poses(data, robot, **check_options(args))
        return data

    cal, val, extra = read(args.cal), read(args.validate), read(args.extra)
    for seen in (cal, extra):            # before the work: validation poses a method has fitted judge nothing
        if val is not None and seen is not None:
            check_held_out(seen, val)
    if val is not None or extra is not None:
        # in the calibration poses' measurement frame: the nominal model, its base pose fitted to them, misses the
        # others by about what it misses its own by (another tracker set-up: by metres)
        from ..calibration import calibrate
        nominal = calibrate(robot, cal, "nominal", "lm", warn=False)
        for d, what in ((val, "validation poses"), (extra, "extra poses")):
            if d is not None:
                check_validation_frames(d, nominal.errors(d), nominal.calibration.mean_mm, args.allow_mismatch, what)
    out = human_stream(args.json)       # --json -: standard output holds the JSON alone
    print(f"compare on {robot.name}: {len(cal)} calibration poses ({args.cal})"
          + (f", {len(val)} validation poses ({args.validate})" if val is not None else "")
          + (f", {len(extra)} extra poses ({args.extra})" if extra is not None else "")
          + f", seed {args.seed}", flush=True, file=out)

    status = Status(args.quiet)
    with status.bar(len(methods), "methods", unit="method") as bar:
        def progress(r: MethodResult) -> None:
            v = f", validation mean {r.validation.mean_mm:.4f} mm" if r.validation else ""
            if not args.quiet:
                bar.write(f"  {r.name}: calibration mean {r.calibration.mean_mm:.4f} mm{v} ({r.time_s:.2f} s)",
                          file=sys.stderr)
            bar.update(1)

        def starting(name: str) -> None:     # the bar says which method runs (some take seconds)
            bar.set_postfix_str(f"running {name}")

        results = compare(robot, cal, val, extra, methods, args.seed, progress=progress, starting=starting)
    print(file=out)
    print(format_table(results), file=out)
    for r in results:
        comp = r.info.get("compensator")
        if isinstance(comp, dict) and not comp.get("kept", True):
            print(f"note: {r.name}: compensator {comp.get('reason', 'dropped')}", file=out)
    if args.json:
        doc = to_json(results, robot=robot.name, calibration_file=args.cal, validation_file=args.validate,
                      extra_file=args.extra, seed=args.seed)
        write_json(args.json, doc, args.force)
        print(f"\nresults -> {'standard output' if args.json == '-' else args.json}", file=out)
    if args.plot:
        plot(results, {"calibration": cal, "validation": val}, args.plot, robot.name, overwrite=args.force)
        print(f"per-pose errors -> {args.plot}", file=out)
    return 0
