"""Every script in examples/ runs from the repository root and prints what it teaches (a broken example fails)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
while not (ROOT / "examples").is_dir() and ROOT != ROOT.parent:    # wherever under tests/ this file lives
    ROOT = ROOT.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))

#: a line each example must print: its result, not merely that it ran
KEY = {
    "01_calibrate.py": "joint compliance lowers the held-out mean error by",
    "02_diagnose.py": "named causes: joint_compliance joint 3, joint_periodic joint 2 harmonic 23",
    "03_compensate.py": "corrected program written to joints.csv (5 rows)",
    "04_export.py": "exported: the geometry refitted to reproduce the full model",
    "05_plan_poses.py": "selected 40 of 2000 candidate poses by d-optimal",
    "06_simulate.py": "within 2 std of the truth",
    "07_unexplained.py": "with gear32.toml, named causes: gear32 joint 3",
    "08_trust.py": "worst case restored: held-out mean / worst",
    "09_program.py": "filtered program: 6 of 6 targets corrected",
    "10_three_nests.py": "the nests' distances from one another, against the truth: within",
}


#: examples a test of what they teach runs instead (the same work once, not twice), and checks their key line
RUN_BY = {
    # its two diagnoses are the worst-case test's: that test runs the example and checks its reports
    "08_trust.py": "tests/diagnosis/test_worst_case.py",
}


def test_every_example_has_a_key_line():
    assert EXAMPLES and {p.name for p in EXAMPLES} == set(KEY)


def test_an_example_run_by_another_test_is_run_there():
    """The test that runs an example instead of this module names the example and checks its key line."""
    for name, test in RUN_BY.items():
        text = (ROOT / test).read_text(encoding="utf-8")
        assert f'"examples" / "{name}"' in text and KEY[name] in text, (name, test)


@pytest.mark.parametrize("script", [p for p in EXAMPLES if p.name not in RUN_BY], ids=lambda p: p.name)
def test_example_runs(script):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "CASADICAL_JIT": os.environ.get("CASADICAL_JIT", "0")}
    run = subprocess.run([sys.executable, str(script.relative_to(ROOT))], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert KEY[script.name] in run.stdout, run.stdout[-3000:]
