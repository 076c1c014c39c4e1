"""plan-poses --program: the measurement run as a program (URScript, KRL, RAPID) that parses back (with the
program readers of compensate) to exactly the planned joint values, in the order of SELECTED.csv, which is a short
path in joint space."""

from __future__ import annotations

import numpy as np
import pytest

from casadical.data import Measurements
from casadical.loading import load_robot
from casadical.planning import measurement_order, path_length
from casadical.programs import _krl as krl
from casadical.programs import _rapid as rapid
from casadical.programs import _urscript as urscript
from casadical.robot import BUILTIN_DIR
from tests.helpers.arms import ARM6, to_toml
from tests.helpers.cli import cli, one_error

CASES = {"run.script": ("arm6", urscript.read), "run.src": ("track6", krl.read), "run.mod": ("ys100", rapid.read)}


@pytest.mark.parametrize("program", sorted(CASES))
@pytest.mark.parametrize("handshake", [False, True])
def test_the_run_parses_back_to_the_planned_joints(tmp_path, capsys, program, handshake):
    name, reader = CASES[program]
    robot_file = tmp_path / "robot.toml"
    robot_file.write_text(to_toml(ARM6) if name == "arm6" else (BUILTIN_DIR / f"{name}.toml").read_text())
    robot = load_robot(robot_file)
    code, _, err = cli(capsys, "candidates", robot_file, "-n", "300", "--out", tmp_path / "c.csv", "--floor-z", "none")
    assert code == 0, err
    extra = ["--handshake", "4,7"] if handshake else ["--wait-s", "1.5"]
    code, out, err = cli(capsys, "plan-poses", robot_file, tmp_path / "c.csv", "-m", "40", "--model", "kinematic",
                         "--out", tmp_path / "sel.csv", "--program", tmp_path / program, *extra)
    assert code == 0, err
    selected = Measurements.read_csv(tmp_path / "sel.csv", robot=robot)
    # (a URScript run sets no TCP: joint moves; read with the flange as the tool)
    prog = reader(str(tmp_path / program), robot.prismatic, *([np.eye(4)] if program.endswith(".script") else []))
    assert len(prog.targets) == len(selected) == 40
    for t, q in zip(prog.targets, selected.q):
        assert t.kind == "joints"
        np.testing.assert_array_equal(t.q, q)         # exactly the planned values
    text = (tmp_path / program).read_text()
    waits = {"run.script": ("while not get_standard_digital_in(7)", "sleep(1.5)"),
             "run.src": ("WAIT FOR $IN[7]", "WAIT SEC 1.5"), "run.mod": ("WaitDI di7, 1;", "WaitTime 1.5;")}[program]
    assert text.count(waits[0] if handshake else waits[1]) == 40 and (waits[1] if handshake else waits[0]) not in text
    # the order is a short path: shorter than the candidate file's order of the same poses
    values = np.column_stack([selected.columns[c] for c in selected.q_columns])
    plain = Measurements.read_csv(tmp_path / "c.csv", robot=robot)
    rows = sorted(int(np.flatnonzero(np.all(np.column_stack([plain.columns[c] for c in plain.q_columns]) == v,
                                                   axis=1))[0]) for v in values)
    cand = np.column_stack([plain.columns[c] for c in plain.q_columns])[rows]
    assert path_length(values, np.arange(40)) < 0.8 * path_length(cand, np.arange(40))


def test_order_is_a_short_path():
    """Poses on a line in joint space, shuffled: the order walks the line end to end."""
    rng = np.random.default_rng(0)
    line = np.outer(np.arange(30), [1.0, -2.0, 0.5]) + rng.normal(0, 0.01, (30, 3))
    shuffled = rng.permutation(30)
    order = measurement_order(line[shuffled])
    assert path_length(line[shuffled], order) == pytest.approx(path_length(line, np.arange(30)), rel=1e-6)


def test_handshake_without_program_and_bad_program_type(tmp_path, capsys):
    code, _, err = cli(capsys, "plan-poses", "ys100", tmp_path / "c.csv", "-m", "5", "--out", tmp_path / "s.csv",
                       "--program", tmp_path / "run.txt")
    assert code == 2
    one_error(err, "run.txt", "--program")
