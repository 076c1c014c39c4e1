"""A mount compliance that follows a session covariate by a law (issue 49): an arm on a lifting column at four
heights, made by the independent truth (tests/truth) on an arm that is not built in, the column's give growing with
its height ``C = c0 h``."""

import warnings

import numpy as np
import pytest

from casadical import calibrate
from casadical.errors import DataFileError, ModelError
from casadical.model import Model
from casadical.result import load_calibration
from casadical.terms import bernstein
from tests.helpers import hidden


@pytest.fixture(scope="module")
def column():
    c = hidden.session_case("arm6", "column", 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot, cal, val, true = hidden.make_data(c, n_cal=60, n_val=40)
    return robot, cal, val, true


def test_the_law_finds_the_columns_give_at_each_height(column):
    """The truth's compliance at each height (c0 h) is the law's, within 4 standard errors; the law beats one
    compliance for every height and is as good as one per session with half the parameters."""
    robot, cal, val, true = column
    c0 = true.effects.mount_law["height_m"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        law = calibrate(robot, cal, "kinematic+joint_compliance[2]+mount_compliance[height_m]", "lm", warn=False)
        one = calibrate(robot, cal, "kinematic+joint_compliance[2]+mount_compliance", "lm", warn=False)
        own = calibrate(robot, cal, "kinematic+joint_compliance[2]+" + "+".join(
            f"mount_compliance@{s}" for s in cal.session_names), "lm", warn=False)
    lo, hi = min(hidden.HEIGHTS), max(hidden.HEIGHTS)
    for k, h in ((0, lo), (1, hi)):       # degree 1: the coefficients are the compliance at the ends
        p = law.parameters[f"cmount_{k}"]
        assert abs(p.value - c0 * h) < 4 * p.std, (h, p.value, c0 * h, p.std)
    assert law.stats(val).mean_mm < one.stats(val).mean_mm
    assert law.stats(val).mean_mm < 1.05 * own.stats(val).mean_mm


def test_a_law_is_kept_over_its_range_and_carried_beyond_it(column, tmp_path):
    """The calibration JSON keeps the column's range; a pose at another height takes the law's value there (the
    model's tilt at a height beyond the range is the straight line's)."""
    robot, cal, _, _ = column
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate(robot, cal, "kinematic+mount_compliance[height_m]", "lm", warn=False)
    res.save(tmp_path / "law.json")
    back = load_calibration(tmp_path / "law.json")
    term = next(t for t in back.model.terms if t.name == "mount_compliance")
    assert (term.law, term.degree, term.law_lo, term.law_hi) == ("height_m", 1, min(hidden.HEIGHTS),
                                                                 max(hidden.HEIGHTS))
    one = cal.subset(cal.sessions == cal.session_names[-1])
    taller = one.with_columns({**one.columns, "height_m": np.full(len(one), 3.4)})
    w = back.model.covariates(taller)[:, back.model.covariate_names.index("height_m:b1")]
    assert np.allclose(w, (3.4 - term.law_lo) / (term.law_hi - term.law_lo))


def test_bernstein_polynomials_sum_to_one_and_stay_within_their_coefficients():
    v = np.linspace(1.0, 2.8, 7)
    for d in (1, 2):
        B = bernstein(d, v, 1.0, 2.8)
        assert np.allclose(B.sum(axis=1), 1.0) and (B >= 0).all()
    assert np.allclose(bernstein(1, np.array([1.0, 2.8]), 1.0, 2.8), np.eye(2))


def test_what_a_law_refuses(column):
    robot, cal, _, _ = column
    with pytest.raises(DataFileError, match="no numeric height_cm column"):
        calibrate(robot, cal, "kinematic+mount_compliance[height_cm]", "lm", warn=False)
    one = cal.subset(cal.sessions == cal.session_names[0])
    with pytest.raises(ModelError, match="takes one value"):
        calibrate(robot, one, "kinematic+mount_compliance[height_m]", "lm", warn=False)
    with pytest.raises(ModelError, match="degree"):
        Model(robot, "kinematic+mount_compliance[height_m:3]", jit=False)
    assert [p.name for p in Model(robot, "kinematic+mount_compliance[xy,height_m:2]", jit=False).parameters
            if p.term == "mount_compliance"] == [f"cmount_{a}_{k}" for a in "xy" for k in range(3)]


def test_a_named_law_asks_for_a_session_at_another_value(column):
    """The diagnosis names the law (its finding's ``law``), and plan-poses REPORT.json asks whether it holds at
    another height: a question of kind ``law`` on its two coefficients."""
    from casadical.diagnosis import DiagnosisSettings, diagnose
    from casadical.planning import open_questions

    robot, cal, val, _ = column
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rep = diagnose(robot, cal, val, DiagnosisSettings(seed=0))
    doc = rep.to_dict()
    law = [f for f in doc["findings"] if f["cause"] == "mount_compliance" and f["in_model"]]
    assert [f["law"]["column"] for f in law] == ["height_m"], doc["final"]["model"]
    values = {p.name: p.value for p in rep.final.parameters}
    qs = [q for q in open_questions(doc, values) if q.kind == "law"]
    names = [f"cmount_{k}" for k in range(law[0]["law"]["degree"] + 1)]
    assert len(qs) == 1 and qs[0].interest == names and "another height_m" in qs[0].text, qs
