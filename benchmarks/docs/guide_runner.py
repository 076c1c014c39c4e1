"""Run docs/guide.md top to bottom, as written, and check what it quotes.

The guide is read as a sequence of fenced blocks and marker comments, in
document order, and followed in one fresh folder that holds a link to the
repository's ``problems/`` (the guide's paths are relative to the repository
root):

- a ```` ```sh ```` block runs: its lines, as one bash script with ``set -e``
  (so ``D=...`` on one line serves the next), each command must exit 0.
  ``casadical`` is this checkout's package (``python -m casadical``).
- a ```` ```text ```` block never runs: synopses with placeholders
  (``CAL.json TARGETS.csv``), install lines, error messages shown as
  examples. tests/docs/test_commands_in_docs.py still parses every ``casadical`` line in it.
- a ```` ```toml ```` block whose first line is a comment naming a file,
  ``# NAME.toml: ...``, is written to NAME.toml before the next ``sh``
  block runs (the guide's mapping files); other ``toml`` blocks are examples.
- a fence without a language right after an ``sh`` block (only prose between)
  quotes that block's output: its text must occur in what the block printed
  (stdout and stderr together), in order, where ``...`` stands for anything
  (an elided part of a line, or elided lines) and line breaks and runs of
  spaces match any whitespace, so a long line may be wrapped in the guide.
- a comment ``<!-- check: lines of FILE -->`` before a Markdown table or a
  fence: every line of it (but a table's header and ``...`` lines) must be a
  line of FILE, a file an earlier step wrote (the export table).

A quoted figure matches a printed one to a tolerance no CPU changes (one unit
of its last digit, or a thousandth of it, at most ten units of its last digit;
a count exactly: ``figures.py`` says why); words must be as quoted.
- ``python`` blocks are not run (fragments that continue the text).

``python benchmarks/docs/guide_runner.py`` runs it and prints each step with its
time; ``tests/docs/test_guide.py`` is the test.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from figures import Quote, same_line

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "guide.md"

_FENCE = re.compile(r"^```([A-Za-z]*)[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)
_CHECK = re.compile(r"<!--\s*check:\s*lines of\s+(\S+)\s*-->")
_TOML_NAME = re.compile(r"^#\s*([\w./-]+\.toml)\s*:")


@dataclass
class Step:
    """One unit of the guide, in document order."""

    kind: str            # "sh", "toml", "output", "lines"
    line: int            # line of the guide where it starts (1-based)
    text: str
    target: str = ""     # toml: file to write; lines: file to compare with
    outputs: list = field(default_factory=list)   # sh: the output blocks that quote it


def parse(text: str) -> list[Step]:
    """The guide's steps: sh blocks (with the output blocks quoting them), named toml blocks, line checks."""
    events = [(m.start(), "fence", m) for m in _FENCE.finditer(text)]
    events += [(m.start(), "check", m) for m in _CHECK.finditer(text)]
    events.sort(key=lambda e: e[0])
    steps: list[Step] = []
    last_sh: Step | None = None       # the sh block an untagged fence right after it quotes
    check: str | None = None          # a pending "check: lines of FILE"
    for pos, kind, m in events:
        line = text.count("\n", 0, pos) + 1
        if kind == "check":
            rest = text[m.end():]
            table = re.match(r"[ \t]*\n+((?:\|.*\|[ \t]*\n)+)", rest)
            if table:             # a Markdown table right after the marker
                steps.append(Step("lines", line, table.group(1), target=m.group(1)))
            else:                 # the next fence
                check = m.group(1)
            last_sh = None
            continue
        lang, body = m.group(1).lower(), m.group(2)
        if check is not None:
            steps.append(Step("lines", line, body, target=check))
            check, last_sh = None, None
        elif lang == "sh":
            last_sh = Step("sh", line, body)
            steps.append(last_sh)
        elif lang == "" and last_sh is not None:
            last_sh.outputs.append(Step("output", line, body))
        else:
            last_sh = None
            name = _TOML_NAME.match(body.lstrip().splitlines()[0]) if lang == "toml" and body.strip() else None
            if name:
                steps.append(Step("toml", line, body, target=name.group(1)))
    return steps


def quoted_pattern(quoted: str) -> Quote:
    """What a quoted output must match (``.search(printed)``): ``...`` any text, whitespace any whitespace, a
    figure one within its tolerance (figures.py)."""
    return Quote(quoted)


def table_lines(block: str) -> list[str]:
    """The lines of a quoted table or block to look for (no header, separator or ``...``)."""
    lines = [ln.rstrip() for ln in block.splitlines() if ln.strip() and ln.strip() != "..."]
    if lines and lines[0].startswith("|") and len(lines) > 1 and re.fullmatch(r"\|[-:| ]+\|", lines[1]):
        lines = lines[2:]
    return lines


