"""The tables the docs quote from scripts are the scripts' output, and still what the code gives.

``benchmarks/docs/regenerate_docs.py`` holds the blocks (``<!-- generated: NAME (COMMAND) -->`` ...
``<!-- end generated -->``), the jobs that print them and how to find them in the output. The fast tests
check the markers (every block registered, named with its job's command, a table; every registered block
quoted once) and that the comparison catches a changed figure and ignores a changed timing. Under
``pytest -m slow`` each job runs with its documented seeds and arguments and every block it fills must
match, timings aside: 11-20 minutes on 2 cores (load 1-8) for all of them (``-k`` picks jobs; the times per job
are in docs/benchmarks.md, "Docs that cannot drift").
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks" / "docs"))
import regenerate_docs as rd  # noqa: E402


def test_the_markers_are_well_formed():
    assert rd.marker_problems() == []
    quoted = rd.quoted_blocks()
    assert len(quoted) == len(rd.BLOCKS)
    docs = {q.path.name for q in quoted}
    assert {"guide.md", "studies.md", "methods.md", "ur10.md", "planning.md"} <= docs


def test_every_job_runs_a_script_or_command_that_exists():
    for name, job in rd.JOBS.items():
        for cmd in job.commands:
            assert cmd[0] in ("python", "casadical"), (name, cmd)
        for script in job.scripts:
            assert script.is_file(), f"job {name}: {script} does not exist"
    assert {b.job for b in rd.BLOCKS.values()} == set(rd.JOBS)


def test_marker_problems_are_found(tmp_path):
    doc = tmp_path / "x.md"
    doc.write_text("<!-- generated: no-such-block (python benchmarks/studies/x.py) -->\n| a |\n|---|\n| 1 |\n"
                   "<!-- end generated -->\n"
                   "<!-- generated: ur10-heldout (python benchmarks/studies/study_ur10.py --seeds 0) -->\n"
                   "| a |\n|---|\n| 1 |\n<!-- end generated -->\n"
                   "<!-- generated: guide-aic (python benchmarks/docs/guide_figures.py) -->\nsome text\n"
                   "<!-- end generated -->\n")
    problems = "\n".join(rd.marker_problems(rd.quoted_blocks([doc])))
    assert "no block 'no-such-block'" in problems
    assert "names the command 'python benchmarks/studies/study_ur10.py --seeds 0'" in problems
    assert "guide-aic should hold a Markdown table" in problems
    assert "timing columns" in problems          # ur10-heldout's timing columns are not in that table
    doc.write_text("<!-- generated: guide-aic (python benchmarks/docs/guide_figures.py) -->\n| a |\n")
    with pytest.raises(rd.MarkerError, match="has no 'end generated' marker"):
        rd.quoted_blocks([doc])


def _with_cell(text: str, row: int, column: str, change) -> str:
    """The table ``text`` with one cell (data row ``row``, column header ``column``) replaced by change(cell)."""
    lines = text.strip("\n").splitlines()
    k = rd._cells(lines[0]).index(column)
    cells = rd._cells(lines[2 + row])
    cells[k] = change(cells[k])
    lines[2 + row] = "| " + " | ".join(cells) + " |"
    return "\n".join(lines) + "\n"


def test_a_changed_figure_is_caught_and_a_changed_timing_is_not():
    """On a quoted block as it stands: the same text matches; its timings changed match; a figure changed in its
    last digit (a rounding another CPU may give) matches; one changed in its second decimal (0.401 -> 0.411 mm)
    does not, and the difference names the doc, the line, the command and the row."""
    q = next(q for q in rd.quoted_blocks() if q.name == "ur10-heldout")
    assert rd.compare(q, q.text) is None
    timed = _with_cell(q.text, 1, "solve (median)", lambda c: "999.9 ms")
    timed = _with_cell(timed, 2, "calibrate() first / median", lambda c: "9.99 s / 9.999 s")
    assert timed != q.text and rd.compare(q, timed) is None
    rounded = _with_cell(q.text, 2, "mean (mm)", lambda c: c[:4] + str((int(c[4]) + 1) % 10) + c[5:])
    assert rounded != q.text and rd.compare(q, rounded) is None
    figure = _with_cell(q.text, 2, "mean (mm)", lambda c: c[:3] + str((int(c[3]) + 1) % 10) + c[4:])
    assert figure != q.text
    diff = rd.compare(q, figure)
    assert diff is not None and "ur10.md, line" in diff and "python benchmarks/studies/study_ur10.py" in diff
    doc_cell = rd._cells(q.text.splitlines()[4])[5]
    now_cell = rd._cells(figure.splitlines()[4])[5]
    assert any(ln.startswith("-|") and doc_cell in ln for ln in diff.splitlines())
    assert any(ln.startswith("+|") and now_cell in ln for ln in diff.splitlines())


def test_extract_finds_the_table_after_its_caption():
    out = "## A\n\n| x |\n|---|\n| 1 |\n\n## B\n\ncaption\n\n| y | time (s) |\n|---|---|\n| 2 | 0.5 |\ntail\n"
    block = rd.Block("ur10", (r"^## B", r"^caption"), timing=("time (s)",))
    assert rd.extract(out, block) == "| y | time (s) |\n|---|---|\n| 2 | 0.5 |\n"
    assert rd.masked("| y | time (s) |\n|---|---|\n| 2 | 0.5 |\n", block)[2] == "| 2 | (time) |"
    with pytest.raises(LookupError, match="no line of job ur10 matches"):
        rd.extract(out, rd.Block("ur10", (r"^## C",)))


def test_write_replaces_only_changed_blocks(tmp_path):
    doc = tmp_path / "x.md"
    table = ("| model | free | AIC | BIC | validation mean mm |\n|---|---|---|---|---|\n"
             "| `k` | 1 | 2.00 | 3.00 | 0.4 |\n")
    doc.write_text("text\n<!-- generated: guide-aic (python benchmarks/docs/guide_figures.py) -->\n" + table
                   + "<!-- end generated -->\nmore\n")
    assert rd.write(rd.quoted_blocks([doc]), {"guide": "AIC and BIC ...\n\n" + table}) == []
    # a unit of the last digit is a rounding (figures.py): the block stays; two are a change
    assert rd.write(rd.quoted_blocks([doc]), {"guide": "AIC and BIC ...\n\n" + table.replace("0.4", "0.5")}) == []
    assert rd.write(rd.quoted_blocks([doc]), {"guide": "AIC and BIC ...\n\n" + table.replace("0.4", "0.6")}) == [doc]
    assert doc.read_text().endswith("| `k` | 1 | 2.00 | 3.00 | 0.6 |\n<!-- end generated -->\nmore\n")


@pytest.mark.slow
@pytest.mark.parametrize("job", list(rd.JOBS))
def test_quoted_tables_match_the_code(job):
    """Run the job (its documented seeds and arguments); every block it fills must match, timings aside."""
    output = rd.run_job(job, verbose=False)
    problems = rd.check_job(job, output)
    assert not problems, ("\n\n".join(problems) + "\n\nregenerate: python benchmarks/docs/regenerate_docs.py --jobs "
                          + job)
