"""Regenerate (or check) every table the docs quote from a script, from that script's own output.

A quoted table in the docs sits between two comments that name it and the command it comes from:

    <!-- generated: ur10-heldout (python benchmarks/studies/study_ur10.py) -->
    | series | model | ... |
    |---|---|...|
    ...
    <!-- end generated -->

Each NAME is registered below (:data:`BLOCKS`): the job that prints it (:data:`JOBS`: a benchmark or
study script with its documented seeds and arguments, or ``casadical study``), and where in the job's
standard output the block is (the first table after a line that matches a pattern, or lines that match).
The docs' text is exactly what the script prints, so regenerating is copying, and checking is comparing.

Timings vary from run to run: the columns a block names as timings (``time (s)``, ``fit time``, ...)
are regenerated but never compared; a block whose every figure is a timing (``check=False``) is only
regenerated. Every other cell is compared at the precision it is printed with, to the tolerance of a figure
no CPU changes (``figures.py``: one unit of its last digit, or a thousandth of it; counts and words exactly).

Usage::

    python benchmarks/docs/regenerate_docs.py --list                  # blocks, jobs, where they are used
    python benchmarks/docs/regenerate_docs.py                         # run every job, rewrite the blocks that changed
    python benchmarks/docs/regenerate_docs.py --timings --jobs ur10   # rewrite its blocks, timings of this run too
    python benchmarks/docs/regenerate_docs.py --check                 # run every job, fail if a block differs
    python benchmarks/docs/regenerate_docs.py --check --jobs ur10 fullpose      # some jobs only
    python benchmarks/docs/regenerate_docs.py --save out/docs-runs    # keep each job's output there
    python benchmarks/docs/regenerate_docs.py --reuse out/docs-runs   # use saved outputs, run nothing

``tests/docs/test_generated.py`` checks the markers (fast) and, under ``pytest -m slow``, runs the
check job by job. All jobs take 21-30 minutes on 2 cores, hidden-effects 10 of them (load 1-8;
docs/benchmarks.md, "Docs that cannot drift", has the time of each); the guide itself is run by
``tests/docs/test_guide.py``.
"""

from __future__ import annotations

import argparse
import difflib
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from figures import same_line

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

BEGIN = re.compile(r"<!--\s*generated:\s*([\w.-]+)\s*\((.*?)\)\s*-->")
END = re.compile(r"<!--\s*end generated\s*-->")


@dataclass(frozen=True)
class Job:
    """Commands whose standard output holds blocks; ``{tmp}`` is a fresh folder of the run."""

    commands: tuple[tuple[str, ...], ...]
    minutes: float            # wall time measured on 2 cores at load 5-8 (for --list)
    note: str = ""

    @property
    def display(self) -> str:
        """The command as the docs' markers show it."""
        return " && ".join(shlex.join(a.replace("{tmp}", "out") for a in c) for c in self.commands)

    @property
    def scripts(self) -> list[Path]:
        """The repository scripts the job runs (for the marker check)."""
        return [ROOT / a for c in self.commands for a in c if a.endswith(".py")]


def _py(script: str, *args: str) -> tuple[str, ...]:
    """``python benchmarks/SCRIPT ARGS``: ``script`` is its path under benchmarks/ (``studies/study_ur10.py``)."""
    return ("python", f"benchmarks/{script}", *args)


def _study(protocol: str, *summary: str) -> tuple[tuple[str, ...], ...]:
    out = "{tmp}/" + protocol + ".parquet"
    return (("casadical", "study", protocol, "--out", out, "--workers", "2", "--quiet"),
            ("casadical", "study", "--summary", out, *summary))


