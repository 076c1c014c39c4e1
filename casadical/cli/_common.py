"""What every command shares: output checks, option types, progress and status lines.

Commands live in the modules of this package, one pattern each: a
``register(sub)`` that adds the command's parser and sets ``func`` to the
function that runs it. They import from here, never from each other.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any, Iterable, TextIO

from ..errors import InputError
from ..runtime._files import EXISTS, atomic_write

STDOUT = "-"


# --- outputs -----------------------------------------------------------------------


#: outputs that ``-`` sends to standard output (text written by :func:`write_text`); any other output is a file
STDOUT_OPTIONS = frozenset({"--json", "--html", "--urdf", "--table", "--markdown"})


def check_outputs(outputs: dict[str, str | None], inputs: Iterable[str | None], force: bool) -> None:
    """Refuse, before any work, outputs that would lose something the user has.

    Parameters
    ----------
    outputs : dict
        Option name -> path (None or ``-`` for options not given / stdout).
    inputs : iterable of str
        Every file the command reads (robot or calibration file included).
    force : bool
        Existing outputs may be replaced (never an input).

    Raises
    ------
    InputError
        Two outputs go to standard output, an output that is a file is ``-`` (:data:`STDOUT_OPTIONS`), an output
        is an input, two outputs are one file, an output exists
        (without ``force``), its folder does not exist or no file can be
        made in it.
    """
    to_stdout = [option for option, path in outputs.items() if path == STDOUT]
    for option in to_stdout:
        if option not in STDOUT_OPTIONS:
            raise InputError(f"{option} -: this output is a file, and only {', '.join(sorted(STDOUT_OPTIONS))} can "
                             "go to standard output; give a file name (./- for a file named '-')")
    if len(to_stdout) > 1:
        raise InputError(f"{' and '.join(to_stdout)} both name standard output ('-'); one output at most can go "
                         "there")
    ins = [Path(i) for i in inputs if i and i != STDOUT and Path(i).exists()]
    seen: dict[Path, str] = {}
    for option, path in outputs.items():
        if path is None or path == STDOUT:
            continue
        out = Path(path)
        key = out.resolve()
        if key in seen:
            raise InputError(f"{option} and {seen[key]} name the same file; give each output its own name",
                             file=path)
        seen[key] = option
        if out.exists():
            if any(_same(out, i) for i in ins):
                raise InputError(f"{option} names an input file; choose another output name "
                                 "(casadical never writes over its inputs, even with --force)", file=path)
            if out.is_dir():
                raise InputError(f"{option} names a folder, not a file", file=path)
            if not force:
                raise InputError(EXISTS, file=path)
        if not out.parent.exists():
            raise InputError(f"folder {str(out.parent)!r} does not exist", file=path)
        _check_writable(out, path)


def _check_writable(out: Path, path: str) -> None:
    """A file can be made in the output's folder (tried, then removed): an output that cannot be written
    fails before the work, not after the other outputs."""
    import tempfile

    try:
        fd, probe = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".part", dir=out.parent)
    except OSError as e:
        raise InputError(f"cannot write in folder {str(out.parent)!r}: {e.strerror or e}", file=path) from e
    os.close(fd)
    os.unlink(probe)


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def fold_long_lines(text: str, longer_than: int = 180, width: int = 160) -> str:
    """``text`` with every line longer than ``longer_than`` characters wrapped at ``width`` (a hanging indent):
    what a terminal shows stays readable; tables narrower than that are left as they are."""
    import textwrap

    out = []
    for line in text.splitlines():
        if len(line) <= longer_than:
            out.append(line)
            continue
        lead = line[:len(line) - len(line.lstrip())]
        out += textwrap.wrap(line, width=width, subsequent_indent=lead + "    ", break_on_hyphens=False)
    return "\n".join(out)


def human_stream(*outputs: str | None) -> TextIO:
    """Where a command's lines for people go: standard error when one of its ``outputs`` is standard output
    (``-``: that stream then holds the output alone, e.g. exactly one JSON document), else standard output."""
    return sys.stderr if STDOUT in outputs else sys.stdout


def write_text(path: str, text: str, force: bool) -> None:
    """Write a text output atomically (``-`` prints it)."""
    if path == STDOUT:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
        return
    atomic_write(path, text, overwrite=force)


def write_json(path: str, doc: Any, force: bool) -> None:
    """Write a JSON document atomically (``-`` prints it); NaN and infinities become null."""
    write_text(path, json.dumps(finite(doc), indent=1, allow_nan=False, default=json_default), force)


def finite(doc: Any) -> Any:
    """``doc`` with every non-finite float replaced by None (JSON has no NaN or infinity)."""
    if isinstance(doc, float):
        return doc if math.isfinite(doc) else None
    if isinstance(doc, dict):
        return {k: finite(v) for k, v in doc.items()}
    if isinstance(doc, (list, tuple)):
        return [finite(v) for v in doc]
    return doc


def json_default(x):
    """numpy scalars and arrays in JSON."""
    import numpy as np
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"cannot write {type(x).__name__} to JSON")


# --- option types (argparse turns their ValueError/ArgumentTypeError into a usage error) ----


def _number(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def int_at_least(lo: int):
    """Option type: a whole number >= ``lo``."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"must be at least {lo}, got {v}")
        return v
    parse.__name__ = f"whole number >= {lo}"
    return parse


