"""``calibrate()`` as a pipeline of named stages (casadical/calibration/): the order the docs give, a stage
added in its place, a warning that names the caller's line."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from casadical import calibrate
from casadical.calibration import _pipeline as pipeline
from casadical.data import Effects, simulate
from casadical.errors import ConvergenceWarning
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM4

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide.md"


def _data(seed: int, n: int = 40):
    robot = robot_from_dict(ARM4)
    data, truth = simulate(robot, n, Effects(stiffness={2: 3e5}, noise=20e-6), seed=seed, floor_z=None)
    return robot, data, truth


def test_the_guide_names_every_stage_in_order():
    """docs/guide.md names the stages as ``STAGES`` runs them; each is a function of a module of the package."""
    text = GUIDE.read_text()
    section = text[text.index("## Adding a calibration stage"):]
    section = section[:section.find("\n## ", 5) if "\n## " in section[5:] else None]
    names = [s.__name__ for s in pipeline.STAGES]
    said = [w for w in re.findall(r"`(\w+)`", section) if w in names]
    assert said == names
    for stage in pipeline.STAGES:
        assert stage.__module__.startswith("casadical.calibration."), stage
        assert stage.__doc__, stage


@pytest.mark.parametrize("seed", [0, 1])
def test_a_stage_added_sees_the_solution_and_its_note_reaches_the_result(monkeypatch, seed):
    """A stage put after ``solve_parameters`` reads the solved parameters; what it notes is in the result, and
    every other figure is what the pipeline gives without it."""
    robot, data, _ = _data(seed)
    plain = calibrate(robot, data, "kinematic+compliance[2]", "lm", warn=False)
    seen = {}

    def look_at_the_solution(run):
        seen["values"] = run.params.values.copy()
        run.note("looked at the solution")

    at = pipeline.STAGES.index(pipeline.solve_parameters) + 1
    monkeypatch.setattr(pipeline, "STAGES", pipeline.STAGES[:at] + (look_at_the_solution,) + pipeline.STAGES[at:])
    res = calibrate(robot, data, "kinematic+compliance[2]", "lm", warn=False)
    np.testing.assert_array_equal(seen["values"], res.parameters.values)
    np.testing.assert_array_equal(res.parameters.values, plain.parameters.values)
    assert "looked at the solution" in res.notes and "looked at the solution" not in plain.notes
    assert res.calibration.mean_mm == plain.calibration.mean_mm


def test_a_warning_of_calibrate_names_the_callers_line():
    """A note warned by a stage points at the line that called ``calibrate`` (not at the pipeline or the
    thread-limit wrapper)."""
    robot, data, _ = _data(2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrate(robot, data, "kinematic+compliance[2]", "ipopt", solver_options={"max_iter": 1})
    ours = [w for w in caught if issubclass(w.category, ConvergenceWarning)]
    assert ours, [str(w.message) for w in caught]
    assert all(w.filename == __file__ for w in ours), [(w.filename, w.lineno) for w in ours]
