"""Issue 28: files an earlier version wrote, and what a new user trips on following the README and the guide.

Each test fails on the code before the issue (fe55b8a); the docstrings say what it did then.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from casadical import Measurements
from tests.cli.test_export import urdf_errors
from tests.helpers.cli import cli

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parents[1] / "data"
SERIES_B = ROOT / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"


# --- a calibration file written by an earlier version ------------------------------------------------------


def test_a_calibration_file_of_an_earlier_version_is_exported(tmp_path, capsys):
    """tests/data/ur10-kc-b70ddc3.json was written by casadical at b70ddc3, before calibration files recorded
    their poses (tests/data/README.md). export refits its geometry over poses drawn within the joint limits and
    says so, naming --as-fitted; the URDF (read by yourdfpy) predicts series B better than the geometry as it
    was fitted. (Before: "the calibration holds no poses (coverage) to refit its geometry on: calibrate again".)"""
    old = DATA / "ur10-kc-b70ddc3.json"
    best, fitted = tmp_path / "best.urdf", tmp_path / "fitted.urdf"
    code, out, err = cli(capsys, "export", old, "--urdf", best, "--table", tmp_path / "t.csv")
    assert code == 0, err
    warning = [line for line in err if line.startswith("casadical: warning:")]
    assert len(warning) == 1 and "earlier casadical" in warning[0] and "drawn within the joint limits" in warning[0]
    assert "--as-fitted" in warning[0]
    assert any("over 500 poses drawn within the joint limits" in line for line in err)
    assert "over 500 poses drawn within the joint limits" in best.read_text()
    assert cli(capsys, "export", old, "--urdf", fitted, "--as-fitted", "-q")[0] == 0
    data = Measurements.read_csv(SERIES_B, n_joints=6)
    assert urdf_errors(best, data).mean() < 0.8 * urdf_errors(fitted, data).mean()


# --- the README and the guide, as a new user follows them ----------------------------------------------------

import re  # noqa: E402
import shlex  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks" / "docs"))
from guide_runner import parse  # noqa: E402

#: options whose value is a file or folder a command writes
OUTPUTS = ("--out", "--out-cal", "--out-val", "--out-dir", "--json", "--html", "--urdf", "--table", "--markdown",
           "--plot-dir", "--plot")
FILE = re.compile(r"\.(csv|json|toml|urdf|md|html|parquet|txt)$")


def _shell_lines(path: Path) -> list[str]:
    """The command lines of a document's ``sh`` blocks, in order (continuations joined, comments dropped)."""
    text = path.read_text(encoding="utf-8")
    if path.name == "guide.md":
        blocks = [s.text for s in parse(text) if s.kind == "sh"]
    else:
        blocks = re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M)
    lines = [x for b in blocks for x in b.replace("\\\n", " ").splitlines()]
    return [p.strip() for x in lines for p in re.split(r"\s*&&\s*", re.sub(r"\s+#.*$", "", x)) if p.strip()]


def _reads_and_writes(line: str) -> tuple[list[str], list[str]]:
    words = shlex.split(line)
    if words[:1] != ["casadical"]:
        return [], []
    reads, writes = [], []
    for k, w in enumerate(words[1:], 1):
        if words[k - 1] in OUTPUTS:
            writes.append(w)
        elif not w.startswith("-") and (FILE.search(w) or "/" in w):
            reads.append(w)
    return reads, writes


@pytest.mark.parametrize("doc", ["README.md", "docs/guide.md"])
def test_every_file_a_command_reads_is_there_when_it_runs(doc):
    """The README's and the guide's commands run as pasted, in order: each file they read is in the repository
    or written by an earlier command (before: the README's compensate read a TARGETS.csv that nothing made)."""
    written: list[str] = []
    for step in parse((ROOT / doc).read_text(encoding="utf-8")) if doc.endswith("guide.md") else []:
        if step.kind == "toml":
            written.append(step.target)
    for line in _shell_lines(ROOT / doc):
        reads, writes = _reads_and_writes(line)
        for r in reads:
            assert (ROOT / r).exists() or any(r == w or r.startswith(w.rstrip("/") + "/") for w in written), \
                f"{doc}: {line}\n  reads {r}, which is neither in the repository nor written before"
        written += writes


