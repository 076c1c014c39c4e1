"""The ``casadical`` command line (INTERFACE.md section 3).

Every command exits 0 on success and 2 with a one-line error naming the
file, row and column at fault on bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from . import __version__
from .errors import CasadicalError, CasadicalWarning, InputError


def _add_out(p: argparse.ArgumentParser, name: str = "--out", required: bool = True, help: str = "") -> None:
    p.add_argument(name, required=required, help=help)


def _check_out(path: str | None, force: bool, inputs: list[str]) -> None:
    """Refuse to overwrite a user's file (or an input) unless --force."""
    if path is None:
        return
    out = Path(path)
    for i in inputs:
        if i and Path(i).exists() and out.exists() and out.resolve() == Path(i).resolve():
            raise InputError("is also an input; choose another output name", file=path)
    if out.exists() and not force:
        raise InputError("exists already; choose another name or pass --force to replace it", file=path)
    if not out.parent.exists():
        raise InputError(f"folder {str(out.parent)!r} does not exist", file=path)


# --- commands ------------------------------------------------------------------------


def cmd_inspect(args) -> int:
    from .identifiability import analyse
    from .model import Model
    from .robot import load_robot
    from .simulate import sample_poses

    robot = load_robot(args.robot)
    model = Model(robot, args.model)
    rng = np.random.default_rng(args.seed)
    q = sample_poses(robot, args.poses, rng, floor_z=None)
    _, J = model.predict_jacobian(q)
    ident = analyse(J, model.parameters)
    ident.apply(model.parameters)
    size = model.expression_size()
    if args.json:
        doc = {
            "robot": robot.name, "model": model.spec, "convention": robot.convention,
            "n_joints": robot.n, "covariates": model.covariate_names,
            "expression": {"parameters": size.n_parameters, "fk_instructions": size.fk_instructions,
                           "jacobian_instructions": size.jacobian_instructions, "fk_nodes": size.fk_nodes},
            "identifiability": {"poses": args.poses, "condition_number": ident.condition_number,
                                "rank": len(ident.identifiable)},
            "parameters": [_param_json(p) for p in model.parameters],
        }
        print(json.dumps(doc, indent=2))
        return 0
    print(f"robot {robot.name} ({robot.n} joints, {robot.convention.upper()} convention"
          f"{', parallelogram loop on joint %d' % robot.loop.joint if robot.loop else ''})  source: {robot.source}")
    print(f"model {model.spec}: {size.n_parameters} parameters; per-pose covariates: "
          f"{', '.join(model.covariate_names)}")
    print(f"symbolic size: forward kinematics {size.fk_instructions} instructions "
          f"({size.fk_nodes} nodes), with Jacobian {size.jacobian_instructions} instructions")
    print(f"identifiability from {args.poses} random poses within the joint limits (seed {args.seed}): "
          f"{len(ident.identifiable)} of {len(ident.identifiable) + len(ident.unidentifiable)} "
          f"free parameters identifiable, condition number {ident.condition_number:.3g}")
    print()
    print(model.parameters.table())
    return 0


def _param_json(p) -> dict:
    import math
    return {"name": p.name, "value": p.to_display(p.value), "nominal": p.to_display(p.nominal),
            "std": p.to_display(p.std) if math.isfinite(p.std) else None,
            "identifiable": bool(p.identifiable) if p.identifiable is not None else not p.fixed,
            "fixed": p.fixed, "reason": p.reason, "unit": p.display_unit, "term": p.term,
            "joint": p.joint}


def cmd_predict(args) -> int:
    from .data import Measurements
    from .model import Model
    from .robot import load_robot

    _check_out(args.out, args.force, [args.poses])
    if args.model.lower().endswith(".json"):
        from .calibration import load_calibration
        cal = load_calibration(args.model)
        data = Measurements.read_csv(args.poses, n_joints=cal.model.robot.n)
        xyz = cal.predict(data)
    else:
        robot = load_robot(args.model)
        model = Model(robot, "nominal")
        data = Measurements.read_csv(args.poses, n_joints=robot.n)
        xyz = model.predict(data.q, cov=model.covariates(data))
    data.with_positions(xyz).write_csv(args.out, overwrite=args.force)
    print(f"predicted {len(data)} poses -> {args.out}")
    return 0