def float_in(lo: float, hi: float, lo_open: bool = True, hi_open: bool = True):
    """Option type: a finite number within (lo, hi) (ends open or closed)."""
    def parse(text: str) -> float:
        v = _number(text)
        if (v <= lo if lo_open else v < lo) or (v >= hi if hi_open else v > hi):
            a, b = ("(" if lo_open else "["), (")" if hi_open else "]")
            raise argparse.ArgumentTypeError(f"must be in {a}{lo:g}, {hi:g}{b}, got {v:g}")
        return v
    parse.__name__ = "number"
    return parse


def add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true",
                   help="replace output files that exist (never an input file)")


def add_terms(p: argparse.ArgumentParser) -> None:
    """``--terms FILE``: causes of the user's own (docs/formats.md, "Terms file")."""
    p.add_argument("--terms", metavar="FILE", default=None,
                   help="a terms file (TOML): causes of your own, named in --model like any term "
                        "(kinematic+axis_wobble); see 'Terms file' in docs/formats.md")


def user_terms(args) -> list:
    """The causes of one's own of a command's ``--terms FILE`` (none without it), read and checked once."""
    if getattr(args, "terms", None) is None:
        return []
    if not hasattr(args, "_user_terms"):
        from ..terms._definitions import read_terms_file
        args._user_terms = read_terms_file(args.terms)
    return args._user_terms


