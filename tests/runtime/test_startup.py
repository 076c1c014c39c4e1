"""Start-up: a command imports what it uses and nothing else (issue 26, item 4).

Each command runs in a fresh process that prints what it imported; the
figures of each command's start-up are ``benchmarks/speed/bench_startup.py``'s.
"""

import json
import subprocess
import sys

import pytest

from casadical.data import Effects, simulate
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM4

#: packages no command below uses
NEVER = ("sklearn", "matplotlib", "cvxpy", "dask", "distributed", "pandas", "casadical.planning",
         "casadical.importers", "casadical.methods", "casadical.study", "casadical.html", "casadical.diagnosis")


def _imported(args: list[str], cwd) -> set[str]:
    """The modules ``casadical ARGS`` imports, in a fresh process (run in ``cwd``, away from the repository's
    root, so that ``PYTHONPATH`` can point at other code)."""
    code = ("import json, sys\nfrom casadical.cli import main\n"
            f"code = main({args!r})\n"
            "print(json.dumps([code, sorted(sys.modules)]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd)
    assert r.returncode == 0, r.stderr
    code, mods = json.loads(r.stdout.splitlines()[-1])
    assert code == 0
    return set(mods)


def _packages(mods: set[str], names) -> list[str]:
    return sorted(n for n in names if n in mods)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Position-only poses of an arm that is not built in, its TOML file, and a kinematic calibration."""
    from tests.helpers.arms import to_toml

    d = tmp_path_factory.mktemp("startup")
    robot = robot_from_dict(ARM4)
    (d / "arm.toml").write_text(to_toml(ARM4))
    data, _ = simulate(robot, 40, Effects(noise=20e-6), seed=3, floor_z=None)
    data.write_csv(d / "poses.csv")
    return d


def test_calibrate_imports_no_planning_no_compensator_no_scipy(files):
    """A kinematic calibration of positions: no scipy (its linear algebra comes with the GP compensator, its
    rotations with measured orientations), no planning, importers or compensators (the GP compensator's
    casadical.calibration._per_session among them)."""
    mods = _imported(["calibrate", str(files / "arm.toml"), str(files / "poses.csv"), "--model", "kinematic",
                      "--out", str(files / "cal.json"), "--force", "--quiet"], files)
    assert "casadical.calibration" in mods
    assert _packages(mods, NEVER + ("scipy", "casadical.compensators", "casadical.calibration._per_session")) == []


def test_predict_imports_no_calibration_pipeline(files):
    """Reading a calibration to predict needs the result and the model, not the pipeline that fits one (the
    package's light __init__ and its per-session GP compensator, which predict applies, are not the pipeline)."""
    if not (files / "cal.json").exists():
        _imported(["calibrate", str(files / "arm.toml"), str(files / "poses.csv"), "--model", "kinematic",
                   "--out", str(files / "cal.json"), "--force", "--quiet"], files)
    mods = _imported(["predict", str(files / "cal.json"), str(files / "poses.csv"), "--out",
                      str(files / "p.csv"), "--force"], files)
    assert "casadical.result" in mods
    assert _packages(mods, NEVER + ("scipy", "casadical.calibration._pipeline", "casadical.calibration._solve",
                                    "casadical.data._simulate")) == []


def test_split_imports_no_model_no_planning(files):
    mods = _imported(["split", str(files / "poses.csv"), "-n", "20", "--out-cal", str(files / "c.csv"),
                      "--out-val", str(files / "v.csv"), "--force"], files)
    assert _packages(mods, NEVER + ("casadi", "casadical.model._symbolic", "casadical.stats._identifiability")) \
        == []


def test_calibrate_that_sets_poses_aside_imports_no_scipy_stats(files, tmp_path):
    """Three gross shots set aside: the structure tests of the set-aside poses (hypergeometric tails) come from
    scipy.special, not scipy.stats (0.5-0.6 s of CPU to import, before)."""
    robot = robot_from_dict(ARM4)
    data, _ = simulate(robot, 40, Effects(noise=20e-6), seed=4, floor_z=None)
    xyz = data.xyz.copy()
    xyz[[3, 17, 29]] += 5e-3
    data.with_positions(xyz).write_csv(tmp_path / "shots.csv")
    (tmp_path / "arm.toml").write_text((files / "arm.toml").read_text())
    mods = _imported(["calibrate", "arm.toml", "shots.csv", "--model", "kinematic", "--out", "cal.json", "--force",
                      "--quiet"], tmp_path)
    assert json.loads((tmp_path / "cal.json").read_text())
    assert "casadical.stats._outliers" in mods and "scipy.stats" not in mods


def test_html_reports_import_no_plotting_library(files, tmp_path):
    """The figures of both HTML reports are written as SVG by casadical.html._svg (issue 37): ``calibrate --html``
    and ``diagnose --html`` import casadical.html and never matplotlib (0.42 s to import, before)."""
    (tmp_path / "arm.toml").write_text((files / "arm.toml").read_text())
    robot = robot_from_dict(ARM4)
    for name, seed, n in (("cal.csv", 5, 60), ("val.csv", 6, 40)):
        simulate(robot, n, Effects(stiffness={2: 4e5}), seed=seed, floor_z=None)[0].write_csv(tmp_path / name)
    for args in (["calibrate", "arm.toml", "cal.csv", "--model", "kinematic", "--html", "c.html", "--out", "c.json"],
                 ["diagnose", "arm.toml", "cal.csv", "--validate", "val.csv", "--html", "d.html", "--out", "d.json",
                  "--no-blackbox", "--max-rounds", "1", "--quiet"]):
        mods = _imported(args + ["--force"], tmp_path)
        assert "casadical.html._svg" in mods and (tmp_path / args[args.index("--html") + 1]).read_text().count(
            "<svg") >= 3
        assert "matplotlib" not in mods, args[0]
