"""The command lines the README and docs/ show are ones the command line accepts.

Fenced examples must parse as written (an optional part in ``[...]``
parses with its brackets removed); every ``--option`` a synopsis names,
in a fenced block or an inline ``casadical ...`` span, must be an option of
that command. An option renamed in the code and not in the docs fails here.
"""

from __future__ import annotations

import argparse
import re
import shlex
from pathlib import Path

import pytest

from casadical.cli import UsageError, build_parser

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
PARSER = build_parser()
COMMANDS = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction)).choices


def _commands(text: str, fenced: bool) -> list[str]:
    """``casadical COMMAND ...`` lines of fenced blocks (continuations joined), or of inline code spans."""
    if fenced:
        lines = [line for block in re.findall(r"```[a-z]*\n(.*?)```", text, re.S)
                 for line in block.replace("\\\n", " ").splitlines()]
        pieces = [re.sub(r"\s+#.*$", "", p).strip() for line in lines for p in re.split(r"\s*&&\s*", line.strip())]
        # a shell prompt and environment settings before the command: "$ VAR=1 casadical ..."
        pieces = [re.sub(r"^(\$\s+)?(\w+=\S*\s+)*", "", p) for p in pieces]
    else:
        pieces = [m.replace("\\|", "|") for m in re.findall(r"`(casadical [^`]+)`", text)]
    return [p for p in pieces if len(p.split()) > 1 and p.split()[0] == "casadical" and p.split()[1] in COMMANDS]


def _cases(fenced: bool) -> list:
    return [pytest.param(cmd, id=f"{path.name}: {cmd[:60]}") for path in DOCS
            for cmd in _commands(path.read_text(encoding="utf-8"), fenced)]


@pytest.mark.parametrize("cmd", _cases(fenced=True))
def test_fenced_example_parses(cmd):
    args = shlex.split(re.sub(r"[\[\]]", " ", cmd))[1:]
    try:
        PARSER.parse_args(args)
    except UsageError as e:
        pytest.fail(f"{cmd}\n  -> {e}")


@pytest.mark.parametrize("cmd", _cases(fenced=True) + _cases(fenced=False))
def test_every_option_named_exists(cmd):
    name = cmd.split()[1]
    known = set(COMMANDS[name]._option_string_actions)
    named = set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", cmd))
    assert named <= known, f"{cmd}: not options of {name}: {sorted(named - known)}"


def test_the_docs_show_commands():
    """The collection itself works: the README's job and the command table of formats.md are found."""
    fenced = [c for p in DOCS for c in _commands(p.read_text(encoding="utf-8"), True)]
    inline = [c for p in DOCS for c in _commands(p.read_text(encoding="utf-8"), False)]
    assert any(c.startswith("casadical diagnose ur10 ") for c in fenced) and len(fenced) >= 30
    assert {c.split()[1] for c in inline} >= {"inspect", "calibrate", "diagnose", "compensate", "export", "study"}
