"""``compensate CAL.json PROGRAM --out FILTERED``: the program form of ``compensate`` (by the file's type).

Shared with ``plan-poses --program``: reading the tool and base options of a language, writing a program.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from ._common import check_outputs, float_in, human_stream, user_terms, write_json


def add_program_options(p) -> None:
    """compensate's options of what is held and its report (both forms), and those only the program form reads."""
    p.add_argument("--hold-orientation", action="store_true",
                   help="hold the orientation a target means (the flange's) even where the calibration measured "
                        "positions alone (default: held only by a full-pose calibration)")
    p.add_argument("--json", metavar="REPORT.json", default=None,
                   help="write the report as JSON: what was held (held, orientation_held); for a program each "
                        "target's correction or why it was left")
    g = p.add_argument_group("robot programs (PROGRAM a .script/.urscript, .src with its .dat, or .mod file)")
    g.add_argument("--tool", action="append", default=[], metavar="TOOL",
                   help="URScript: the TCP the program starts with, X,Y,Z,RX,RY,RZ (m, rotation vector in rad); "
                        "KRL: TOOL_DATA[N] as N=X,Y,Z,A,B,C (mm, deg), repeatable (default: none; the program's "
                        "own)")
    g.add_argument("--base", action="append", default=[], metavar="N=X,Y,Z,A,B,C",
                   help="KRL: BASE_DATA[N] (mm, deg; in the robot base frame), repeatable (default: none; the "
                        "program's own)")
    g.add_argument("--config", metavar="$config.dat",
                   help="KRL: a file with TOOL_DATA[n] = {...} and BASE_DATA[n] = {...} assignments")
    g.add_argument("--extrapolate", action="store_true",
                   help="correct targets outside what the calibration saw too (default: leave them as written)")


def _values(text: str, option: str, count: int = 6) -> np.ndarray:
    try:
        v = np.array([float(x) for x in text.split(",")])
    except ValueError:
        raise InputError(f"{option} {text}: expected {count} numbers separated by commas") from None
    if len(v) != count or not np.isfinite(v).all():
        raise InputError(f"{option} {text}: expected {count} finite numbers separated by commas")
    return v


def _numbered(items: list[str], option: str) -> dict[str, np.ndarray]:
    from ..programs._krl import frame_of
    out = {}
    for item in items:
        key, sep, rest = item.partition("=")
        if not sep or not key.strip().isdigit():
            raise InputError(f"{option} {item}: expected N=X,Y,Z,A,B,C (N the TOOL_DATA or BASE_DATA number; mm, "
                             "deg)")
        out[key.strip()] = frame_of(_values(rest, option))
    return out


def read_program(path: str, language: str, robot, args):
    """The program at ``path`` for ``robot``, with the frames the options give."""
    from ..programs import _krl as krl
    from ..programs import _rapid as rapid
    from ..programs import _urscript as urscript
    from ..programs._program import frame, rotvec_matrix

    tools = getattr(args, "tool", []) or []
    bases = getattr(args, "base", []) or []
    config = getattr(args, "config", None)
    if language != "krl" and (bases or config):
        raise InputError(f"--base and --config are KRL's; a {language} program names its frames itself", file=path)
    if language == "urscript":
        if len(tools) > 1:
            raise InputError("--tool: a URScript program starts with one TCP", file=path)
        tcp = None
        if tools:
            v = _values(tools[0], "--tool")
            tcp = frame(v[:3], rotvec_matrix(v[3:]))
        return urscript.read(path, robot.prismatic, tcp)
    if language == "krl":
        return krl.read(path, robot.prismatic, _numbered(tools, "--tool"), _numbered(bases, "--base"), config)
    if tools:
        raise InputError("--tool: a RAPID module declares its tooldata", file=path)
    return rapid.read(path, robot.prismatic)


def outputs_of(out: str, language: str) -> list[str]:
    """The files a filtered program of ``language`` is written to (KRL: the ``.src`` and its ``.dat``)."""
    return [out, str(Path(out).with_suffix(".dat"))] if language == "krl" else [out]