def add_quiet(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", "-q", action="store_true", help="no progress output on stderr")


def add_json(p: argparse.ArgumentParser, what: str, required: bool = False) -> None:
    """``--json PATH``: the command's result as JSON (``-`` or no PATH: standard output)."""
    if required:
        p.add_argument("--json", required=True, metavar="OUT.json", help=f"write {what} as JSON")
    else:
        p.add_argument("--json", nargs="?", const=STDOUT, default=None, metavar="OUT.json",
                       help=f"write {what} as JSON to OUT.json ('-' or nothing: standard output)")


def add_checks(p: argparse.ArgumentParser, mismatch: bool = True) -> None:
    """The overrides of the plausibility checks of poses (:mod:`casadical.data._checks`).

    ``--allow-mismatch`` is one of them on every command (``mismatch`` is
    accepted for the callers that asked for it when it was ``predict``'s
    alone).
    """
    g = p.add_argument_group("plausibility checks of the poses (each is an error unless overridden)")
    g.add_argument("--allow-outside-limits", action="store_true",
                   help="accept joint readings beyond the robot's min_deg/max_deg (a warning)")
    g.add_argument("--angles-are-degrees", action="store_true",
                   help="the joint readings are degrees although all lie within +-6.3 (which looks like radians)")
    g.add_argument("--positions-are-mm", action="store_true",
                   help="the positions are mm even though their spread does not match the robot's")
    g.add_argument("--allow-mismatch", action="store_true",
                   help="accept measured poses the model misses far beyond what it can mean, with its base pose "
                        "fitted: the nominal model by more than 5%% of the robot's reach, a calibration by more "
                        "than 100 times its own error (a warning)")


def add_row_spacing(p: argparse.ArgumentParser) -> None:
    """``--row-spacing-s``: the rows of a file without ``time_s`` are in time order at this spacing."""
    p.add_argument("--row-spacing-s", type=float_in(0, math.inf), metavar="SECONDS",
                   help="the poses of files without a time_s column were measured in row order, this many seconds "
                        "apart (time_s = row x SECONDS; split's source_row gives the row): what a drift needs. "
                        "Without it such files have no time, and no drift is fitted")


def add_session_tool(p: argparse.ArgumentParser) -> None:
    """``--session-tool``: with several sessions, each after the first has its own tool offset."""
    p.add_argument("--session-tool", action="store_true",
                   help="with several sessions: each session after the first has its own tool offset too (the "
                        "probe was re-mounted between them)")


def add_fixture(p: argparse.ArgumentParser) -> None:
    """``--fixture FILE``: the known geometry of the points the rows touch (docs/formats.md section 11)."""
    p.add_argument("--fixture", metavar="FILE", default=None,
                   help="a fixture file (TOML): touched points at known coordinates in a fixture's own frame (two "
                        "sockets 50 mm apart), whose pose in each session is estimated; see 'What the tool "
                        "touches' in docs/formats.md")


def fixtures(args) -> list:
    """The fixtures of a command's ``--fixture FILE`` (none without it), read and checked once."""
    if getattr(args, "fixture", None) is None:
        return []
    if not hasattr(args, "_fixtures"):
        from ..rows import read_fixture_file
        args._fixtures = read_fixture_file(args.fixture)
    return args._fixtures


def add_levelled(p: argparse.ArgumentParser) -> None:
    """``--levelled`` / ``--not-levelled``: whether the instrument's z is up (the robot file's gravity is checked
    against it; by default where every session's base pose agrees on one vertical)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--levelled", action="store_true", default=None,
                   help="the instrument was levelled (its z up): warn where the robot file's gravity is more than 5 "
                        "deg from its down as the fitted base pose puts it, and say the direction to give (by "
                        "default checked where two sessions or more agree on one vertical)")
    g.add_argument("--not-levelled", dest="levelled", action="store_false", default=None,
                   help="the instrument was not levelled: no check of the robot file's gravity")


def timed(data, args):
    """``data`` as the command's options make it: with the fixtures of ``--fixture``, and with times from its rows
    if ``--row-spacing-s`` was given and it has no ``time_s``."""
    if fixtures(args):
        data = data.with_fixtures(fixtures(args))
    spacing = getattr(args, "row_spacing_s", None)
    if spacing is None:
        return data
    if "time_s" in data.columns:
        import warnings

        from ..errors import DataWarning
        warnings.warn(f"{data.path}: has a time_s column, whose times are used; --row-spacing-s applies to files "
                      "without one", DataWarning, stacklevel=2)
        return data
    return data.with_row_times(spacing)


def add_urdf_chain(p: argparse.ArgumentParser) -> None:
    """``--urdf-base``, ``--urdf-tip``, ``--urdf-tool``: which chain of a URDF robot file is read."""
    g = p.add_argument_group("URDF robot (ROBOT a .urdf file; defaults: the root link, the deepest leaf, its "
                             "origin)")
    g.add_argument("--urdf-base", metavar="LINK", help="link the robot stands on; positions are in its frame")
    g.add_argument("--urdf-tip", metavar="LINK", help="link whose frame carries the measured point")
    g.add_argument("--urdf-tool", type=_triple, metavar="X,Y,Z",
                   help="measured point in the tip link's frame, metres (default: its origin)")


def _triple(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"three numbers separated by commas (metres), got {text!r}")
    return tuple(_number(x) for x in parts)  # type: ignore[return-value]


def robot_from_args(spec: str, args):
    """The robot ``spec`` names (built-in, TOML or URDF), with the chain options of :func:`add_urdf_chain`."""
    from ..loading import load_robot

    return load_robot(spec, tip=args.urdf_tip, base=args.urdf_base, tool=args.urdf_tool)


def robot_or_calibration(spec: str, args):
    """A calibration (``spec`` ends in ``.json``; the URDF chain options are refused) or a robot."""
    if not spec.lower().endswith(".json"):
        return robot_from_args(spec, args)
    given = [f"--urdf-{k}" for k in ("base", "tip", "tool") if getattr(args, f"urdf_{k}", None) is not None]
    if given:
        raise InputError(f"{spec}: {', '.join(given)} {'chooses' if len(given) == 1 else 'choose'} the chain of a "
                         "URDF robot; a calibration JSON already holds its robot (drop the option)")
    from ..result import load_calibration

    return load_calibration(spec, terms=user_terms(args))


def check_options(args) -> dict:
    """Keyword overrides of :func:`casadical.data._checks.check_poses` from the options of :func:`add_checks`."""
    return {"allow_outside_limits": args.allow_outside_limits, "angles_are_degrees": args.angles_are_degrees,
            "positions_are_mm": args.positions_are_mm, "allow_mismatch": args.allow_mismatch}


# --- what a calibration holds of its session -----------------------------------------

def warn_session_terms(cal, data, cal_file: str) -> None:
    """A calibration holding terms of its measurement session(s), applied to poses not named as of one of them:
    a warning that says which terms and how to take the calibration to another session."""
    import warnings

    from ..errors import DataWarning

    terms = [t.spec() for t in cal.model.terms if t.session and t.name not in ("sessions", "gp_compensator")]
    named = data.sessions is not None and set(data.session_names) <= set(cal.sessions)
    if terms and not named:
        warnings.warn(f"{data.path}: {cal_file} holds {', '.join(terms)}, of the measurement session it was fitted "
                      "on; it is applied to these poses as if they were of that session (with their own time_s). "
                      f"If they are not, take the calibration to them first: calibrate {cal_file} "
                      f"{data.path} --model base (which drops what belongs to a session)", DataWarning, stacklevel=2)


def warn_session_frame(sessions: list[str], data, holder: str) -> None:
    """A calibration of several ``sessions`` applied to poses with no ``session`` column: they are taken in the
    first session's measurement frame; a warning that says so and how to choose another (before the work: a file
    of another session then misses by metres). ``holder``: what holds the sessions, for the message."""
    import warnings

    from ..errors import DataWarning

    if len(sessions) > 1 and data.sessions is None:
        warnings.warn(f"{data.path}: has no 'session' column; {holder} holds the sessions {', '.join(sessions)}, so "
                      f"its rows are taken in the measurement frame of the first, {sessions[0]}; add a 'session' "
                      "column to use another's", DataWarning, stacklevel=2)


def compensator_line(cal, data) -> str:
    """Where the GP compensator (one per session) applied, in words ('' without one)."""
    from ..calibration._per_session import gp_compensator_coverage

    known, total = gp_compensator_coverage(cal, data)
    if not total:
        return ""
    return (f"GP compensator (a Gaussian process of the residual, one per session): applied at {known} of {total} "
            f"poses (at least half of its correction); at the other {total - known} it knows the residual less (too "
            "far from the poses it learnt from), its correction shrinks toward nothing and the physical model stands "
            "nearly alone")


# --- progress ------------------------------------------------------------------------


class Status:
    """Progress for the terminal (stderr): lines and bars with an ETA, silent with ``--quiet``.

    Bars are tqdm's: a well-kept library that handles terminals, pipes and
    rates; the library itself only calls the callbacks it is given.
    """

    def __init__(self, quiet: bool = False):
        self.quiet = quiet

    def line(self, text: str) -> None:
        if not self.quiet:
            print(text, file=sys.stderr, flush=True)

    def timed_line(self, width: int = 160):
        """A line printer that prefixes the time since it was made (for steps of unknown number); a long line is
        wrapped at ``width`` characters."""
        t0 = time.perf_counter()

        def say(text: str) -> None:
            line = f"[{time.perf_counter() - t0:6.1f} s] {text}"
            if len(line) > width:
                import textwrap

                lead = " " * (11 + len(text) - len(text.lstrip()) + 4)
                line = "\n".join(textwrap.wrap(line, width, subsequent_indent=lead, break_on_hyphens=False))
            self.line(line)
        return say

    @contextlib.contextmanager
    def slow(self, text: str, after_s: float = 1.0):
        """A phase that says ``text`` only if it lasts longer than ``after_s`` (then also how long it took): a
        quick command stays quiet (and an error in it stays one line)."""
        if self.quiet:
            yield
            return
        t0 = time.perf_counter()
        said = threading.Event()

        def tell() -> None:
            said.set()
            self.line(text)
        timer = threading.Timer(after_s, tell)
        timer.daemon = True
        timer.start()
        try:
            yield
        finally:
            timer.cancel()
        if said.is_set():
            self.line(f"  done in {time.perf_counter() - t0:.1f} s")

    def bar(self, total: int | None, desc: str, unit: str = "it"):
        from tqdm.auto import tqdm
        return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, disable=self.quiet,
                    leave=False, dynamic_ncols=True)
