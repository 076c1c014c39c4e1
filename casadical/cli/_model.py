"""``inspect`` and ``predict``: the symbolic model and what it predicts."""

from __future__ import annotations

import math

import numpy as np

from .._format import number
from ..errors import InputError
from ._common import (
    add_checks,
    add_fixture,
    add_force,
    add_json,
    add_terms,
    add_urdf_chain,
    check_options,
    check_outputs,
    compensator_line,
    int_at_least,
    robot_from_args,
    robot_or_calibration,
    timed,
    user_terms,
    warn_session_frame,
    warn_session_terms,
    write_json,
)


def register(sub) -> None:
    p = sub.add_parser("inspect", help="show the symbolic model, its parameters and their identifiability",
                       description="Show the symbolic model of ROBOT: parameters with units and nominal "
                                   "values, which are identifiable (and why not), expression sizes.")
    p.add_argument("robot", metavar="ROBOT", help="built-in robot (ys100, hh800, ur10), robot TOML or URDF file")
    p.add_argument("--model", default="kinematic+compliance",
                   help="error model, terms joined by '+' (default: %(default)s)")
    p.add_argument("--poses", type=_poses, default=200, metavar="N|DATA.csv",
                   help="random poses for the identifiability analysis, or a measurement CSV whose poses (and "
                        "columns) to analyse (default: %(default)s random poses)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random poses (default: %(default)s)")
    add_json(p, "the model description")
    add_urdf_chain(p)
    add_terms(p)
    add_fixture(p)
    add_force(p)
    p.set_defaults(func=run_inspect)

    p = sub.add_parser("predict", help="predict tool positions for joint readings",
                       description="Predict tool positions. MODEL is a robot (nominal model) or a "
                                   "calibration JSON written by 'calibrate'. OUT.csv holds the input "
                                   "columns plus x_mm, y_mm, z_mm (measured ones are renamed measured_*), and for "
                                   "a full-pose calibration the probe's orientation rx_deg, ry_deg, rz_deg "
                                   "(intrinsic XYZ).")
    p.add_argument("model", metavar="MODEL", help="robot (nominal model) or calibration JSON")
    p.add_argument("poses", metavar="POSES.csv", help="joint readings (q1_deg, ...)")
    p.add_argument("--out", required=True, metavar="OUT.csv", help="output CSV")
    p.add_argument("--std", action="store_true",
                   help="also write std_mm, the predicted position's uncertainty at each pose (rms 3-D error of the "
                        "prediction): the parameters' covariance (std_params_mm) and, with a GP compensator, its "
                        "predictive std (std_layer_mm); and interval_mm, the radius of the 95 %% interval of a "
                        "measured point (the noise added); MODEL must be a calibration JSON")
    add_checks(p)
    add_urdf_chain(p)
    add_terms(p)
    add_force(p)
    p.set_defaults(func=run_predict)


