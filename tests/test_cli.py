"""The command line: every command's help, inspect, predict, and one-line errors."""

import subprocess
import sys

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
            "      casadical.simulate.__name__)\n")
    (tmp_path / "d.csv").write_text("q1_deg,q2_deg,x_mm,y_mm,z_mm\n" + "".join(f"{k},0,1,2,3\n" for k in range(5)))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[-2:] == ["[]", "True True casadical.simulate"]   # submodules too, as before
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
