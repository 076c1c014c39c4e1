"""``split``, ``simulate``, ``import`` and ``import-ur10``: measurement files in and out."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ._common import add_force, check_outputs, int_at_least, write_json


def register(sub) -> None:
    p = sub.add_parser("split", help="split a measurement file into calibration and validation poses",
                       description="Random split of DATA.csv: N rows for calibration, the rest for "
                                   "validation; both keep the original row order, and columns move1..moveN "
                                   "keep the direction of each joint's last move in the original sequence, "
                                   "source_row each pose's row in it.")
    p.add_argument("data", metavar="DATA.csv", help="measurement file")
    p.add_argument("-n", type=int_at_least(1), required=True, help="number of calibration poses")
    p.add_argument("--out-cal", required=True, metavar="CAL.csv", help="calibration poses to write")
    p.add_argument("--out-val", required=True, metavar="VAL.csv", help="validation poses to write")
    p.add_argument("--seed", type=int, default=0, help="seed of the random split (default: %(default)s)")
    add_force(p)
    p.set_defaults(func=run_split)

    p = sub.add_parser("simulate", help="simulate the pose sets of an experiment protocol",
                       description="Simulate measurements from a protocol of problems/protocols "
                                   "(name or TOML path); writes one CSV per pose set and truth.json.")
    p.add_argument("protocol", help="protocol name (e.g. ca-ys100) or protocol TOML file")
    p.add_argument("--out-dir", required=True, help="folder for the CSV files and truth.json (created)")
    p.add_argument("--seed", type=int, default=None, help="override the protocol's seed")
    add_force(p)
    p.set_defaults(func=run_simulate)

    p = sub.add_parser("import", help="convert any tracker file to the measurement CSV with a column mapping",
                       description="Convert a delimited tracker file to the measurement CSV contract. "
                                   "The mapping says which columns are joints (deg or rad), which the "
                                   "measured point (mm or m; directly or as target + deviation), the "
                                   "separator and decimal mark, and what else to keep; see docs/formats.md.")
    p.add_argument("source", help="tracker file (text with a header row)")
    maps = p.add_argument("--map", action="append", required=True, dest="maps",
                          metavar="MAP.toml|PRESET|KEY=VALUE",
                          help="column mapping: a TOML file or a preset ({presets}), "
                               "then any key=value pairs that set or override keys (repeat --map)")
    _add_import_options(p)
    p.set_defaults(func=run_import)

    def complete_help(parser) -> None:   # the presets need the importers package: only for --help
        from ..importers._column_map import presets

        maps.help = maps.help.format(presets=", ".join(sorted(presets())))

    p.complete_help = complete_help

    p = sub.add_parser("import-ur10", help="convert the UR10 (ipa) raw format to the measurement CSV",
                       description="Convert a raw UR10 file (';' separated, decimal comma, radians) "
                                   "to the measurement CSV contract: the same as "
                                   "'casadical import SOURCE --map ur10-ipa'.")
    p.add_argument("source", help="raw UR10 measurement file")
    _add_import_options(p)
    p.set_defaults(func=run_import, maps=["ur10-ipa"])


def _add_import_options(p) -> None:
    p.add_argument("--out", required=True, metavar="OUT.csv", help="output CSV")
    p.add_argument("--allow-multiturn", action="store_true",
                   help="accept joint readings beyond a turn (2 pi) with joint_unit = \"rad\" (a joint that turns "
                        "more than once; else they are an error: degrees mapped as radians)")
    p.add_argument("--keep-order", action="store_true",
                   help="keep the file's row order where the timestamps say otherwise (default: sort by time)")
    add_force(p)


def run_split(args) -> int:
    from ..data._measurements import Measurements

    check_outputs({"--out-cal": args.out_cal, "--out-val": args.out_val}, [args.data], args.force)
    data = Measurements.read_csv(args.data)
    n = len(data)
    if not args.n < n:
        raise InputError(f"cannot take {args.n} calibration poses out of {n}: choose 1 to {n - 1}",
                         file=args.data)
    idx = np.sort(np.random.default_rng(args.seed).permutation(n)[: args.n])
    rest = np.setdiff1d(np.arange(n), idx)
    # the direction of each joint's last move in the original sequence and each pose's place in it travel
    # with the rows (a subset cannot recompute them): columns move1..moveN and source_row
    extra = {} if any(c.startswith("move") for c in data.columns) else \
        {f"move{j + 1}": data.moves[:, j].astype(int) for j in range(data.n_joints)}
    if "source_row" not in data.columns:
        extra["source_row"] = data.rows + 1
    if extra:
        data = Measurements({**data.columns, **extra}, data.path, data.rows, data.moves, data.lines)
    data.subset(idx).write_csv(args.out_cal, overwrite=args.force)
    data.subset(rest).write_csv(args.out_val, overwrite=args.force)
    print(f"{len(idx)} poses -> {args.out_cal}, {len(rest)} poses -> {args.out_val} (row order kept)")
    return 0


def run_simulate(args) -> int:
    from ..data._simulate import load_protocol

    proto = load_protocol(args.protocol)
    out = Path(args.out_dir)
    outputs = {f"{name}.csv": str(out / f"{name}.csv") for name in proto.sets}
    outputs["truth.json"] = str(out / "truth.json")
    if out.exists() and not out.is_dir():
        raise InputError("--out-dir names a file, not a folder", file=args.out_dir)
    if out.is_dir():
        check_outputs(outputs, [args.protocol], args.force)
    sets, truth = proto.generate(args.seed)
    try:                              # made only now: a protocol that fails leaves no empty folder behind
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot make the folder: {e.strerror or e}", file=args.out_dir) from e
    for name, data in sets.items():
        data.write_csv(out / f"{name}.csv", overwrite=args.force)
        print(f"{name}: {len(data)} poses -> {out / (name + '.csv')}")
    truth_doc = {"protocol": proto.name, "robot": proto.robot.name,
                 "parameters": {n: v for n, v in zip(truth.model.parameters.names, truth.values.tolist())},
                 "base0": truth.base0.tolist(), "model": truth.model.spec}
    write_json(outputs["truth.json"], truth_doc, args.force)
    print(f"true parameters (SI units) -> {outputs['truth.json']}")
    return 0


def run_import(args) -> int:
    from ..importers import import_file, load_column_map
    from ..importers._column_map import mapping_file

    column_map = load_column_map(args.maps)
    map_files = [str(f) for m in args.maps if (f := mapping_file(m)) is not None]
    check_outputs({"--out": args.out}, [args.source, *map_files], args.force)
    imported = import_file(args.source, args.out, column_map, overwrite=args.force,
                           sort_by_time=not args.keep_order, multiturn=args.allow_multiturn)
    print(f"mapping ({column_map.source}):")
    groups: dict[str, list] = {}
    for m in imported.mapped:
        groups.setdefault(m.group, []).append(m)
    for group, items in groups.items():
        notes = sorted({m.note for m in items if m.note})
        pairs = ", ".join(f"{m.source} -> {m.output}" for m in items)
        print(f"  {group}{' (' + '; '.join(notes) + ')' if notes else ''}: {pairs}")
    if imported.dropped:
        print(f"  dropped: {', '.join(imported.dropped)}")
    print(f"{len(imported)} rows -> {args.out}")
    return 0