JOBS: dict[str, Job] = {
    "ur10": Job((_py("studies/study_ur10.py"),), 0.2),
    "fullpose": Job((_py("studies/study_fullpose.py"),), 0.1),
    "fullpose-kc": Job((_py("studies/study_fullpose.py", "--model", "kinematic+compliance"),), 0.1),
    "papers": Job((_py("studies/study_papers.py"),), 3),
    "metaheuristics": Job((_py("studies/study_metaheuristics.py"),), 2.5),
    "planning": Job((_py("studies/study_planning.py", "--out-dir", "{tmp}"),), 4,
                    "the plots go to a temporary folder; regenerate docs/img with the script's default"),
    "study-poses": Job(_study("poses-ys100", "--baseline", "KM"), 2.5),
    "study-ca": Job(_study("ca-ys100"), 2),
    "study-metaheuristics": Job(_study("metaheuristics-ys100"), 1.7),
    "study-ga": Job(_study("ga-ys100", "--baseline", "KM"), 3.7),
    "guide": Job((_py("docs/guide_figures.py"),), 0.4),
    "singular": Job((_py("studies/study_singular.py"),), 0.1),
    "next-poses": Job((_py("studies/study_next_poses.py"),), 1.8),
    "hidden-effects": Job((_py("studies/study_hidden_effects.py"),), 10),
    "open-world": Job((_py("studies/study_open_world.py"),), 2),
    "compensator": Job((_py("studies/study_compensator.py"),), 2),
    "touch-peer": Job((_py("studies/study_touch_peer.py"),), 0.5),
}


@dataclass(frozen=True)
class Block:
    """Where a block is in its job's output: the first Markdown table after lines that match the patterns
    ``after``, in this order. ``timing``: column headers whose cells are not compared; ``check=False``:
    the whole block is timings, regenerated (``--timings``) and never compared.
    """

    job: str
    after: tuple[str, ...] = ()
    timing: tuple[str, ...] = ()
    check: bool = True


def _summary(job: str) -> Block:
    return Block(job, (r"^study .*: \d+ repetitions",), timing=("fit time, median (s)",))


BLOCKS: dict[str, Block] = {
    # docs/studies.md
    "studies-poses-ys100": _summary("study-poses"),
    "studies-ca-ys100": _summary("study-ca"),
    "studies-metaheuristics-ys100": _summary("study-metaheuristics"),
    "studies-ga-ys100": _summary("study-ga"),
    # docs/ur10.md
    "ur10-heldout": Block("ur10", (r"^Held-out position error",),
                          timing=("calibrate() first / median", "solve (median)")),
    "ur10-compliance-effect": Block("ur10", (r"^Effect of compliance",)),
    "ur10-stiffness": Block("ur10", (r"^Identified joint compliance",)),
    "ur10-torques": Block("ur10", (r"^Gravity torques",)),
    "fullpose-kinematic": Block("fullpose", (r"^ranges over the seeds",)),
    "fullpose-compliance": Block("fullpose-kc", (r"^ranges over the seeds",)),
    # docs/methods.md
    "papers-ca-calibration": Block("papers", (r"^## CA paper", r"^### Table 5")),
    "papers-ca-validation": Block("papers", (r"^## CA paper", r"^### Table 6")),
    "papers-ca-gain": Block("papers", (r"^## CA paper", r"^### Improvement of SKCM-CA")),
    "papers-ca-stiffness": Block("papers", (r"^## CA paper", r"^### Stiffness")),
    "papers-ca-robots": Block("papers", (r"^## CA paper", r"^### Over \d+ simulated robots")),
    "papers-ga-o1": Block("papers", (r"^## GA paper", r"^### Pose selection")),
    "papers-ga-set": Block("papers", (r"^## GA paper", r"^### On the GA-selected set"), timing=("time (s)",)),
    "papers-ga-splits": Block("papers", (r"^## GA paper", r"^statistics of the per-split mean error")),
    "papers-tlbo-calibration": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800\)", r"^### Table 4")),
    "papers-tlbo-validation": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800\)", r"^### Table 5")),
    "papers-tlbo-robots": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800\)", r"^### Over \d+ simulated")),
    "papers-tlbo-gears-calibration": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800-gears\)", r"^### Table 4")),
    "papers-tlbo-gears-validation": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800-gears\)", r"^### Table 5")),
    "papers-tlbo-gears-gain": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800-gears\)", r"^### Improvement")),
    "papers-tlbo-gears-robots": Block("papers", (r"^## TLBO paper.*\(tlbo-hh800-gears\)", r"^### Over \d+ simul")),
    "papers-rbf": Block("papers", (r"^## Why GA-RBF gains little", r"^KM and GA-RBF validation mean")),
    "metaheuristics-a": Block("metaheuristics", (r"^## A\. ",), timing=("time (s), mean",)),
    "metaheuristics-b": Block("metaheuristics", (r"^## B\. ",), timing=("time (s), mean",)),
    # docs/planning.md
    "planning-fig6": Block("planning", (r"^### Fig\. 6",)),
    "planning-simulation": Block("planning", (r"^### Simulation: validation",)),
    "planning-efficiency": Block("planning", (r"^### Simulation: certified D-efficiency",)),
    "planning-ga": Block("planning", (r"^### D-optimal vs GA",), timing=("D-opt time (s)", "GA time (s, mean)")),
    "next-poses-loop": Block("next-poses", (r"^### The loop",)),
    "next-poses-example": Block("next-poses", (r"^### Worked example: narrow range",)),
    "next-poses-compliance": Block("next-poses", (r"^### Worked example: compliance or scale",)),
    # docs/diagnosis.md
    "hidden-effects-summary": Block("hidden-effects", (r"^### Exact claims per effect",)),
    "hidden-effects-failing": Block("hidden-effects", (r"^### Claims that are not exact",)),
    "open-world-outside": Block("open-world", (r"^### Effects outside the catalogue",)),
    "open-world-noise": Block("open-world", (r"^### Noise alone",)),
    "compensator-study": Block("compensator", (r"^### The GP compensator's study",)),
    # docs/guide.md
    "guide-aic": Block("guide", (r"^AIC and BIC",)),
    "guide-urdf": Block("guide", (r"^URDF read by yourdfpy",)),
    # docs/touch.md
    "touch-peer-panda2": Block("touch-peer", (r"^### Held-out means per robot",)),
    # docs/formats.md
    "formats-singular": Block("singular", (r"^UR10, .* measured poses",)),
}