def cmd_calibrate(args) -> int:
    from .calibration import calibrate
    from .data import Measurements
    from .robot import load_robot

    _check_out(args.out, args.force, [args.data])
    robot = load_robot(args.robot)
    data = Measurements.read_csv(args.data, n_joints=robot.n, require_positions=True)
    opts = {"max_iter": args.max_iter} if args.max_iter else {}
    result = calibrate(robot, data, args.model, args.solver, solver_options=opts,
                       fix=tuple(args.fix.split(",")) if args.fix else ())
    result.save(args.out, overwrite=args.force)
    print(result.summary())
    print(f"\ncalibration -> {args.out}")
    return 0


def cmd_diagnose(args) -> int:
    from .data import Measurements
    from .diagnosis import DiagnosisSettings, diagnose
    from .diagnosis.html import render
    from .robot import load_robot

    for out in (args.json, args.html):
        _check_out(out, args.force, [args.data, args.validate])
    robot = load_robot(args.robot)
    cal = Measurements.read_csv(args.data, n_joints=robot.n, require_positions=True)
    val = Measurements.read_csv(args.validate, n_joints=robot.n, require_positions=True)
    settings = DiagnosisSettings(alpha=args.alpha, max_harmonic=args.max_harmonic,
                                 max_rounds=args.max_rounds, blackbox=not args.no_blackbox, seed=args.seed)
    report = diagnose(robot, cal, val, settings,
                      progress=None if args.quiet else (lambda line: print(line, file=sys.stderr)))
    print(report.text())
    Path(args.json).write_text(json.dumps(report.to_dict(), indent=1, allow_nan=False))
    print(f"\nreport -> {args.json}")
    if args.html:
        Path(args.html).write_text(render(report))
        print(f"html report -> {args.html}")
    return 0


def cmd_split(args) -> int:
    from .data import Measurements

    for out in (args.out_cal, args.out_val):
        _check_out(out, args.force, [args.data])
    data = Measurements.read_csv(args.data)
    n = len(data)
    if not 1 <= args.n < n:
        raise InputError(f"cannot take {args.n} calibration poses out of {n}: choose 1 to {n - 1}",
                         file=args.data)
    idx = np.sort(np.random.default_rng(args.seed).permutation(n)[: args.n])
    rest = np.setdiff1d(np.arange(n), idx)
    data.subset(idx).write_csv(args.out_cal, overwrite=args.force)
    data.subset(rest).write_csv(args.out_val, overwrite=args.force)
    print(f"{len(idx)} poses -> {args.out_cal}, {len(rest)} poses -> {args.out_val} (row order kept)")
    return 0


def cmd_simulate(args) -> int:
    from .simulate import load_protocol

    proto = load_protocol(args.protocol)
    sets, truth = proto.generate(args.seed)
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name in sets:
        _check_out(str(out / f"{name}.csv"), args.force, [])
    for name, data in sets.items():
        data.write_csv(out / f"{name}.csv", overwrite=args.force)
        print(f"{name}: {len(data)} poses -> {out / (name + '.csv')}")
    truth_doc = {"protocol": proto.name, "robot": proto.robot.name,
                 "parameters": {n: v for n, v in zip(truth.model.parameters.names, truth.values.tolist())},
                 "base0": truth.base0.tolist(), "model": truth.model.spec}
    tpath = out / "truth.json"
    _check_out(str(tpath), args.force, [])
    tpath.write_text(json.dumps(truth_doc, indent=1))
    print(f"true parameters (SI units) -> {tpath}")
    return 0


def cmd_import_ur10(args) -> int:
    from .importers.ur10 import convert_ur10

    _check_out(args.out, args.force, [args.source])
    n = convert_ur10(args.source, args.out, overwrite=args.force, sort_by_time=not args.keep_order)
    print(f"converted {n} poses -> {args.out}")
    return 0