@pytest.mark.parametrize("doc", ["README.md", "docs/guide.md"])
def test_every_output_goes_to_a_folder_git_ignores(doc):
    """A new user following the README or the guide in a clone leaves nothing git would show (before: the
    guide wrote some 30 files into the repository's root)."""
    outputs = [w for line in _shell_lines(ROOT / doc) for w in _reads_and_writes(line)[1]]
    outputs += [s.target for s in parse((ROOT / doc).read_text(encoding="utf-8")) if s.kind == "toml"] \
        if doc.endswith("guide.md") else []
    assert len(outputs) >= 5
    probe = subprocess.run(["git", "check-ignore", "--no-index", *outputs], cwd=ROOT, capture_output=True, text=True)
    if probe.returncode == 128:
        pytest.skip("not a git checkout")
    ignored = set(probe.stdout.split())
    assert [o for o in outputs if o not in ignored] == []


# --- the exported parameter table ------------------------------------------------------------------------


def test_the_exported_table_names_its_convention_and_shows_the_base_as_a_pose(tmp_path, capsys):
    """UR10 (DH with Hayati's beta on joints 2 and 3): the heading and the link transform say so; numbers read
    as written (-572.3, not -572.3000000000001); a calibration's base is a pose in the tracker's frame, without
    a nominal value or a 'difference' of 507.8 mm, and the Markdown shows it as a pose. (Before: 'DH parameter
    table', beta rows without a word, base rows with nominal 0 and a difference of metres.)"""
    csv_out, md_out = tmp_path / "t.csv", tmp_path / "t.md"
    code, _, err = cli(capsys, "export", DATA / "ur10-kc-b70ddc3.json", "--as-fitted", "--table", csv_out,
                       "--markdown", md_out, "-q")
    assert code == 0, err
    text = csv_out.read_text()
    head = text.splitlines()[0]
    assert head.startswith("# UR10: DH parameter table with Hayati's beta on joints 2, 3 (")
    assert "Hayati's Ry(beta) Ty(b) after Rx(alpha)" in head and "plain DH has no entry for them" in head
    assert not re.search(r"\d\.\d*(0{9}|9{9})\d", text), re.findall(r"\S*(?:0{9}|9{9})\d\S*", text)[:3]
    rows = {r.split(",")[1]: r.split(",") for r in text.splitlines()[2:]}
    assert rows["a3"][3] == "-572.3"
    for axis in ("x", "y", "z", "roll", "pitch", "yaw"):
        r = rows[f"base_pose_{axis}"]
        assert r[3] == "" and r[5] == "" and r[4] != "" and "a pose, not a parameter" in ",".join(r[9:])
    md = md_out.read_text()
    assert "Robot base in the measurement frame" in md and "| x (mm) | y (mm) | z (mm) |" in md
    assert "| base_pose_x |" not in md


# --- bad input, said so a new user can act on it ----------------------------------------------------------


def test_a_semicolon_separated_file_is_named_so_with_the_import_that_converts_it(tmp_path, capsys):
    """A file separated by ';': the error says so and gives the import command, which then works. (Before:
    'row 1: has no joint columns: expected q1_deg, q2_deg, ...'.)"""
    lines = SERIES_B.read_text().splitlines()[:30]
    semi = tmp_path / "semi.csv"
    semi.write_text("\n".join(line.replace(",", ";") for line in lines) + "\n")
    code, _, err = cli(capsys, "predict", "ur10", semi, "--out", tmp_path / "p.csv")
    assert code == 2 and len(err) == 1 and "separated by ';'" in err[0] and "casadical import" in err[0], err
    command = err[0].split("convert it with ")[1].split(" (and")[0].replace("NEW.csv", str(tmp_path / "new.csv"))
    words = shlex.split(command)
    assert words[:2] == ["casadical", "import"] and cli(capsys, *words[1:])[0] == 0
    assert cli(capsys, "predict", "ur10", tmp_path / "new.csv", "--out", tmp_path / "p.csv")[0] == 0


def test_a_misspelt_column_is_the_one_named(tmp_path, capsys):
    """``x_mn`` for ``x_mm``: the error names the column that is there and what it should be. (Before: column
    'x_mm': has only some of x_mm, y_mm, z_mm.)"""
    lines = SERIES_B.read_text().splitlines()[:30]
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([lines[0].replace("x_mm", "x_mn")] + lines[1:]) + "\n")
    code, _, err = cli(capsys, "calibrate", "ur10", bad, "--out", tmp_path / "c.json")
    assert code == 2 and len(err) == 1
    assert err[0].startswith(f"casadical: error: {bad}, row 1, column 'x_mn': ") and "'x_mm'" in err[0], err