# --- the docs' blocks ----------------------------------------------------------------------------------


@dataclass
class Quoted:
    """A generated block as it stands in a doc."""

    path: Path
    name: str
    command: str
    line: int            # line of the begin marker (1-based)
    start: int           # offsets of the content (after the begin marker's line, before the end marker)
    end: int
    text: str


class MarkerError(ValueError):
    pass


_FENCE = re.compile(r"^```.*?^```[ \t]*$", re.S | re.M)


def _search(pattern: re.Pattern, text: str, pos: int, fences: list[tuple[int, int]], end: int | None = None):
    """The next match of ``pattern`` outside fenced code (where a marker is an example, not a block)."""
    while True:
        m = pattern.search(text, pos) if end is None else pattern.search(text, pos, end)
        if m is None or not any(a <= m.start() < b for a, b in fences):
            return m
        pos = m.end()


def quoted_blocks(paths=None) -> list[Quoted]:
    """Every generated block of the docs, in order; MarkerError for an unbalanced or nested marker."""
    found = []
    for path in paths or DOCS:
        text = path.read_text(encoding="utf-8")
        fences = [(m.start(), m.end()) for m in _FENCE.finditer(text)]
        pos = 0
        while True:
            b = _search(BEGIN, text, pos, fences)
            e = _search(END, text, pos, fences)
            if b is None:
                if e is not None:
                    raise MarkerError(f"{path.name}, line {text.count(chr(10), 0, e.start()) + 1}: "
                                      "'end generated' without a 'generated:' marker")
                break
            line = text.count("\n", 0, b.start()) + 1
            if e is None or e.start() < b.start():
                raise MarkerError(f"{path.name}, line {line}: '{b.group(1)}' has no 'end generated' marker")
            nested = _search(BEGIN, text, b.end(), fences, e.start())
            if nested:
                raise MarkerError(f"{path.name}, line {line}: '{b.group(1)}' is not closed before the next block")
            start = text.index("\n", b.end()) + 1
            found.append(Quoted(path, b.group(1), b.group(2).strip(), line, start, e.start(),
                                text[start:e.start()]))
            pos = e.end()
    return found


# --- the jobs' output -----------------------------------------------------------------------------------


