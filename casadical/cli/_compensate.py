"""``compensate``: corrected joint targets of a robot program from a calibration."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ._common import (
    add_checks,
    add_force,
    add_terms,
    check_options,
    check_outputs,
    compensator_line,
    float_in,
    human_stream,
    int_at_least,
    user_terms,
    warn_session_frame,
    write_json,
)
from ._programs import add_program_options, run_program

#: below this many rows CasADi's virtual machine beats compiling the model (~3 s once per run)
JIT_MIN_ROWS = 10_000


def register(sub) -> None:
    p = sub.add_parser("compensate", help="corrected joint targets that put the calibrated tool point on targets, "
                                          "or a robot program filtered",
                       description="A robot program (PROGRAM.script/.urscript, .src with its .dat, .mod: by the "
                                   "file type) is filtered: each target replaced by the one at which the calibrated "
                                   "robot reaches what the program meant, every other byte kept (docs/formats.md, "
                                   "compensate). "
                                   "For each row of TARGETS.csv (desired tool point x_mm, y_mm, z_mm in the "
                                   "measurement frame; programmed joints q1_deg..qN_deg as the start) find the "
                                   "joints at which the calibrated model puts the tool point on the target. "
                                   "Robots with 6 joints or more keep the flange orientation the nominal model "
                                   "has at the programmed joints where the calibration measured orientation (a "
                                   "full-pose calibration) or --hold-orientation asks, or, when TARGETS.csv has "
                                   "rx_deg, ry_deg, rz_deg "
                                   "and CAL.json is a full-pose calibration, put the probe in that orientation "
                                   "(measurement frame); the remaining freedom takes the least joint change. "
                                   "JOINTS.csv holds the input columns with corrected q*_deg, plus "
                                   "programmed_q*_deg, dq*_deg, residual_mm (and orientation_error_deg). "
                                   "A row that is not reached or needs a joint beyond its limit is an error; "
                                   "nothing is written then.")
    p.add_argument("cal", metavar="CAL.json", help="calibration JSON written by 'calibrate'")
    p.add_argument("targets", metavar="TARGETS.csv|PROGRAM",
                   help="programmed joints and desired tool points, or a program (URScript, KRL, RAPID)")
    p.add_argument("--out", required=True, metavar="JOINTS.csv|FILTERED",
                   help="corrected joint targets to write (a program: the filtered program, of the same file type)")
    p.add_argument("--tolerance-mm", type=float_in(0, math.inf), default=1e-4,
                   help="largest distance of the calibrated tool point from a target (default: %(default)g mm)")
    p.add_argument("--max-iter", type=int_at_least(1), default=30,
                   help="iterations per row at most (default: %(default)s)")
    p.add_argument("--max-change-deg", type=float_in(0, 360, hi_open=False), default=5.0,
                   help="largest change of a joint from its programmed value: a target that needs more is an "
                        "error; where holding the orientation would need more, only the point is reached "
                        "(default: %(default)g deg; as many mm for a prismatic joint, a linear axis)")
    p.add_argument("--max-deg-per-mm", type=float_in(0, math.inf), default=2.0, metavar="DEG",
                   help="largest joint motion per mm of correction (or per mrad of orientation) along any direction: "
                        "near a singular configuration, where an exact correction would need more, it is damped "
                        "(least joint motion) and the rows are named with their conditioning (default: %(default)g)")
    p.add_argument("--position-only", action="store_true",
                   help="hold no orientation (neither the targets' rx_deg, ry_deg, rz_deg nor the nominal flange's): "
                        "least joint change that reaches the point")
    add_program_options(p)
    add_checks(p)
    add_terms(p)
    add_force(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..programs._program import language_of

    language = language_of(args.targets)
    if language is not None:
        return run_program(args, language)
    return _run_csv(args)


def _run_csv(args) -> int:
    from ..apply._inverse import compensate
    from ..data._measurements import Measurements
    from ..result import load_calibration

    program_only = [o for o, v in (("--tool", args.tool), ("--base", args.base), ("--config", args.config),
                                   ("--extrapolate", args.extrapolate)) if v]
    if program_only:
        raise InputError(f"{program_only[0]} is an option of the program form (a .script, .src or .mod file); "
                         f"{args.targets} is a TARGETS.csv")
    if args.position_only and args.hold_orientation:
        raise InputError("--position-only and --hold-orientation contradict each other; give one")
    check_outputs({"--out": args.out, "--json": args.json}, [args.cal, args.targets], args.force)
    cal = load_calibration(args.cal, terms=user_terms(args))
    targets = Measurements.read_csv(args.targets, robot=cal.model.robot)
    warn_session_frame(cal.sessions, targets, args.cal)
    if len(targets) < JIT_MIN_ROWS:
        cal.model.jit = False
    result = compensate(cal, targets, tolerance_mm=args.tolerance_mm, max_iter=args.max_iter,
                        max_change_deg=args.max_change_deg,
                        orientation=False if args.position_only else True if args.hold_orientation else None,
                        max_deg_per_mm=args.max_deg_per_mm,
                        **check_options(args))
    if cal.coverage is not None:    # the programmed joints: the same rows whatever is held (the corrections move
        cal.coverage.warn(targets.q_deg if any(targets.prismatic) else np.degrees(targets.q), targets.lines,
                          args.targets)   # them by fractions of a degree)
    result.joints().write_csv(args.out, overwrite=args.force)
    if args.json:
        write_json(args.json, {"targets": args.targets, "held": result.held,
                               "orientation_held": result.orientation_error is not None, "probe": result.probe,
                               "rows": len(targets), "converged": int(result.converged.sum()),
                               "damped": int(result.damped.sum()) if result.damped is not None else 0}, args.force)
    stream = human_stream(args.json)
    print(result.summary(), file=stream)
    line = compensator_line(cal, targets)
    if line:
        print(line.replace("poses", "targets"), file=stream)
    print(f"corrected joints -> {args.out}", file=stream)
    return 0