@pytest.mark.parametrize("missing", ["z_mm", "rz_deg"])
def test_a_missing_column_is_named_not_the_valid_column_about_it(tmp_path, capsys, missing):
    """Series B without its z_mm (rz_deg) column: the error names that column as missing, never its valid
    std_z_mm (std_rz_deg) as an unknown misspelling of it (issue 47)."""
    lines = [line.split(",") for line in SERIES_B.read_text().splitlines()[:30]]
    k = lines[0].index(missing)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(",".join(f[:k] + f[k + 1:]) for f in lines) + "\n")
    code, _, err = cli(capsys, "calibrate", "ur10", bad, "--out", tmp_path / "c.json")
    assert code == 2 and len(err) == 1
    assert err[0].startswith(f"casadical: error: {bad}, row 1, column {missing!r}: has only some of "), err
    assert "std_" not in err[0] and "not a column casadical knows" not in err[0], err


def test_an_unknown_option_names_the_command_once(tmp_path, capsys):
    """(Before: 'casadical: error: casadical: unrecognized arguments: ...'.)"""
    code, _, err = cli(capsys, "diagnose", "ur10", "a.csv", "--validate", "b.csv", "--no-such-option")
    assert code == 2 and err == ["casadical: error: diagnose: unrecognized arguments: --no-such-option "
                                 "(see casadical diagnose --help)"]
    code, _, err = cli(capsys, "calibrate", "ur10", "a.csv", "--out", "c.json", "--max-iter", "0")
    assert code == 2 and err[0].startswith("casadical: error: calibrate: argument --max-iter: ")


def test_whole_numbers_stay_whole(tmp_path, capsys):
    """split, predict and compensate keep a column of whole numbers whole (source_row 856, not 856.0). (Before:
    a split of a split, predict and compensate rewrote them as floats.)"""
    cal, rest = tmp_path / "cal.csv", tmp_path / "rest.csv"
    assert cli(capsys, "split", SERIES_B, "-n", 300, "--seed", 0, "--out-cal", cal, "--out-val", rest)[0] == 0
    again = tmp_path / "again.csv"
    assert cli(capsys, "split", rest, "-n", 40, "--seed", 1, "--out-cal", again,
               "--out-val", tmp_path / "r.csv")[0] == 0
    predicted = tmp_path / "p.csv"
    assert cli(capsys, "predict", "ur10", again, "--out", predicted, "--allow-mismatch")[0] == 0
    for path in (cal, again, predicted):
        header, first = path.read_text().splitlines()[:2]
        row = dict(zip(header.split(","), first.split(",")))
        assert re.fullmatch(r"\d+", row["source_row"]) and re.fullmatch(r"-?\d", row["move1"]), (path.name, row)


def test_compensate_names_the_same_extrapolating_rows_whatever_it_holds(tmp_path, capsys):
    """The same targets with and without --position-only: the rows the extrapolation warning names are the
    same (the programmed joints are judged), and the output keeps whole numbers whole. (Before: lines 2, 7 in
    one mode and 2, 7, 8 in the other, judged on the corrected joints; source_row written as 856.0.)"""
    cal, rest = tmp_path / "cal.csv", tmp_path / "rest.csv"
    assert cli(capsys, "split", SERIES_B, "-n", 100, "--seed", 3, "--out-cal", cal, "--out-val", rest)[0] == 0
    assert cli(capsys, "calibrate", "ur10", cal, "--model", "kinematic", "--solver", "lm", "--out",
               tmp_path / "k.json", "-q")[0] == 0
    named = []
    for mode in ([], ["--position-only"]):
        out = tmp_path / f"j{len(mode)}.csv"
        with warnings.catch_warnings():
            warnings.simplefilter("always")     # the same text twice in one process: said twice
            code, _, err = cli(capsys, "compensate", tmp_path / "k.json", rest, "--out", out, *mode)
        assert code == 0, err
        named.append([line for line in err if "outside the ranges the calibration saw" in line])
        header, first = out.read_text().splitlines()[:2]
        assert re.fullmatch(r"\d+", dict(zip(header.split(","), first.split(",")))["source_row"])
    assert named[0] and named[0] == named[1]


