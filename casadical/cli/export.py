"""``export``: take a calibration to the robot, as URDF and as a DH/MDH parameter table."""

from __future__ import annotations

from ..errors import InputError
from .common import Status, add_force, add_quiet, add_urdf_chain, check_outputs, robot_or_calibration, write_text


def register(sub) -> None:
    p = sub.add_parser("export", help="write a calibration as URDF and as a DH/MDH parameter table",
                       description="Write the calibrated geometry of CAL.json (or a robot's nominal one) as "
                                   "URDF, and the parameter table (nominal, identified, difference, std in the "
                                   "robot's DH or MDH convention) as CSV and Markdown. At least one output.")
    p.add_argument("source", metavar="CAL.json",
                   help="calibration JSON written by 'calibrate', or a robot (built-in, TOML or URDF: nominal values)")
    p.add_argument("--urdf", metavar="OUT.urdf", help="the geometric model as URDF")
    p.add_argument("--table", metavar="OUT.csv", help="the parameter table as CSV (full precision)")
    p.add_argument("--markdown", metavar="OUT.md", help="the parameter table as Markdown")
    add_urdf_chain(p)
    add_force(p)
    add_quiet(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..parameter_table import parameter_table
    from ..urdf import robot_to_urdf

    outputs = {"--urdf": args.urdf, "--table": args.table, "--markdown": args.markdown}
    if not any(outputs.values()):
        raise InputError("nothing to write: give --urdf OUT.urdf, --table OUT.csv and/or --markdown OUT.md")
    check_outputs(outputs, [args.source], args.force)
    source = robot_or_calibration(args.source, args)
    texts = {}   # everything is built before anything is written
    if args.urdf:
        texts[args.urdf] = robot_to_urdf(source)
    if args.table or args.markdown:
        table = parameter_table(source)
        if args.table:
            texts[args.table] = table.to_csv()
        if args.markdown:
            texts[args.markdown] = table.to_markdown()
    status = Status(args.quiet)
    for path, text in texts.items():
        write_text(path, text, args.force)
        status.line(f"-> {path}")
    return 0