def run_inspect(args) -> int:
    from ..data._simulate import sample_poses
    from ..model._symbolic import Model
    from ..stats._identifiability import analyse
    check_outputs({"--json": args.json}, [args.robot] + ([args.poses] if isinstance(args.poses, str) else []),
                  args.force)
    robot = robot_from_args(args.robot, args)
    spec = args.model
    if args.terms is not None:      # the terms file's terms are inspected, named in --model or not
        named = {item.split("@")[0].split("[")[0].strip() for item in spec.split("+")}
        spec = "+".join([spec] + [d.name for d in user_terms(args) if d.name not in named])
    unobservable = []
    if isinstance(args.poses, str):
        from ..data import Measurements
        from ..model._symbolic import parse_spec
        from ..terms._tool_points import check_tool_points, with_tool_points
        data = timed(Measurements.read_csv(args.poses, robot=robot), args)
        said = check_tool_points(data, robot)
        if said:
            print(f"note: {robot.source or robot.name}: {said}")
        # each row's tool point (a tool column)
        model = Model(robot, with_tool_points(parse_spec(spec, user_terms(args)), data), user_terms=user_terms(args))
        q, cov, n_poses = data.q, model.covariates(data), len(data)
    else:
        model = Model(robot, spec, user_terms=user_terms(args))
        rng = np.random.default_rng(args.seed)
        q = sample_poses(robot, args.poses, rng, floor_z=None)
        cov, n_poses = _random_covariates(model, len(q)), args.poses
    P, J = model.predict_jacobian(q, cov=cov)
    if isinstance(args.poses, str) and data.touches:
        # rows that touch: what they cannot see held and said (as calibrate does), the rest from what they touched
        from ..calibration._unobservable import unseen, whole_robot
        unobservable = unseen(data, model.parameters)
        for u in unobservable:
            model.parameters.fix(u["parameters"], f"{u['what']}: {u['why']}")
        moving = {n for n, m in zip(model.parameters.names, np.linalg.norm(J, axis=(0, 1)) > 0) if m}
        J = data.layout.project(P, J)[1]
    ident = analyse(J, model.parameters)
    if unobservable and data.touching.all():
        whole_robot(ident, moving, unobservable)
    ident.apply(model.parameters)
    size = model.expression_size()
    if args.json:
        doc = {
            "robot": robot.name, "model": model.spec, "convention": robot.convention,
            "n_joints": robot.n, "covariates": model.covariate_names,
            "expression": {"parameters": size.n_parameters, "fk_instructions": size.fk_instructions,
                           "jacobian_instructions": size.jacobian_instructions, "fk_nodes": size.fk_nodes},
            "identifiability": {"poses": n_poses, "condition_number": ident.condition_number,
                                "rank": len(ident.identifiable)},
            "parameters": [param_json(p) for p in model.parameters],
        }
        if unobservable:
            doc["unobservable"] = unobservable
        if model.user_terms:
            doc["user_terms"] = [{**t.definition.to_dict(), "identifiable": {
                p.name: bool(p.identifiable) for p in model.parameters if p.term == t.name}}
                for t in model.user_terms]
        write_json(args.json, doc, args.force)
        return 0
    print(f"robot {robot.name} ({robot.n} joints, {robot.convention.upper()} convention"
          f"{', parallelogram loop on joint %d' % robot.loop.joint if robot.loop else ''})  source: {robot.source}")
    print(f"model {model.spec}: {size.n_parameters} parameters; per-pose covariates: "
          f"{', '.join(model.covariate_names)}")
    print(f"symbolic size: forward kinematics {size.fk_instructions} instructions "
          f"({size.fk_nodes} nodes), with Jacobian {size.jacobian_instructions} instructions")
    where = f"the {n_poses} poses of {args.poses}" if isinstance(args.poses, str) else \
        f"{args.poses} random poses within the joint limits (seed {args.seed})"
    print(f"identifiability from {where}: "
          f"{len(ident.identifiable)} of {len(ident.identifiable) + len(ident.unidentifiable)} "
          f"free parameters identifiable, condition number {ident.condition_number:.3g}")
    for u in unobservable:
        print(f"not seen by these rows: {u['what']} ({u['why']}): {', '.join(u['parameters'])} held")
    for line in user_term_lines(model, isinstance(args.poses, str)):
        print(line)
    print()
    print(model.parameters.table())
    return 0


def _poses(text: str):
    """``--poses``: a number of random poses, or a measurement CSV."""
    if text.strip().lstrip("+-").isdigit():
        return int_at_least(1)(text)
    return text


def _random_covariates(model, N: int) -> np.ndarray:
    """Covariates of random poses: the model's defaults; a column only a user term reads is 0 there (``row``:
    the pose's number)."""
    cov = model.default_covariates(N)
    for k, name in enumerate(model.covariate_names):
        if name == "row":
            cov[:, k] = np.arange(N)
        elif not np.all(np.isfinite(cov[:, k])):
            cov[:, k] = 0.0
    return cov


def user_term_lines(model, from_data: bool) -> list[str]:
    """``inspect``'s words on each user term: its effects' expressions and which parameters the poses identify."""
    lines = []
    for t in model.user_terms:
        d = t.definition
        on = "" if d.joints is None else (f", joint {d.joints[0]}" if d.one_joint else
                                          f", joints {', '.join(map(str, d.joints))}")
        lines += ["", f"user term {d.name} ({d.file}{on}, scope {d.scope}):"]
        for effect, texts in d.texts.items():
            lines.append(f"  {effect} = " + (texts[0] if len(texts) == 1 and effect in ("angle", "offset")
                                             else "[" + ", ".join(texts) + "]"))
        defined = {f"{d.name}.{pd.name}": pd for pd in d.parameters}
        for p in model.parameters:
            if p.term == d.name:
                lines.append(f"  {p.name}: " + ("identifiable" if p.identifiable else
                                                f"NOT identifiable ({p.reason})")
                             + _as_defined(defined.get(p.name.split("@")[0]), p))
        cols = [c for c in d.columns() if c != "row"]
        if cols and not from_data:
            lines.append(f"  reads {', '.join(cols)}: 0 at the random poses; give --poses DATA.csv to judge it on "
                         "measured poses")
    return lines


def _as_defined(pd, p) -> str:
    """A user term's parameter as its file states it (unit, bounds, start), and the unit the table shows it in
    when that is another (rad and m are shown in deg and mm, as every parameter)."""
    if pd is None:
        return ""
    unit = f" {pd.unit}" if pd.unit else ""
    shown = (f" (the table below shows it in {p.reading_unit}: {number(p.to_reading(1.0), 4)} {p.reading_unit} "
             f"per {pd.unit})" if pd.unit and p.reading_unit != pd.unit else "")
    return (f"; in the terms file: unit {pd.unit or '(none)'}{shown}, bounds {number(pd.lower, 4)} .. "
            f"{number(pd.upper, 4)}{unit}, start {number(pd.start, 4)}{unit}")