# --- what calibrate says ---------------------------------------------------------------------------------


def test_calibrate_validate_on_full_pose_data_says_the_orientation_error_and_a_zero_bound_plainly(tmp_path,
                                                                                                   capsys):
    """Series B with the probe's orientation, kinematic+compliance on 200 poses, validated on 300 others: the
    summary and the JSON give the orientation error on the validation poses; a compliance stuck at its physical
    bound 0 is 'not determined by these poses', not 'widen the bound'. (Before: no validation orientation; 'c4
    is at or beyond its lower bound ...; widen the bound if it is not physical'.)"""
    cal, rest = tmp_path / "cal.csv", tmp_path / "rest.csv"
    assert cli(capsys, "split", SERIES_B, "-n", 200, "--seed", 0, "--out-cal", cal, "--out-val", rest)[0] == 0
    val = tmp_path / "val.csv"
    assert cli(capsys, "split", rest, "-n", 300, "--seed", 1, "--out-cal", val, "--out-val", tmp_path / "x.csv")[0] == 0
    out = tmp_path / "kc.json"
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        code, stdout, err = cli(capsys, "calibrate", "ur10", cal, "--model", "kinematic+compliance", "--solver", "lm",
                                "--validate", val, "--out", out)
    assert code == 0, err
    line = next(x for x in stdout.splitlines() if x.startswith(f"validation orientation ({val}): mean "))
    doc = json.loads(out.read_text())["orientation"]["validation"]
    assert doc["n_poses"] == 300 and f"mean {doc['mean_deg']:.4f}" in line and "over 300 poses" in line
    at_zero = [x for x in stdout.splitlines() + err if "at its lower bound 0" in x]
    assert at_zero and all("not determined by these poses" in x for x in at_zero)
    assert not any("widen the bound" in x for x in stdout.splitlines() + err if "bound 0" in x)


def test_the_html_report_reads_a_scale_in_ppm_and_counts_what_it_lists(tmp_path, capsys):
    """An encoder scale is shown in ppm in the report's parameter table (before: unit '1', 0.000123); the
    legend of short labels counts labels, not 'each of the N models' beside 'M models tried'."""
    from casadical.html import FOLD_FOOTNOTES, Page

    cal = tmp_path / "cal.csv"
    assert cli(capsys, "split", SERIES_B, "-n", 150, "--seed", 0, "--out-cal", cal, "--out-val",
               tmp_path / "v.csv")[0] == 0
    html = tmp_path / "r.html"
    code, _, err = cli(capsys, "calibrate", "ur10", cal, "--model", "kinematic+encoder_scale[2]", "--solver", "lm",
                       "--position-only", "--out", tmp_path / "c.json", "--html", html, "-q")
    assert code == 0, err
    row = re.search(r"<tr[^>]*>(?:(?!</tr>).)*>escale2<(?:(?!</tr>).)*</tr>", html.read_text(), re.S).group(0)
    cells = [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)]
    assert "ppm" in cells and "1" not in cells, cells
    value = json.loads((tmp_path / "c.json").read_text())
    escale = next(p for p in value["parameters"] if p["name"] == "escale2")
    assert f"{escale['value'] * 1e6:.6g}"[:4] in " ".join(cells)      # the JSON keeps the ratio; the page shows ppm
    page = Page("t")
    for k in range(FOLD_FOOTNOTES + 2):
        page.footnote(f"kinematic+spec{k}")
    text = page.html()
    assert not re.search(r"each of the \d+ models", text) and f"({FOLD_FOOTNOTES + 2} labels;" in text


def test_the_guide_says_why_two_stiffnesses_of_one_joint_differ():
    """The guide shows k2 from calibrate --model kinematic+compliance and from diagnose on the same poses: where
    the second is quoted, a paragraph gives both and says they are two models. (Before: 7.12e4 and 5.38e4 side by
    side, nothing on why.)"""
    text = (ROOT / "docs" / "guide.md").read_text(encoding="utf-8")
    values = {f"{float(m):.2e}".replace("e+0", "e") for m in re.findall(r"k2 = (\d\.\d+e\+?\d+)", text)}
    assert len(values) == 2, values
    paragraphs = [p for p in text.split("\n\n") if all(v in p for v in values)]
    assert paragraphs and "two" in paragraphs[0] and "models" in paragraphs[0], values
