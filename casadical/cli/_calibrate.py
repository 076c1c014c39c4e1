"""``calibrate``: identify a model from measured poses."""

from __future__ import annotations

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
    fold_long_lines,
    human_stream,
    int_at_least,
    robot_or_calibration,
    timed,
    user_terms,
    warn_session_frame,
    write_text,
)


def register(sub) -> None:
    p = sub.add_parser("calibrate", help="identify a calibrated model from measured poses",
                       description="Identify the parameters of MODEL (kinematic, kinematic+compliance, or more "
                                   "terms joined by '+') from DATA.csv; the base pose is always estimated. "
                                   "Writes CAL.json and prints a summary. With a calibration JSON in place of "
                                   "ROBOT, only what MODEL names is estimated again (base: the base pose "
                                   "alone; kinematic: the geometry; base+tool: the base pose and the tool) "
                                   "and every other value is kept: how a calibration is taken to a new "
                                   "measurement series or tracker set-up. Several DATA files are several "
                                   "measurement sessions of one robot (as is a file with a session column): each "
                                   "has its own base pose, the robot's parameters are shared. Data with a measured "
                                   "orientation (rx_deg, ry_deg, rz_deg) are calibrated on the full pose (unless "
                                   "--position-only): the probe's mounting on the flange is estimated too.")
    p.add_argument("robot", metavar="ROBOT",
                   help="built-in robot, robot TOML or URDF file, or a calibration JSON to take further")
    p.add_argument("data", metavar="DATA.csv", nargs="+",
                   help="measured poses (q1_deg, ..., x_mm, y_mm, z_mm); several files: one session each")
    p.add_argument("--model", default="kinematic+compliance",
                   help="error model, e.g. kinematic, kinematic+compliance, "
                        "kinematic+compliance[2,3]+periodic[2:1] (default: %(default)s)")
    p.add_argument("--out", required=True, metavar="CAL.json", help="calibration JSON to write")
    p.add_argument("--html", metavar="REPORT.html",
                   help="also write a self-contained HTML report: errors before (nominal model, base fitted) and "
                        "after, residuals per axis, parameters with std, correlations, poses set aside, "
                        "identifiability")
    p.add_argument("--solver", default="ipopt", choices=["ipopt", "lm", "gn", "auto"],
                   help="ipopt (bounded), lm (Levenberg-Marquardt), gn (Gauss-Newton), auto (lm, then "
                        "ipopt if a bound is crossed); default %(default)s")
    p.add_argument("--max-iter", type=int_at_least(1), default=None,
                   help="solver iteration limit (default: the solver's own, 200 for ipopt, 100 for lm/gn)")
    p.add_argument("--robust", default="huber", choices=["huber", "none"],
                   help="loss: huber (pseudo-Huber with the noise scale from the data: bad measurements are "
                        "down-weighted and reported) or none (plain least squares); default %(default)s")
    p.add_argument("--fix", default="", help="comma-separated parameters to hold at nominal (default: none)")
    p.add_argument("--keep-compensator", action="store_true",
                   help="with a calibration JSON in place of ROBOT: keep its GP compensator (gp_compensator), "
                        "which is dropped otherwise like every term of the session it was fitted on")
    add_session_tool(p)
    add_levelled(p)
    p.add_argument("--validate", metavar="VAL.csv",
                   help="held-out poses, never fitted: their errors (mean, max, rms mm) are printed, written to "
                        "CAL.json ('validation') and shown in the HTML report")
    p.add_argument("--position-only", action="store_true",
                   help="calibrate on the measured positions alone; without it, data with a measured orientation "
                        "(rx_deg, ry_deg, rz_deg) are calibrated on the full pose, position and orientation "
                        "weighted by their noise scales from the data")
    add_row_spacing(p)
    add_checks(p)
    add_quiet(p)
    add_urdf_chain(p)
    add_terms(p)
    add_fixture(p)
    add_force(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..calibration import calibrate
    from ..data._checks import check_held_out
    from ..data._measurements import Measurements
    from ..data._sessions import read_sessions
    from ..errors import InputError
    from ..result import CalibrationResult

    check_outputs({"--out": args.out, "--html": args.html}, [args.robot, *args.data, args.validate], args.force)
    robot = robot_or_calibration(args.robot, args)
    if args.keep_compensator and not (isinstance(robot, CalibrationResult) and robot.model.term("gp_compensator")):
        raise InputError("--keep-compensator keeps the GP compensator of a calibration taken further: "
                         + (f"{args.robot} has none" if isinstance(robot, CalibrationResult)
                            else "give a calibration JSON in place of ROBOT"))
    arm = robot.model.robot if isinstance(robot, CalibrationResult) else robot
    data = timed(read_sessions(args.data, robot=arm, require_positions=True), args)
    # read before the fit: a malformed file stops the command before the work
    val = timed(Measurements.read_csv(args.validate, robot=arm, require_positions=True), args) \
        if args.validate else None
    if val is not None:
        check_held_out(data, val)          # before the fit: validation poses it has seen would judge nothing
        warn_session_frame(data.session_names, val, "the calibration")
    opts = {"max_iter": args.max_iter} if args.max_iter else {}
    status = Status(args.quiet)
    with status.slow(f"calibrate: fitting model {args.model} to {len(data)} poses ({args.solver}, robust loss "
                     f"{args.robust})"):
        # a calibration taken further judges each cause it carries on these poses (casadical.apply._carry)
        fit = calibrate
        if isinstance(robot, CalibrationResult):
            from ..apply._carry import carry as fit
        result = fit(robot, data, args.model, solver=args.solver, solver_options=opts,
                     fix=tuple(f.strip() for f in args.fix.split(",") if f.strip()), robust=args.robust,
                     session_tools=args.session_tool, position_only=args.position_only,
                     keep_compensator=args.keep_compensator, terms=user_terms(args), **check_options(args))
    from ..calibration._gravity import warn_gravity
    warn_gravity(result, args.levelled)
    if val is not None:     # the checks predict makes, then the held-out errors, before anything is written
        result.validate(val, name=f"fitted to {' '.join(args.data)}", **check_options(args))
    result.save(args.out, overwrite=args.force)
    out = human_stream(args.html)        # --html -: standard output holds the page alone
    print(fold_long_lines(result.summary()), file=out)
    print(f"\ncalibration -> {args.out}", file=out)
    if args.html:
        from ..html import calibration_html
        before, label = None, "nominal model, base pose fitted"
        if isinstance(robot, CalibrationResult):    # the calibration taken further: the error it starts from
            before = calibrate(robot, data, "base", "lm", warn=False, robust=args.robust,
                               position_only=args.position_only)
            label = f"{args.robot} with its base pose re-estimated"
        write_text(args.html, calibration_html(result, data, before, label, validation=val, progress=status.line),
                   args.force)
        print(f"html report -> {'standard output' if args.html == STDOUT else args.html}", file=out)
    return 0
