"""``iso9283``: ISO 9283 pose accuracy and repeatability, distance accuracy and repeatability, before and after
compensation (docs/formats.md, iso9283)."""

from __future__ import annotations

import csv

import numpy as np

from ..errors import DataFileError, InputError
from ._common import (
    add_force,
    add_json,
    add_urdf_chain,
    check_outputs,
    human_stream,
    robot_from_args,
    write_json,
    write_text,
)

XYZ = ("x_mm", "y_mm", "z_mm")
RXYZ = ("rx_deg", "ry_deg", "rz_deg")
CMD_XYZ = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")
CMD_RXYZ = ("cmd_rx_deg", "cmd_ry_deg", "cmd_rz_deg")


def register(sub) -> None:
    p = sub.add_parser("iso9283", help="ISO 9283 pose and distance accuracy and repeatability, before and after "
                                       "compensation",
                       description="From MEASURED.csv (columns cycle, pose, optional cube and compensated; the "
                                   "commanded pose as cmd_x_mm, cmd_y_mm, cmd_z_mm (and cmd_rx_deg, cmd_ry_deg, "
                                   "cmd_rz_deg) in the robot base frame, or as commanded joints q1_deg.. whose "
                                   "nominal tool point it is; the attained x_mm, y_mm, z_mm (and rx_deg, ry_deg, "
                                   "rz_deg)) the pose accuracy AP and repeatability RP of each pose, the distance "
                                   "accuracy AD and repeatability RD of pairs of poses, and each cube's largest. "
                                   "With CAL.json (and joints) the same after compensation as the calibration "
                                   "predicts it, beside the figures before; rows with compensated = 1 are measured "
                                   "after compensation and reported as such.")
    p.add_argument("robot", metavar="ROBOT|CAL.json",
                   help="the robot (built-in, TOML, URDF): its nominal model gives commanded poses from joints; or a "
                        "calibration JSON: the figures after compensation too")
    p.add_argument("measured", metavar="MEASURED.csv", help="the commanded and attained poses, cycle by cycle")
    add_json(p, "the report")
    p.add_argument("--html", metavar="OUT.html", default=None, help="write the report as an HTML page")
    p.add_argument("--frame", choices=("fit", "base"), default="fit",
                   help="fit: the attained poses are in the instrument's frame, placed in the robot base frame by "
                        "the rigid transform that best fits them to the commanded ones (said in the report); "
                        "base: they are in the robot base frame already (default: %(default)s)")
    p.add_argument("--pairs", metavar="A-B,...", default=None,
                   help="the pairs of poses of the distance characteristics AD, RD (default: P2-P4, ISO 9283's, "
                        "where the file has those poses)")
    add_urdf_chain(p)
    add_force(p)
    p.set_defaults(func=run)


