"""``export``: take a calibration to the robot, as URDF and as a DH/MDH parameter table."""

from __future__ import annotations

import math
import warnings

from ..errors import DataWarning, InputError
from ._common import (
    Status,
    add_force,
    add_quiet,
    add_urdf_chain,
    check_outputs,
    float_in,
    robot_or_calibration,
    write_text,
)


def register(sub) -> None:
    p = sub.add_parser("export", help="write a calibration as URDF and as a DH/MDH parameter table",
                       description="Write the calibrated geometry of CAL.json (or a robot's nominal one) as "
                                   "URDF, and the parameter table (nominal, identified, difference, std in the "
                                   "robot's DH or MDH convention) as CSV and Markdown. At least one output. A "
                                   "calibration whose model has terms a URDF cannot carry (compliance, gear "
                                   "errors, ...) is exported as the geometry refitted to reproduce its full model "
                                   "over its calibration poses; how far that geometry departs from the full model is "
                                   "printed, and compensate (the full model) gives the rest. Terms of the "
                                   "measurement session (drift, the GP compensator) are never exported.")
    p.add_argument("source", metavar="CAL.json",
                   help="calibration JSON written by 'calibrate', or a robot (built-in, TOML or URDF: nominal values)")
    p.add_argument("--urdf", metavar="OUT.urdf", help="the geometric model as URDF")
    p.add_argument("--table", metavar="OUT.csv", help="the parameter table as CSV (full precision)")
    p.add_argument("--markdown", metavar="OUT.md", help="the parameter table as Markdown")
    p.add_argument("--payload-kg", type=float_in(0, math.inf, lo_open=False), metavar="KG",
                   help="for a calibration with terms a URDF cannot carry (compliance, gear errors, ...): the payload "
                        "its geometry is refitted at (default: the robot file's)")
    p.add_argument("--as-fitted", action="store_true",
                   help="export the calibration's geometry as it was fitted together with its other terms (and the "
                        "compliances in the table), for a controller that models those terms itself; without it, "
                        "the best geometry alone")
    add_urdf_chain(p)
    add_force(p)
    add_quiet(p)
    p.set_defaults(func=run, terms=None)   # the user terms a calibration JSON carries are known while it is read


def run(args) -> int:
    from ..apply._export_geometry import geometric_equivalent
    from ..apply._parameter_table import parameter_table
    from ..result import CalibrationResult
    from ..urdf import robot_to_urdf

    outputs = {"--urdf": args.urdf, "--table": args.table, "--markdown": args.markdown}
    if not any(outputs.values()):
        raise InputError("nothing to write: give --urdf OUT.urdf, --table OUT.csv and/or --markdown OUT.md")
    check_outputs(outputs, [args.source], args.force)
    source = robot_or_calibration(args.source, args)
    if args.payload_kg is not None and (args.as_fitted or not isinstance(source, CalibrationResult)):
        raise InputError("--payload-kg is the load the best geometry is refitted at: "
                         + ("--as-fitted exports the geometry as it was fitted; give one of the two" if args.as_fitted
                            else f"{args.source} is a robot, whose nominal geometry is exported as it is; "
                                 "leave it out"))
    status = Status(args.quiet)
    description = None
    if isinstance(source, CalibrationResult) and not args.as_fitted:
        # the best geometric model: a model with terms a URDF cannot carry is reproduced by its geometry alone
        with status.slow("export: fitting the geometry that reproduces the calibration's full model over its poses"):
            eq = geometric_equivalent(source, args.payload_kg)
        description = f"calibration {args.source}, model {source.model.spec}: {eq.text()}"
        if args.payload_kg is not None and not eq.payload_matters:
            warnings.warn(f"--payload-kg {args.payload_kg:g}: no effect, the model of {args.source} "
                          f"({source.model.spec}) "
                          "has no term that depends on the payload", DataWarning)
        status.line(f"exported: {eq.text()}")
        source = eq.result
    texts = {}   # everything is built before anything is written
    if args.urdf:
        texts[args.urdf] = robot_to_urdf(source, description)
    if args.table or args.markdown:
        table = parameter_table(source, description)
        if args.table:
            texts[args.table] = table.to_csv()
        if args.markdown:
            texts[args.markdown] = table.to_markdown()
    for path, text in texts.items():
        write_text(path, text, args.force)
        status.line(f"-> {path}")
    return 0