def param_json(p) -> dict:
    return {"name": p.name, "value": p.to_display(p.value), "nominal": p.to_display(p.nominal),
            "std": p.to_display(p.std) if math.isfinite(p.std) else None,
            "identifiable": bool(p.identifiable) if p.identifiable is not None else not p.fixed,
            "fixed": p.fixed, "reason": p.reason, "unit": p.display_unit, "term": p.term,
            "joint": p.joint}


def run_predict(args) -> int:
    from ..data._checks import check_calibration_fits, check_poses
    from ..data._measurements import RXYZ, Measurements
    from ..model._symbolic import Model, parse_spec
    from ..result import CalibrationResult, ErrorStats
    from ..stats._alignment import align
    from ..terms._tool_points import with_tool_points

    check_outputs({"--out": args.out}, [args.model, args.poses], args.force)
    source = robot_or_calibration(args.model, args)
    if isinstance(source, CalibrationResult):
        cal, robot = source, source.model.robot
        data = Measurements.read_csv(args.poses, robot=robot)
        warn_session_frame(cal.sessions, data, args.model)
        xyz = cal.predict(data)
    else:
        if args.std:
            raise InputError(f"{args.model}: --std needs a calibration JSON (a robot's nominal model has no "
                             "parameter covariance)")
        cal, robot = None, source
        data = Measurements.read_csv(args.poses, robot=robot)
        model = Model(robot, with_tool_points(parse_spec("nominal"), data))    # each row's tool point
        xyz = model.predict(data.q, cov=model.covariates(data))
    # a robot's nominal model judges the poses as calibrate does (another robot's poses are refused); a
    # calibration's predictions are judged below against its own error
    check_poses(data, robot, predicted=xyz, nominal=cal is None, **check_options(args))
    stats = None
    if data.has_positions:
        if cal is None:   # the robot file's base is not the tracker's: compare after a best-fit base
            T = align(xyz, data.xyz)
            errors = np.linalg.norm(xyz @ T[:3, :3].T + T[:3, 3] - data.xyz, axis=1)
        else:
            errors = np.linalg.norm(xyz - data.xyz, axis=1)
            check_calibration_fits(errors, data, args.model,
                                   cal.calibration.mean_mm if cal.calibration else None, args.allow_mismatch)
        stats = ErrorStats.of(errors)
    angles = None
    if cal is not None and cal.has_orientation and data.has_orientation:
        angles = cal.orientation_stats(data)
    if cal is not None and cal.coverage is not None:
        cal.coverage.warn(data.q_deg, data.lines, args.poses)
    if cal is not None:
        warn_session_terms(cal, data, args.model)
    out = data.with_positions(xyz)
    if cal is not None and cal.has_orientation:   # a full-pose calibration: the probe's orientation too
        out = out.with_orientations(cal.predict_rotations(data))
    elif data.has_orientation:
        # measured orientations are renamed as the measured positions are: an rx_deg beside the model's x_mm would
        # read as the model's (compensate takes it for the target orientation)
        out = out.with_columns({f"measured_{k}" if k in RXYZ else k: v for k, v in out.columns.items()})
    if args.std:
        from ..prediction import prediction_interval, prediction_std

        try:
            sp, sl = prediction_std(cal, data)
        except InputError as e:
            raise InputError(e.message, file=args.model) from e
        total = sp if sl is None else np.sqrt(sp ** 2 + sl ** 2)
        cols = {"std_mm": total * 1000, "std_params_mm": sp * 1000}
        if sl is not None:
            cols["std_layer_mm"] = sl * 1000
        cols["interval_mm"] = prediction_interval(cal, data, (sp, sl)) * 1000
        out = out.with_columns({**out.columns, **cols})
    out.write_csv(args.out, overwrite=args.force)
    print(f"predicted {len(data)} poses -> {args.out}")
    if args.std:
        print(f"predicted uncertainty (rms 3-D error of the prediction): median {np.median(total) * 1000:.4f} mm, "
              f"max {np.max(total) * 1000:.4f} mm")
    if stats is not None:
        how = "calibrated model" if cal is not None else "nominal model with its base pose fitted to them"
        print(f"error against the measured positions ({how}): {stats.line()}")
    if angles is not None:
        print(f"error against the measured orientations: {angles.line()}")
    if cal is not None:
        line = compensator_line(cal, data)
        if line:
            print(line)
    return 0