def run_job(name: str, save: Path | None = None, verbose: bool = True) -> str:
    """Run a job in the repository (this checkout's package) and return its standard output."""
    job = JOBS[name]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    env["PYTHONUNBUFFERED"] = "1"
    bindir = Path(tempfile.mkdtemp(prefix="casadical-docs-bin-"))
    (bindir / "casadical").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m casadical "$@"\n')
    (bindir / "casadical").chmod(0o755)
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    out = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=f"casadical-docs-{name}-") as tmp:
        for cmd in job.commands:
            argv = [sys.executable if a == "python" else a.replace("{tmp}", tmp) for a in cmd]
            proc = subprocess.run(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True)
            if proc.returncode != 0:
                raise RuntimeError(f"job {name}: {shlex.join(cmd)} exits with {proc.returncode}:\n"
                                   f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
            out.append(proc.stdout)
    shutil.rmtree(bindir, ignore_errors=True)
    text = "".join(out)
    if verbose:
        load = os.getloadavg()[0]
        print(f"job {name}: {time.perf_counter() - t0:.0f} s (load {load:.1f})", flush=True)
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        (save / f"{name}.out").write_text(text, encoding="utf-8")
    return text


def extract(output: str, block: Block, name: str = "") -> str:
    """The block's table in a job's output, ending in a newline."""
    lines = output.splitlines()
    i = 0
    for pat in block.after:
        while i < len(lines) and not re.search(pat, lines[i]):
            i += 1
        if i == len(lines):
            raise LookupError(f"block {name}: no line of job {block.job} matches {pat!r} (after the ones before)")
        i += 1
    while i < len(lines) and not lines[i].startswith("|"):
        i += 1
    table = []
    while i < len(lines) and lines[i].startswith("|"):
        table.append(lines[i].rstrip())
        i += 1
    if not table:
        raise LookupError(f"block {name}: no table after {block.after[-1]!r} in job {block.job}")
    return "\n".join(table) + "\n"


def _cells(row: str) -> list[str]:
    return [c.strip() for c in re.split(r"(?<!\\)\|", row.strip())[1:-1]]


def masked(text: str, block: Block) -> list[str]:
    """The block's lines with the timing columns blanked (what the check compares)."""
    rows = [ln.rstrip() for ln in text.strip("\n").splitlines()]
    if not block.timing or not rows:
        return rows
    header = _cells(rows[0])
    drop = {i for i, h in enumerate(header) if h in block.timing}
    missing = set(block.timing) - set(header)
    if missing:
        raise LookupError(f"timing columns {sorted(missing)} are not in the table's header {header}")
    out = []
    for r in rows:
        cells = _cells(r)
        out.append("| " + " | ".join("(time)" if i in drop else c for i, c in enumerate(cells)) + " |")
    return out


# --- check and write --------------------------------------------------------------------------------------


def compare(quoted: Quoted, generated: str) -> str | None:
    """None if the quoted block matches what its job printed now (timings aside), else a diff."""
    block = BLOCKS[quoted.name]
    if not block.check:
        return None
    a, b = masked(quoted.text, block), masked(generated, block)
    if len(a) == len(b) and all(same_line(x, y) for x, y in zip(a, b)):
        return None
    diff = difflib.unified_diff(a, b, f"{quoted.path.name} (line {quoted.line})", f"job {block.job} now",
                                lineterm="", n=0)
    return f"{quoted.path.name}, line {quoted.line}: block {quoted.name} differs from what " \
           f"`{JOBS[block.job].display}` prints now (timings not compared):\n" + "\n".join(diff)


def write(quoted: list[Quoted], outputs: dict[str, str], timings: bool = False) -> list[Path]:
    """Replace the content of every block whose job ran and whose figures changed (with ``timings``: every
    block whose text changed, timings included); returns the files changed."""
    changed = []
    by_path: dict[Path, list[Quoted]] = {}
    for q in quoted:
        if BLOCKS[q.name].job in outputs:
            by_path.setdefault(q.path, []).append(q)
    for path, qs in by_path.items():
        text = path.read_text(encoding="utf-8")
        for q in sorted(qs, key=lambda q: q.start, reverse=True):
            new = extract(outputs[BLOCKS[q.name].job], BLOCKS[q.name], q.name)
            if timings or not q.text.strip() or compare(q, new) is not None:
                text = text[:q.start] + new + text[q.end:]
        if text != path.read_text(encoding="utf-8"):
            path.write_text(text, encoding="utf-8")
            changed.append(path)
    return changed


def check_job(name: str, output: str, quoted: list[Quoted] | None = None) -> list[str]:
    """The differences between the docs' blocks of job ``name`` and its output (empty if none)."""
    quoted = quoted_blocks() if quoted is None else quoted
    problems = []
    for q in quoted:
        if BLOCKS[q.name].job != name:
            continue
        try:
            d = compare(q, extract(output, BLOCKS[q.name], q.name))
        except LookupError as e:
            d = f"{q.path.name}, line {q.line}: {e}"
        if d:
            problems.append(d)
    return problems


def marker_problems(quoted: list[Quoted] | None = None, complete: bool = True) -> list[str]:
    """What is wrong with the markers themselves (no job runs): unknown names, wrong commands, ...;
    with ``complete``, also empty blocks (not filled yet) and registered blocks no doc quotes."""
    problems = []
    try:
        quoted = quoted_blocks() if quoted is None else quoted
    except MarkerError as e:
        return [str(e)]
    for q in quoted:
        where = f"{q.path.name}, line {q.line}"
        block = BLOCKS.get(q.name)
        if block is None:
            problems.append(f"{where}: no block {q.name!r} in benchmarks/docs/regenerate_docs.py")
            continue
        job = JOBS[block.job]
        if q.command != job.display:
            problems.append(f"{where}: block {q.name} names the command {q.command!r}; its job runs "
                            f"{job.display!r}")
        for s in job.scripts:
            if not s.is_file():
                problems.append(f"{where}: block {q.name}: {s.relative_to(ROOT)} does not exist")
        if not q.text.strip():
            if complete:
                problems.append(f"{where}: block {q.name} is empty")
        else:
            rows = q.text.strip("\n").splitlines()
            if not all(r.startswith("|") and r.rstrip().endswith("|") for r in rows):
                problems.append(f"{where}: block {q.name} should hold a Markdown table and nothing else")
            elif len(rows) < 3 or not re.fullmatch(r"\|[-:| ]+\|", rows[1].strip()):
                problems.append(f"{where}: block {q.name}: a header, a separator and at least one row")
            else:
                try:
                    masked(q.text, block)
                except LookupError as e:
                    problems.append(f"{where}: block {q.name}: {e}")
    names = [q.name for q in quoted]
    for n in sorted({n for n in names if names.count(n) > 1}):
        problems.append(f"block {n} is quoted {names.count(n)} times")
    for n in sorted(set(BLOCKS) - set(names)) if complete else ():
        problems.append(f"block {n} of benchmarks/docs/regenerate_docs.py is in no doc")
    return problems


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare instead of writing; exit 1 if a block differs")
    ap.add_argument("--jobs", nargs="+", metavar="JOB", help=f"only these jobs ({', '.join(JOBS)})")
    ap.add_argument("--list", action="store_true", help="list the jobs and blocks and where they are")
    ap.add_argument("--timings", action="store_true",
                    help="also rewrite blocks whose figures are unchanged (their timings are this run's)")
    ap.add_argument("--save", type=Path, help="keep each job's output here (NAME.out)")
    ap.add_argument("--reuse", type=Path, help="read the jobs' outputs from here instead of running them")
    args = ap.parse_args(argv)
    problems = marker_problems(complete=False)
    if problems:
        print("\n".join(problems), file=sys.stderr)
        return 2
    for p in marker_problems()[len(problems):]:
        print(f"warning: {p}", file=sys.stderr)
    quoted = quoted_blocks()
    if args.list:
        for jname, job in JOBS.items():
            print(f"{jname} (~{job.minutes:g} min): {job.display}")
            for q in quoted:
                if BLOCKS[q.name].job == jname:
                    print(f"    {q.name}: {q.path.relative_to(ROOT)}, line {q.line}"
                          + ("" if BLOCKS[q.name].check else " (timings, not checked)"))
        return 0
    names = args.jobs or list(JOBS)
    unknown = set(names) - set(JOBS)
    if unknown:
        ap.error(f"unknown jobs {sorted(unknown)}; choose from {', '.join(JOBS)}")
    outputs = {}
    for n in names:
        if args.reuse:
            outputs[n] = (args.reuse / f"{n}.out").read_text(encoding="utf-8")
        else:
            outputs[n] = run_job(n, args.save)
    if args.check:
        failed = [p for n in names for p in check_job(n, outputs[n], quoted)]
        for p in failed:
            print(p + "\n")
        print(f"{len(failed)} block(s) differ" if failed else
              f"every block of {', '.join(names)} matches (timings not compared)")
        return 1 if failed else 0
    for path in write(quoted, outputs, args.timings):
        print(f"rewrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