def check_output(out: Step, printed: str) -> bool:
    """Whether a quoted output block occurs in what its sh block printed (``...`` = anything)."""
    return quoted_pattern(out.text).search(printed)


def check_lines(step: Step, folder: Path) -> str | None:
    """None if every quoted line of a ``check: lines of FILE`` step is a line of FILE in ``folder`` (its figures
    within their tolerance), else why not."""
    path = Path(folder) / step.target
    if not path.is_file():
        return f"{step.target} was not written by the steps before"
    text = path.read_text(encoding="utf-8")
    have = [ln.rstrip() for ln in text.splitlines()]
    missing = [ln for ln in table_lines(step.text) if not any(same_line(ln, h) for h in have)]
    if missing:
        return (f"lines quoted from {step.target} that it does not hold ({len(missing)}):\n" + "\n".join(missing)
                + f"\n--- {step.target}:\n{_clip(text)}")
    return None


def _clip(text: str, head: int = 1500, tail: int = 4500) -> str:
    if len(text) <= head + tail:
        return text
    return text[:head] + f"\n[... {len(text) - head - tail} characters ...]\n" + text[-tail:]


class GuideFailure(AssertionError):
    """A step of the guide failed or a quoted output differs."""


def _shim(folder: Path) -> dict:
    """Environment whose ``casadical`` is this checkout's, run by this Python."""
    bindir = folder / ".bin"
    bindir.mkdir()
    exe = bindir / "casadical"
    exe.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m casadical "$@"\n')
    exe.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env.setdefault("CASADICAL_JIT", "0")
    env["PYTHONUNBUFFERED"] = "1"     # warnings and output interleaved as in a terminal
    return env


@dataclass
class StepResult:
    step: Step
    seconds: float
    output: str


def run(folder: str | Path | None = None, guide: str | Path = GUIDE, verbose: bool = False,
        keep_going: bool = False) -> tuple[list[StepResult], list[str]]:
    """Follow the guide in ``folder`` (a new temporary folder if None).

    Raises GuideFailure at the first failure, or with ``keep_going`` collects the failures and goes on.
    Returns the sh steps run (with their time and output) and the failures.
    """
    text = Path(guide).read_text(encoding="utf-8")
    steps = parse(text)
    if folder is None:
        folder = Path(tempfile.mkdtemp(prefix="casadical-guide-"))
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if any(folder.iterdir()):
        raise GuideFailure(f"{folder} is not empty: the guide starts in a fresh folder")
    (folder / "problems").symlink_to(ROOT / "problems")
    env = _shim(folder)
    done, failures = [], []

    def fail(message: str) -> None:
        if not keep_going:
            raise GuideFailure(message)
        failures.append(message)
        if verbose:
            print("FAILED: " + message, flush=True)

    name = Path(guide).name
    for step in steps:
        where = f"{name}, line {step.line}"
        if step.kind == "toml":
            (folder / step.target).write_text(step.text)
        elif step.kind == "lines":
            problem = check_lines(step, folder)
            if problem:
                fail(f"{where}: {problem}")
        elif step.kind == "sh":
            t0 = time.perf_counter()
            proc = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", step.text], cwd=folder, env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            dt = time.perf_counter() - t0
            if verbose:
                first = step.text.strip().splitlines()[0]
                print(f"{where}: {dt:6.1f} s  {first[:100]}", flush=True)
            if proc.returncode != 0:
                fail(f"{where}: the block exits with {proc.returncode}:\n{step.text}\n"
                     f"--- its output:\n{_clip(proc.stdout)}")
            for out in step.outputs:
                if not check_output(out, proc.stdout):
                    fail(f"{name}, line {out.line}: the output quoted there is not what the block of line "
                         f"{step.line} prints.\n--- quoted:\n{out.text}\n--- printed:\n{_clip(proc.stdout)}")
            done.append(StepResult(step, dt, proc.stdout))
    return done, failures


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--guide", default=str(GUIDE))
    ap.add_argument("--folder", help="run here (must be empty or new; default: a temporary folder, kept)")
    ap.add_argument("--keep-going", action="store_true", help="report every failure, not only the first")
    args = ap.parse_args()
    t0 = time.perf_counter()
    try:
        _, failures = run(args.folder, args.guide, verbose=True, keep_going=args.keep_going)
    except GuideFailure as e:
        print(f"FAILED: {e}", file=sys.stderr)
        sys.exit(1)
    if failures:
        print(f"{len(failures)} failure(s)", file=sys.stderr)
        sys.exit(1)
    print(f"the guide ran top to bottom in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