def _read(path: str, robot) -> dict:
    """The file's columns: ``cycle``, ``pose``, ``cube`` (text), numbers; one-line errors naming row and column."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh)]
    except FileNotFoundError:
        raise InputError("no such file", file=path) from None
    if not rows:
        raise DataFileError("is empty", file=path, row=1)
    header = [h.strip() for h in rows[0]]
    body = [(k, r) for k, r in enumerate(rows[1:], start=2) if "".join(r).strip()]
    for col in ("cycle", "pose") + XYZ:
        if col not in header:
            raise DataFileError("is a column ISO 9283 needs (docs/formats.md, iso9283)", file=path, row=1,
                                column=col)
    out = {"_lines": np.array([k for k, _ in body])}
    numeric = [c for c in header if c not in ("pose", "cube", "session")]
    for c in header:
        j = header.index(c)
        values = []
        for k, r in body:
            if len(r) != len(header):
                raise DataFileError(f"has {len(r)} fields, the header {len(header)}", file=path, row=k)
            v = r[j].strip()
            if c in numeric:
                try:
                    values.append(float(v))
                except ValueError:
                    raise DataFileError(f"{v!r} is not a number", file=path, row=k, column=c) from None
            else:
                values.append(v)
        out[c] = np.array(values, dtype=float if c in numeric else object)
    if not all(c in out for c in CMD_XYZ) and not all(c in out for c in robot.q_columns):
        missing = next(c for c in CMD_XYZ if c not in out)
        raise DataFileError(f"the commanded pose is needed: {', '.join(CMD_XYZ)} (robot base frame), or the commanded "
                            f"joints {robot.q_columns[0]}..{robot.q_columns[-1]}", file=path, row=1, column=missing)
    return out


def _angles_to_matrix(deg):
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler("XYZ", deg, degrees=True).as_matrix()


def _matrix_to_angles(R):
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(R).as_euler("XYZ", degrees=True)


def run(args) -> int:
    from ..apply._iso9283 import Iso9283, Poses, rigid_fit
    from ..calibration import calibrate
    from ..data._measurements import Measurements
    from ..model._symbolic import Model, pose_to_base0
    from ..result import load_calibration

    check_outputs({"--json": args.json, "--html": args.html}, [args.robot, args.measured], args.force)
    cal = load_calibration(args.robot) if args.robot.lower().endswith(".json") else None
    robot = cal.model.robot if cal is not None else robot_from_args(args.robot, args)
    cols = _read(args.measured, robot)
    N = len(cols["_lines"])
    has_q = all(c in cols for c in robot.q_columns)
    q = robot.from_file_units(np.column_stack([cols[c] for c in robot.q_columns])) if has_q else None
    if all(c in cols for c in CMD_XYZ):
        commanded = np.column_stack([cols[c] for c in CMD_XYZ])
        how = "the commanded positions of the file (cmd_x_mm ..)"
    else:
        commanded = Model(robot, "nominal", jit=False).predict(q, base0=pose_to_base0(np.eye(4))) * 1000.0
        how = f"the nominal model's tool point of {robot.name} at the commanded joints"
    measured = np.column_stack([cols[c] for c in XYZ])
    angles = all(c in cols for c in CMD_RXYZ + RXYZ)
    cmd_ang = np.column_stack([cols[c] for c in CMD_RXYZ]) if angles else None
    att_ang = np.column_stack([cols[c] for c in RXYZ]) if angles else None
    after = cols["compensated"] != 0 if "compensated" in cols else np.zeros(N, bool)
    before = ~after
    if not before.any():
        raise InputError("has no rows measured before compensation (compensated = 0)", file=args.measured)
    report = Iso9283(source=args.measured)
    report.notes.append(f"commanded poses: {how}")
    attained = measured
    if args.frame == "fit":
        R, t = rigid_fit(measured[before], commanded[before])
        attained = measured @ R.T + t
        if angles:
            att_ang = _matrix_to_angles(R @ _angles_to_matrix(att_ang))
        report.notes.append(f"the attained poses are placed in the robot base frame by the rigid transform that "
                            f"fits them best to the commanded ones over {int(before.sum())} poses (--frame fit): the "
                            "mean error and its rotation are absorbed; with the poses measured in the robot base "
                            "frame, --frame base")
    cube = cols.get("cube", np.array(["1"] * N, dtype=object))
    cube = np.array([_label(c) for c in cube], dtype=object)
    pose = np.array([str(p) for p in cols["pose"]], dtype=object)
    cycle = cols["cycle"]
    pairs = _pairs(args.pairs, set(pose.tolist()))
    full = Poses(cycle, pose, cube, commanded, attained, cmd_ang, att_ang)
    report.add("before", full.subset(np.flatnonzero(before)), pairs)
    if cal is not None:
        if q is None:
            raise InputError(f"the figures after compensation need the commanded joints {robot.q_columns[0]}.. of "
                             "each pose", file=args.measured)
        data = Measurements.from_arrays(q[before], measured[before] / 1000.0, prismatic=robot.prismatic)
        data.path = args.measured
        fitted = calibrate(cal, data, "base", "lm", warn=False)
        left = (data.xyz - fitted.predict(data)) * 1000.0                       # what the model leaves, mm
        Rb = fitted.base_matrix()[:3, :3]
        predicted = full.subset(np.flatnonzero(before))
        predicted.attained = predicted.commanded + left @ Rb                    # in the robot base frame
        predicted.attained_angles = predicted.commanded_angles = None
        report.add("after (predicted)", predicted, pairs)
        report.notes.append("after (predicted): a compensated pose misses its command by what the calibration "
                            f"leaves of that pose's error ({args.robot}, its base pose fitted again to these poses: "
                            "another day's tracker placement)")
    if after.any():
        report.add("after (measured)", full.subset(np.flatnonzero(after)), pairs)
    if not report.repeated:
        report.notes.append("each pose was commanded and measured once (one cycle): pose and distance "
                            "repeatability (RP, RD) need repeated cycles (30 in ISO 9283) and are not given")
    stream = human_stream(args.json, args.html)
    print(report.text(), file=stream)
    if args.json:
        write_json(args.json, report.to_dict(), args.force)
    if args.html:
        write_text(args.html, report.html(), args.force)
    return 0


def _label(c) -> str:
    """A cube's name: ``3`` whether written 3 or 3.0."""
    try:
        v = float(c)
    except ValueError:
        return str(c)
    return str(int(v)) if v == int(v) else str(c)


def _pairs(text: str | None, poses: set[str]) -> list[tuple[str, str]]:
    if text is None:
        return [("P2", "P4")] if {"P2", "P4"} <= poses else []
    out = []
    for item in text.split(","):
        a, sep, b = item.strip().partition("-")
        if not sep or a not in poses or b not in poses:
            raise InputError(f"--pairs {text}: {item!r} is not A-B with two poses of the file")
        out.append((a, b))
    return out
