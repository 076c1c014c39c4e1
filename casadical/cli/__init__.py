"""The ``casadical`` command line.

Every command exits 0 on success and 2 with one line naming the file, row
and column at fault on bad input. Anything unexpected is one line too, with
a request to report it; ``--debug`` shows the traceback. Ctrl-C and SIGTERM
(or SIGHUP) stop any command with one line and exit 130 (143, 129); a
command's output files appear together when it succeeds, or none of them
(:func:`casadical.runtime._files.outputs_together`).

Each command lives in a module of this package with one pattern: a
``register(sub)`` that adds its parser and sets ``func``; shared helpers are
in :mod:`casadical.cli._common`.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
import warnings

from .. import __version__
from ..errors import CasadicalError, CasadicalWarning
from ..model._jitcache import announcing
from ..runtime import _interrupts as interrupts
from ..runtime._files import outputs_together
from ..runtime._interrupts import exit_code, handle_signals
from ..runtime._threads import evaluation_threads, limited_threads
from . import _cache as cache
from . import _calibrate as calibrate
from . import _compare as compare
from . import _compensate as compensate
from . import _data as data
from . import _diagnose as diagnose
from . import _export as export
from . import _iso9283 as iso9283
from . import _model as model
from . import _planning as planning
from . import _study as study
from ._common import Status

#: command modules, in the order ``--help`` lists them
COMMANDS = (model, calibrate, diagnose, compensate, iso9283, planning, compare, study, data, export, cache)

class UsageError(CasadicalError):
    """A command line that argparse rejects (unknown option, value out of its domain)."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (the usage itself is one ``--help`` away).

    A command may set ``complete_help`` on its parser: a function of the
    parser called once before its help is shown, to fill in what is costly
    to know when every command's parser is built (``compare`` imports every
    method to list them).
    """

    complete_help = None

    def format_help(self) -> str:
        if self.complete_help is not None:
            complete, self.complete_help = self.complete_help, None
            complete(self)
        return super().format_help()

    def error(self, message: str):  # type: ignore[override]
        # "casadical: error: " comes first: the prog once, as the command's name ("diagnose: ...")
        command = self.prog.removeprefix("casadical").strip()
        raise UsageError(f"{command + ': ' if command else ''}{message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(
        prog="casadical",
        description="Calibration of industrial robot arms: symbolic kinematic + compliance "
                    "models in CasADi, identification with IPOPT and Gauss-Newton, diagnosis and "
                    "pose planning.")
    ap.add_argument("--version", action="version", version=f"casadical {__version__}")
    ap.add_argument("--debug", action="store_true", help="show the full traceback of unexpected errors")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS:
        module.register(sub)
    for p in sub.choices.values():
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show the full traceback of unexpected errors")
    return ap


def _show_warning(message, category, filename, lineno, file=None, line=None):
    if issubclass(category, CasadicalWarning):
        print(f"casadical: warning: {message}", file=sys.stderr)
    else:
        print(f"casadical: warning: {category.__name__}: {message}", file=sys.stderr)


def _check_cache_settings() -> None:
    """A bad CASADICAL_JIT or CASADICAL_CACHE_MAX_MB is said before any work (casadi is imported only if set)."""
    if os.environ.get("CASADICAL_JIT") is not None or os.environ.get("CASADICAL_CACHE_MAX_MB") is not None:
        from ..model._jitcache import jit_setting, max_bytes
        jit_setting()
        max_bytes()


def main(argv: list[str] | None = None) -> int:
    """Run one command; its exit code (a signal after its outputs were in place: 128 + the signal, one line)."""
    code = _main(argv)
    late = interrupts.late_exit_code()
    if late is None:
        return code
    print(interrupts.late(), file=sys.stderr)
    return late


def _command_named(e: UsageError, ap: argparse.ArgumentParser, argv: list[str] | None) -> str:
    """An error of the top parser about a command's arguments (unrecognized ones) names that command and its help."""
    text = str(e)
    words = sys.argv[1:] if argv is None else argv
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    command = next((w for w in words if w in sub.choices), None)
    if command and text.startswith("unrecognized arguments"):
        return f"{command}: {text.replace('(see casadical --help)', f'(see casadical {command} --help)')}"
    return text


def _interrupted(e: KeyboardInterrupt) -> int:
    what = "interrupted" if exit_code(e) == 130 else f"stopped by {e.args[0] if e.args else 'a signal'}"
    print(f"casadical: {what}; no output was written", file=sys.stderr)
    return exit_code(e)


def _main(argv: list[str] | None) -> int:
    ap = build_parser()
    try:
        args = ap.parse_args(argv)
    except UsageError as e:
        print(f"casadical: error: {_command_named(e, ap, argv)}", file=sys.stderr)
        return 2
    if not getattr(args, "func", None):
        ap.print_help()
        return 2
    old = warnings.showwarning
    warnings.showwarning = _show_warning
    signals = interrupts.received()
    try:
        # SIGTERM takes Ctrl-C's path; every output of the command appears at its end, or none
        with handle_signals(), outputs_together():
            interrupts.checkpoint("work")
            evaluation_threads()     # a bad CASADICAL_EVAL_THREADS is said before any work, whatever the command
            _check_cache_settings()
            # small dense problems: one BLAS thread unless CASADICAL_THREADS says otherwise; a first run says
            # when it compiles the robot's model (seconds, once per machine)
            with limited_threads(), announcing(Status(getattr(args, "quiet", False)).line):
                return int(args.func(args) or 0)
    except CasadicalError as e:
        print(f"casadical: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        where = f"{e.filename}: " if e.filename else ""
        print(f"casadical: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
    except MemoryError:
        print("casadical: error: out of memory; use fewer poses or a machine with more memory",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        return _interrupted(e)
    except Exception as e:  # noqa: BLE001  (the last line of defence: one line, never a traceback)
        stop = interrupts.since(signals)
        if stop is not None:   # a signal that a library turned into its own error (Python wraps one in __set_name__)
            return _interrupted(stop)
        if args.debug:
            traceback.print_exc()
        text = str(e).strip().splitlines()[0] if str(e).strip() else ""
        print(f"casadical: internal error: {type(e).__name__}{': ' + text if text else ''}. This is a bug: "
              "please report it to the casadical developers with the command line"
              + ("" if args.debug else " and the output of the same command with --debug"), file=sys.stderr)
        return 3
    finally:
        warnings.showwarning = old


__all__ = ["COMMANDS", "UsageError", "build_parser", "main"]