def run_program(args, language: str) -> int:
    """The program form of compensate."""
    from ..programs._filter import filter_program
    from ..programs._program import language_of
    from ..result import load_calibration
    from ..runtime._files import atomic_write

    out_lang = language_of(args.out)
    if out_lang != language:
        raise InputError(f"--out {args.out}: the filtered program is a {language} program like {args.targets}; "
                         f"give it the same file type ({Path(args.targets).suffix})")
    if args.position_only and args.hold_orientation:
        raise InputError("--position-only and --hold-orientation contradict each other; give one")
    outs = outputs_of(args.out, language)
    program_files = outputs_of(args.targets, language)
    check_outputs({**{f"--out {Path(o).suffix}": o for o in outs}, "--json": args.json},
                  [args.cal, *program_files, args.config], args.force)
    cal = load_calibration(args.cal, terms=user_terms(args))
    cal.model.jit = False           # a program's targets are few: CasADi's virtual machine beats compiling
    program = read_program(args.targets, language, cal.model.robot, args)
    if not program.targets:
        raise InputError("has no targets this filter reads (joint lists, poses, declared points)", file=args.targets)
    orientation = False if args.position_only else True if args.hold_orientation else None
    result = filter_program(cal, program, orientation=orientation, tolerance_mm=args.tolerance_mm,
                            max_change_deg=args.max_change_deg, max_deg_per_mm=args.max_deg_per_mm,
                            extrapolate=args.extrapolate)
    texts = result.texts()
    sources = list(program.files)
    for src, dst in zip(_ordered(sources, language), outs):
        atomic_write(dst, texts[src], overwrite=args.force)
    if args.json:
        write_json(args.json, result.to_dict(), args.force)
    print(result.summary(), file=human_stream(args.json))
    print(f"filtered program -> {', '.join(outs)}", file=human_stream(args.json))
    return 0


def _ordered(sources: list[str], language: str) -> list[str]:
    """The program's files in the order of :func:`outputs_of` (KRL: the .src, then the .dat)."""
    if language != "krl":
        return sources
    src = [s for s in sources if s.lower().endswith(".src")]
    dat = [s for s in sources if not s.lower().endswith(".src")]
    return src + dat


def add_measurement_program(p) -> None:
    """plan-poses' options of the measurement run as a program."""
    g = p.add_argument_group("the measurement run as a robot program")
    g.add_argument("--program", metavar="RUN.script|.src|.mod",
                   help="also write the selected poses as a program (URScript, KRL .src with its .dat, RAPID .mod) "
                        "that moves to each with a joint move and waits for the measurement; the poses, and "
                        "SELECTED.csv, in an order of short joint moves (no needless wrist turns)")
    g.add_argument("--wait-s", type=float_in(0, math.inf), default=2.0, metavar="S",
                   help="with --program: wait this long at each pose for the measurement (default: %(default)g s)")
    g.add_argument("--handshake", metavar="OUT,IN",
                   help="with --program: at each pose set digital output OUT and wait for input IN (the "
                        "measurement done), then clear OUT and wait for IN to fall, instead of --wait-s")


def measurement_outputs(args) -> dict[str, str]:
    """The files --program writes (checked with the command's other outputs), by option."""
    from ..programs._program import language_of

    if not args.program:
        if args.handshake:
            raise InputError("--handshake is for --program")
        return {}
    language = language_of(args.program)
    if language is None:
        raise InputError("--program: a .script, .urscript, .src or .mod file (its type is the language)",
                         file=args.program)
    return {f"--program {Path(o).suffix}": o for o in outputs_of(args.program, language)}


def write_measurement_program(args, values, prismatic) -> None:
    """The measurement run of ``values`` (rows in visiting order, the files' units) as the program of
    ``--program``."""
    from ..programs import _krl as krl
    from ..programs import _rapid as rapid
    from ..programs import _urscript as urscript
    from ..programs._program import language_of
    from ..runtime._files import atomic_write

    language = language_of(args.program)
    handshake = None
    if args.handshake:
        try:
            out, inp = (int(x) for x in args.handshake.split(","))
        except ValueError:
            raise InputError(f"--handshake {args.handshake}: expected OUT,IN (two signal numbers)") from None
        handshake = (out, inp)
    name = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in Path(args.program).stem) or "run"
    if not name[0].isalpha():
        name = "run_" + name
    if language == "krl":
        src, dat = krl.measurement_program(name, values, prismatic, args.wait_s, handshake)
        atomic_write(args.program, src, overwrite=args.force)
        atomic_write(str(Path(args.program).with_suffix(".dat")), dat, overwrite=args.force)
    elif language == "rapid":
        atomic_write(args.program, rapid.measurement_program(name, values, prismatic, args.wait_s, handshake),
                     overwrite=args.force)
    else:
        atomic_write(args.program, urscript.measurement_program(name, values, prismatic, args.wait_s, handshake),
                     overwrite=args.force)