# --- entry point ---------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="casadical",
        description="Calibration of industrial robot arms: symbolic kinematic + compliance "
                    "models in CasADi, identification with IPOPT and Gauss-Newton, diagnosis and "
                    "pose planning.")
    ap.add_argument("--version", action="version", version=f"casadical {__version__}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("inspect", help="show the symbolic model, its parameters and their identifiability",
                       description="Show the symbolic model of ROBOT: parameters with units and nominal "
                                   "values, which are identifiable (and why not), expression sizes.")
    p.add_argument("robot", help="built-in robot (ys100, hh800, ur10) or robot TOML file")
    p.add_argument("--model", default="kinematic+compliance",
                   help="error model, terms joined by '+' (default: %(default)s)")
    p.add_argument("--poses", type=int, default=200, help="random poses for the identifiability analysis")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=cmd_inspect)

    p = sub.add_parser("predict", help="predict tool positions for joint readings",
                       description="Predict tool positions. MODEL is a robot (nominal model) or a "
                                   "calibration JSON written by 'calibrate'. OUT.csv holds the input "
                                   "columns plus x_mm, y_mm, z_mm (measured ones are renamed measured_*).")
    p.add_argument("model", metavar="MODEL")
    p.add_argument("poses", metavar="POSES.csv")
    _add_out(p, help="output CSV")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser("calibrate", help="identify a calibrated model from measured poses",
                       description="Identify the parameters of MODEL (kinematic, kinematic+compliance, or more "
                                   "terms joined by '+') from DATA.csv; the base pose is always estimated. "
                                   "Writes CAL.json (INTERFACE.md section 4) and prints a summary.")
    p.add_argument("robot", metavar="ROBOT")
    p.add_argument("data", metavar="DATA.csv")
    p.add_argument("--model", default="kinematic+compliance",
                   help="error model, e.g. kinematic, kinematic+compliance, "
                        "kinematic+compliance[2,3]+periodic[2:1] (default: %(default)s)")
    _add_out(p, help="calibration JSON to write")
    p.add_argument("--solver", default="ipopt", choices=["ipopt", "lm", "gn", "auto"],
                   help="ipopt (bounded), lm (Levenberg-Marquardt), gn (Gauss-Newton), auto (lm, then "
                        "ipopt if a bound is crossed); default %(default)s")
    p.add_argument("--max-iter", type=int, default=None, help="solver iteration limit")
    p.add_argument("--fix", default="", help="comma-separated parameters to hold at nominal")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("diagnose", help="find what the model gets wrong, name the cause, measure the gain",
                       description="Calibrate on DATA step by step (nominal, geometric, then candidate "
                                   "causes: joint compliance, periodic gear error, encoder scale, backlash, "
                                   "thermal expansion, then a black-box compensator), judge every step on "
                                   "VAL (never fitted), and report the accepted causes with their evidence "
                                   "and validation gain.")
    p.add_argument("robot", metavar="ROBOT")
    p.add_argument("data", metavar="DATA.csv")
    p.add_argument("--validate", required=True, metavar="VAL.csv", help="validation poses (never fitted)")
    p.add_argument("--json", required=True, metavar="REPORT.json")
    p.add_argument("--html", metavar="REPORT.html", help="also write a self-contained HTML report")
    p.add_argument("--alpha", type=float, default=0.01, help="family-wise significance level (default 0.01)")
    p.add_argument("--max-harmonic", type=int, default=60, help="highest harmonic scanned (default 60)")
    p.add_argument("--max-rounds", type=int, default=8, help="most extensions accepted (default 8)")
    p.add_argument("--no-blackbox", action="store_true", help="skip the black-box compensator step")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--force", action="store_true", help="replace existing report files")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("split", help="split a measurement file into calibration and validation poses",
                       description="Random split of DATA.csv: N rows for calibration, the rest for "
                                   "validation; both keep the original row order.")
    p.add_argument("data", metavar="DATA.csv")
    p.add_argument("-n", type=int, required=True, help="number of calibration poses")
    p.add_argument("--out-cal", required=True)
    p.add_argument("--out-val", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--force", action="store_true")
    p.set_defaults(func=cmd_split)

    p = sub.add_parser("simulate", help="simulate the pose sets of an experiment protocol",
                       description="Simulate measurements from a protocol of problems/protocols "
                                   "(name or TOML path); writes one CSV per pose set and truth.json.")
    p.add_argument("protocol")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--seed", type=int, default=None, help="override the protocol's seed")
    p.add_argument("--force", action="store_true", help="replace existing files")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("import-ur10", help="convert the UR10 (ipa) raw format to the measurement CSV",
                       description="Convert a raw UR10 file (';' separated, decimal comma, radians) "
                                   "to the measurement CSV contract.")
    p.add_argument("source")
    _add_out(p, help="output CSV")
    p.add_argument("--keep-order", action="store_true",
                   help="keep the file's row order where the timestamps say otherwise (default: sort by time)")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.set_defaults(func=cmd_import_ur10)

    from .methods.compare import add_commands as compare_commands
    from .planning.cli import add_commands as planning_commands
    planning_commands(sub)
    compare_commands(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    if not getattr(args, "func", None):
        ap.print_help()
        return 2

    def _warn(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, CasadicalWarning):
            print(f"casadical: warning: {message}", file=sys.stderr)
        else:
            print(f"casadical: warning: {category.__name__}: {message}", file=sys.stderr)

    warnings.showwarning = _warn
    try:
        return int(args.func(args) or 0)
    except CasadicalError as e:
        print(f"casadical: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"casadical: error: {e.filename or ''}: {e.strerror}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("casadical: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
