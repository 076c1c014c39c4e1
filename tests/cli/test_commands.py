"""The command line: every command's help, inspect, predict, and one-line errors."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from casadical.cli import main
from casadical.data import Measurements


def run(*args):
    """Run the real entry point in a subprocess (checks exit code and stderr as a user sees them)."""
    return subprocess.run([sys.executable, "-m", "casadical", *args], capture_output=True, text=True)


@pytest.mark.parametrize("cmd", ["inspect", "predict", "simulate", "import-ur10", "calibrate", "diagnose", "split",
                                 "plan-poses", "candidates", "compare", "study"])
def test_help(cmd, capsys):
    with pytest.raises(SystemExit) as e:
        main([cmd, "--help"])
    assert e.value.code == 0
    assert "usage: casadical" in capsys.readouterr().out


def test_compare_help_lists_every_method(capsys):
    """The method names are filled in when the help is shown (the parser is built without the methods)."""
    from casadical.methods import method_names

    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    out = "".join(capsys.readouterr().out.split())    # argparse wraps at the terminal's width, even at hyphens
    assert "{names}" not in out
    assert out.count("".join(", ".join(method_names()).split())) == 2   # the description and --methods


def test_commands_without_a_model_start_without_casadi(tmp_path):
    """``split`` and ``--help`` import neither CasADi nor the methods; the package's names and submodules
    still resolve."""
    code = ("import contextlib, io, sys, casadical, casadical.cli as c\n"
            "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()): c.main(['--help'])\n"
            f"c.main(['split', {str(tmp_path / 'd.csv')!r}, '-n', '2', '--out-cal', {str(tmp_path / 'c.csv')!r}, "
            f"'--out-val', {str(tmp_path / 'v.csv')!r}])\n"
            "print(sorted(m for m in ('casadi', 'casadical.methods', 'casadical.calibration') if m in sys.modules))\n"
            "print(all(getattr(casadical, n) is not None for n in casadical.__all__), 'Model' in dir(casadical),\n"
            "      casadical.data._simulate.__name__)\n")
    (tmp_path / "d.csv").write_text("q1_deg,q2_deg,x_mm,y_mm,z_mm\n" + "".join(f"{k},0,1,2,3\n" for k in range(5)))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-2:] == ["[]", "True True casadical.data._simulate"]   # submodules too, as before
    import casadical

    assert set(casadical.__all__) == set(casadical._EXPORTS) | {"__version__"}
    with pytest.raises(AttributeError, match="no attribute 'nosuch'"):
        casadical.nosuch  # noqa: B018


def test_inspect_shows_identifiability(capsys):
    assert main(["inspect", "ys100", "--poses", "60"]) == 0
    out = capsys.readouterr().out
    assert "identifiable" in out and "d6" in out and "combination of tool_z" in out
    assert "instructions" in out


def test_predict_nominal(tmp_path, write):
    poses = write("poses.csv", "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,tag\n0,90,0,0,0,0,home\n10,80,5,0,20,0,b\n")
    out = tmp_path / "out.csv"
    assert main(["predict", "ys100", poses, "--out", str(out)]) == 0
    d = Measurements.read_csv(out)
    assert list(d.columns)[:7] == ["q1_deg", "q2_deg", "q3_deg", "q4_deg", "q5_deg", "q6_deg", "tag"]
    assert d.has_positions and np.isfinite(d.xyz).all()
    # refuses to overwrite without --force, keeps the file
    before = out.read_text()
    r = run("predict", "ys100", poses, "--out", str(out))
    assert r.returncode == 2 and "exists already" in r.stderr and out.read_text() == before
    assert main(["predict", "ys100", poses, "--out", str(out), "--force"]) == 0


def test_bad_input_is_one_line(write, tmp_path):
    poses = write("poses.csv", "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n0,90,x,0,0,0\n")
    r = run("predict", "ys100", poses, "--out", str(tmp_path / "o.csv"))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "row 2" in lines[0] and "'q3_deg'" in lines[0] and poses in lines[0]
    assert "Traceback" not in r.stderr
    r = run("inspect", "nosuchrobot")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


def test_simulate_protocol(tmp_path):
    assert main(["simulate", "ca-ys100", "--out-dir", str(tmp_path)]) == 0
    cal = Measurements.read_csv(tmp_path / "calibration.csv", n_joints=6, require_positions=True)
    assert len(cal) == 25 and (tmp_path / "truth.json").exists()


def test_every_option_has_help_with_its_default():
    """Help texts for every argument; an option with a default says it (issue 11: CLI conventions)."""
    import argparse

    from casadical.cli import build_parser
    ap = build_parser()
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, p in sub.choices.items():
        for a in p._actions:
            if isinstance(a, argparse._HelpAction) or a.dest == "debug":
                continue
            h = a.help or ""
            if not h:
                missing.append(f"{name} {a.option_strings or a.dest}: no help")
            elif (a.default not in (None, False, argparse.SUPPRESS) and not isinstance(a, argparse._StoreTrueAction)
                  and "default" not in h):
                missing.append(f"{name} {a.option_strings}: default {a.default!r} not in its help")
    assert not missing, missing


# --- outputs on standard output, and what a command needs to write ---------------------------------------------


@pytest.fixture(scope="module")
def poses(tmp_path_factory):
    """Calibration and validation poses of the YS100 with a compliant joint, and candidate poses."""
    from casadical import load_robot
    from casadical.data import Effects, simulate

    d = tmp_path_factory.mktemp("poses")
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 40, Effects(stiffness={2: 1.5e6}), seed=3)
    val, _ = simulate(robot, 40, truth=truth, seed=4)
    cal.write_csv(d / "cal.csv")
    val.write_csv(d / "val.csv")
    assert main(["candidates", "ys100", "-n", "300", "--out", str(d / "cand.csv")]) == 0
    assert main(["calibrate", "ys100", str(d / "cal.csv"), "--model", "kinematic", "--out", str(d / "cal.json"),
                 "--quiet"]) == 0
    (d / "study.toml").write_text('name = "one"\nprotocol = "ca-ys100"\nseed = 1\nrepetitions = 1\n'
                                  'validation_poses = 20\n[[plan]]\nmethod = "random"\nposes = 25\n'
                                  '[[method]]\nmethod = "Nominal"\n[[method]]\nmethod = "KM"\n')
    return d


#: a command line with --json - for every command that has --json (check: test_every_json_command_is_covered)
JSON_COMMANDS = {
    "inspect": ["inspect", "ys100", "--poses", "40"],
    "compare": ["compare", "ys100", "{d}/cal.csv", "--validate", "{d}/val.csv", "--methods", "KM"],
    "plan-poses": ["plan-poses", "ys100", "{d}/cand.csv", "-m", "30", "--out", "{d}/sel.csv", "--force"],
    "diagnose": ["diagnose", "ys100", "{d}/cal.csv", "--validate", "{d}/val.csv", "--max-rounds", "1", "--no-layer",
                 "--out", "{d}/final.json", "--force"],
    "cache": ["cache", "--info"],
    "study": ["study", "{d}/study.toml", "--out", "{d}/study-results", "--serial"],
    "compensate": ["compensate", "{d}/cal.json", "{d}/val.csv", "--out", "{d}/joints.csv", "--force"],
    "iso9283": ["iso9283", "ur10", str(Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"
                                       / "series_d.csv")],
}


def test_every_json_command_is_covered():
    import argparse

    from casadical.cli import build_parser
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    with_json = {name for name, p in sub.choices.items() if any("--json" in a.option_strings for a in p._actions)}
    assert with_json == set(JSON_COMMANDS)


@pytest.mark.parametrize("cmd", sorted(JSON_COMMANDS))
def test_json_to_standard_output_is_clean_json(cmd, poses):
    """``--json -``: standard output holds exactly one JSON document; every line for people goes to stderr."""
    r = run(*[a.format(d=poses) for a in JSON_COMMANDS[cmd]], "--json", "-")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert isinstance(doc, dict) and doc
    if cmd == "diagnose":       # the report (keys of docs/formats.md section 4) and the summary beside it, on stderr
        assert {"steps", "findings", "final"} <= set(doc)
        assert "findings (sizes in the final model" in r.stderr and "final model -> " in r.stderr
    if cmd in ("compare", "plan-poses", "study"):
        assert "standard output" in r.stderr
    if cmd == "study":          # the table people read, and the same rows in the JSON
        assert "| random | 25 | KM | 1/1 |" in r.stderr
        assert [(row["method"], row["ok"]) for row in doc["rows"]] == [("Nominal", 1), ("KM", 1)]
        assert doc["baseline"] == "Nominal" and doc["rows"][1]["win_rate"] in (0.0, 0.5, 1.0)


@pytest.mark.parametrize("args", [
    ["calibrate", "ys100", "{d}/cal.csv", "--out", "-"],
    ["diagnose", "ys100", "{d}/cal.csv", "--validate", "{d}/val.csv", "--out", "-"],
    ["split", "{d}/cal.csv", "-n", "10", "--out-cal", "-", "--out-val", "v.csv"],
    ["candidates", "ys100", "-n", "20", "--out", "-"],
    ["plan-poses", "ys100", "{d}/cand.csv", "-m", "30", "--out", "-"],
    ["compare", "ys100", "{d}/cal.csv", "--validate", "{d}/val.csv", "--methods", "KM", "--plot", "-"],
], ids=lambda a: a[0])
def test_a_file_output_named_dash_is_refused(poses, tmp_path, monkeypatch, capsys, args):
    """'-' means standard output; an output that is a file (a calibration, poses, a plot) cannot go there: one line
    before the work, and no file named '-' (it was written silently)."""
    monkeypatch.chdir(tmp_path)
    assert main([a.format(d=poses) for a in args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and " -: this output is a file" in err[0] and "./-" in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_one_output_at_most_on_standard_output(poses):
    r = run("diagnose", "ys100", f"{poses}/cal.csv", "--validate", f"{poses}/val.csv", "--json", "-", "--html", "-")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "--json and --html both name standard output" in lines[0]


def test_diagnose_needs_one_output_and_no_json_for_html(poses, tmp_path):
    """--html alone is enough; without --json, --html and --out one line says what to give."""
    r = run("diagnose", "ys100", f"{poses}/cal.csv", "--validate", f"{poses}/val.csv")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "nothing to write" in lines[0] and "--html" in lines[0]
    html = tmp_path / "r.html"
    r = run("diagnose", "ys100", f"{poses}/cal.csv", "--validate", f"{poses}/val.csv", "--html", str(html),
            "--max-rounds", "1", "--no-layer", "--quiet")
    assert r.returncode == 0, r.stderr
    assert html.read_text().startswith("<!DOCTYPE html>") and list(tmp_path.iterdir()) == [html]
    assert f"html report -> {html}" in r.stdout and "report -> " not in r.stdout.replace("html report -> ", "")
    # --html -: the page alone on standard output
    r = run("diagnose", "ys100", f"{poses}/cal.csv", "--validate", f"{poses}/val.csv", "--html", "-",
            "--max-rounds", "1", "--no-layer", "--quiet")
    assert r.returncode == 0 and r.stdout.startswith("<!DOCTYPE html>") and r.stdout.rstrip().endswith("</html>")
    assert "findings (sizes in the final model" in r.stderr


def test_predict_renames_measured_orientations_it_does_not_predict(tmp_path):
    """predict with a position-only calibration on poses with a measured orientation: the output's x_mm.. are the
    model's, and the measured rx_deg.. are renamed measured_rx_deg.. like the measured positions (an rx_deg left
    beside the model's point would be taken for a target orientation by compensate)."""
    import csv
    from pathlib import Path
    series_b = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"
    cal, val = tmp_path / "cal.csv", tmp_path / "val.csv"
    assert main(["split", str(series_b), "-n", "200", "--out-cal", str(cal), "--out-val", str(val)]) == 0
    assert main(["calibrate", "ur10", str(cal), "--model", "kinematic", "--position-only", "--solver", "lm",
                 "--out", str(tmp_path / "c.json")]) == 0
    assert main(["predict", str(tmp_path / "c.json"), str(val), "--out", str(tmp_path / "p.csv")]) == 0
    header = next(csv.reader(open(tmp_path / "p.csv")))
    assert "rx_deg" not in header and {"measured_rx_deg", "measured_x_mm", "x_mm"} <= set(header)
