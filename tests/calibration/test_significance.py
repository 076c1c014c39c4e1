"""Statistics an engineer reads: t, significance, intervals, AIC/BIC, and ``calibrate --validate``.

On simulated data of a robot that is not built in (the four-axis
palletiser of ``arms.py``) with a hidden compliance on joint 2 and none on
joint 3, fitted with compliance on both: joint 2's compliance must be
significant and its interval must cover the truth, joint 3's must be
flagged with a note that says what to do; AIC and BIC must prefer the true
model to one with more terms and to one with fewer.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from casadical.calibration import calibrate, load_calibration
from casadical.cli import main
from casadical.data import Effects, Measurements, simulate
from casadical.errors import SignificanceWarning
from casadical.loading import load_robot
from casadical.robot import robot_from_dict
from casadical.stats import FitStatistics, betainc, parameter_tests, stiffness_interval, t_critical, t_two_sided_p
from tests.helpers.arms import ARM4, to_toml

SEEDS = range(5)
STIFF = 4e6          # N m/rad on joint 2: t of its compliance about 15-20 at 60 poses
TRUE, OVER, UNDER = "kinematic+compliance[2,3]", "kinematic+compliance[2,3,4]+encoder_scale[2,3]", "kinematic"


# --- the t distribution, without SciPy -------------------------------------------------------------


@pytest.mark.parametrize("dof", [1, 2, 3, 5, 12, 30, 871, 10_000, 1_000_000])
def test_t_distribution_agrees_with_scipy(dof):
    from scipy import special

    rel = 1e-10 if dof <= 10_000 else 1e-8     # lgamma of a million loses digits; 3 are shown
    for level in (0.5, 0.9, 0.95, 0.99, 0.999):
        assert t_critical(level, dof) == pytest.approx(special.stdtrit(dof, 0.5 + level / 2), rel=rel)
    for t in (0.0, 0.19, 1.0, 1.96, 4.0, 12.0, -3.0, 40.0):
        assert t_two_sided_p(t, dof) == pytest.approx(2 * special.stdtr(dof, -abs(t)), rel=10 * rel, abs=1e-300)
    for a, b, x in ((dof / 2, 0.5, 0.3), (0.5, dof / 2, 0.999), (2.5, 3.5, 0.5)):
        assert betainc(a, b, x) == pytest.approx(special.betainc(a, b, x), rel=rel, abs=1e-300)
    assert t_critical(0.95) == pytest.approx(1.959963984540054)           # unknown dof: the normal's


def test_relative_std_interval_and_stiffness_interval_by_hand():
    robot = robot_from_dict(ARM4)
    from casadical.model import Model
    params = Model(robot, "kinematic+compliance[2,3]").parameters.copy()
    a2, c2, c3 = params["a2"], params["c2"], params["c3"]
    a2.value, a2.std = a2.nominal + 0.5e-3, 0.1e-3           # a deviation of 0.5 mm known to 0.1 mm
    c2.value, c2.std = 2.5e-7, 1e-8
    c3.value, c3.std = 1e-8, 2e-8
    for p in params:
        p.fixed = p.name not in ("a2", "c2", "c3")
    tests = parameter_tests(params, dof=100)
    assert set(tests) == {"a2", "c2", "c3"}
    crit = t_critical(0.95, 100)
    assert tests["a2"].t == pytest.approx(5.0) and tests["a2"].relative_std == pytest.approx(0.2)
    assert tests["a2"].ci == pytest.approx((a2.value - crit * 1e-4, a2.value + crit * 1e-4))
    assert tests["a2"].significant and tests["c2"].significant and not tests["c3"].significant
    assert tests["c3"].p == pytest.approx(t_two_sided_p(0.5, 100))
    # k = 1/c over c's interval; unbounded above where c's reaches 0
    lo, hi = tests["c2"].ci
    assert stiffness_interval(tests["c2"].ci) == pytest.approx((1 / hi, 1 / lo))
    assert stiffness_interval(tests["c3"].ci)[1] == math.inf
    assert stiffness_interval((-2e-8, -1e-9)) is None


def test_notes_name_what_to_drop_for_each_kind_of_term():
    """By hand, no fit: a joint, a harmonic, a whole term; the geometry is never the subject of a note."""
    from casadical.model import Model
    from casadical.stats import significance_notes

    model = Model(robot_from_dict(ARM4), "kinematic+compliance[2,3]+periodic[2:1,2:17,3:2]+encoder_scale[3]+drift")
    params = model.parameters.copy()
    strong = {"c2": 3e-7, "gear2_s1": 1e-4, "gear3_c2": 1e-4, "drift_x": 1e-6}   # t = 10
    for p in params:
        p.fixed = False
        p.value = p.nominal + strong.get(p.name, 0.1 * p.scale)     # t = 0.1 unless strong
        p.std = strong[p.name] / 10 if p.name in strong else p.scale
    params["gear2_c17"].value = 0.0
    notes = significance_notes(model, params, parameter_tests(params, dof=200))
    assert not any(n.startswith("geometric") for n in notes)
    by = {n.split(":")[0]: n for n in notes}
    assert set(by) == {"joint_compliance", "joint_periodic", "encoder_scale"}, notes
    assert by["joint_compliance"].startswith("joint_compliance: c3 (t = 0.10) is not significant (95 % level): the "
                                             "stiffness of joint 3 is not determined by these poses; drop the joint "
                                             "from the model (kinematic+joint_compliance[2]+")
    # a harmonic is named when neither its sine nor its cosine is significant
    assert "gear2_s17 (t = 0.10) and gear2_c17 (t = 0.00) are not significant" in by["joint_periodic"]
    assert "the periodic error at 17 cycles per turn of joint 2 is not determined" in by["joint_periodic"]
    assert "joint_periodic[2:1,3:2]" in by["joint_periodic"] and "gear3" not in by["joint_periodic"]
    assert "+encoder_scale[3]" not in by["encoder_scale"].split("(")[-1]       # the model without it
    # drift: one term of three components, significant when any is
    assert "drift" not in by


def test_log_likelihood_aic_bic_formulas():
    """Gaussian log-likelihood of the residuals in mm with the ML variance; k = free parameters."""
    rng = np.random.default_rng(0)
    r = rng.normal(scale=0.02, size=300)                # mm
    f = FitStatistics(300, 12, float(r @ r) * 1e-6)     # SSR in m^2
    s2 = r @ r / 300
    llf = float(np.sum(-0.5 * np.log(2 * np.pi * s2) - r ** 2 / (2 * s2)))
    assert f.log_likelihood == pytest.approx(llf, rel=1e-12)
    assert f.aic == pytest.approx(2 * 12 - 2 * llf) and f.bic == pytest.approx(12 * math.log(300) - 2 * llf)
    assert f.dof == 288 and f.sigma * 1000 == pytest.approx(math.sqrt(r @ r / 288))
    assert FitStatistics.from_dict(f.to_dict()) == pytest.approx(f) or \
        FitStatistics.from_dict(f.to_dict()).ssr == pytest.approx(f.ssr)


# --- hidden compliance on one joint, none on another -------------------------------------------------


@pytest.fixture(scope="module")
def fits():
    robot = robot_from_dict(ARM4)
    out = []
    for seed in SEEDS:
        data, truth = simulate(robot, 60, Effects(stiffness={2: STIFF}), seed=seed, floor_z=None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            true = calibrate(robot, data, TRUE)
        over = calibrate(robot, data, OVER, warn=False)
        under = calibrate(robot, data, UNDER, warn=False)
        out.append((truth, true, over, under, [w for w in caught if w.category is SignificanceWarning]))
    return out


def test_the_compliant_joint_is_significant_and_its_interval_covers_the_truth(fits):
    covered = 0
    for truth, res, _, _, _ in fits:
        t2 = res.significance()["c2"]
        assert t2.significant and t2.t > 5, t2
        covered += t2.ci[0] <= truth.value("c2") <= t2.ci[1]
        lo, hi = res.stiffness_intervals()[2]
        assert (lo <= STIFF <= hi) == (t2.ci[0] <= truth.value("c2") <= t2.ci[1])
        assert not any("c2 (t =" in n for n in res.notes)
    assert covered >= len(fits) - 1, covered


def test_the_stiff_joint_is_flagged_with_a_note_that_says_what_to_do(fits):
    flagged = 0
    for truth, res, _, _, warned in fits:
        t3 = res.significance()["c3"]
        assert "c3" not in truth.model.parameters      # the truth has no compliance on joint 3
        if t3.significant:
            continue
        flagged += 1
        note = next(n for n in res.notes if n.startswith("joint_compliance: c3 (t = "))
        assert f"c3 (t = {t3.t:.2f}) is not significant (95 % level)" in note
        assert "the stiffness of joint 3 is not determined by these poses" in note
        assert "drop the joint from the model (kinematic+joint_compliance[2])" in note
        assert [str(w.message) for w in warned] == [note]          # warned once, as the other notes
        assert "note: " + note in res.summary()
        # a compliance at its bound keeps that note too
        if res.parameters["c3"].value <= 1e-12:
            assert any(n.startswith("c3 is at its lower bound 0") and "not determined by these poses" in n
                       for n in res.notes)
    assert flagged >= len(fits) - 1, flagged


def test_aic_and_bic_prefer_the_true_model(fits):
    aic_wins = 0
    for _, true, over, under, _ in fits:
        s, so, su = true.statistics, over.statistics, under.statistics
        assert s.n_equations == so.n_equations == su.n_equations == 180
        assert so.n_parameters == s.n_parameters + 3 and su.n_parameters == s.n_parameters - 2
        assert s.bic < so.bic and s.bic < su.bic
        assert s.aic < su.aic
        aic_wins += s.aic < so.aic
    assert aic_wins >= len(fits) - 1


def test_summary_and_json_of_the_statistics(fits, tmp_path):
    truth, res, *_ = fits[0]
    text = res.summary()
    assert "significant at 95 % when |t| >" in text and "[0.025      0.975]" in text
    c3 = next(line for line in text.splitlines() if line.startswith("c3 "))
    assert c3.rstrip().endswith("free, not significant") or "free, not significant (" in c3
    assert f"AIC {res.statistics.aic:.2f}, BIC {res.statistics.bic:.2f}" in text
    res.save(tmp_path / "cal.json")
    doc = json.loads((tmp_path / "cal.json").read_text())
    # the contract's keys stay; the new ones are added
    assert {"robot", "model", "parameters", "calibration", "solver"} <= set(doc)
    s = doc["statistics"]
    assert s == pytest.approx(res.statistics.to_dict())
    assert s["dof"] == s["n_equations"] - s["n_parameters"] and s["level"] == 0.95
    by = {e["name"]: e for e in doc["parameters"]}
    for e in doc["parameters"]:
        assert {"name", "value", "std", "identifiable", "unit", "t", "p", "significant", "ci95",
                "relative_std"} <= set(e)
    test = res.significance()
    a = res.parameters["a2"]
    assert by["a2"]["t"] == pytest.approx(test["a2"].t)
    assert by["a2"]["ci95"] == pytest.approx([a.to_display(v) for v in test["a2"].ci])      # mm
    assert by["a2"]["relative_std"] == pytest.approx(a.std / abs(a.value - a.nominal))
    assert by["c3"]["significant"] is test["c3"].significant
    fixed = next(e for e in doc["parameters"] if e.get("fixed"))
    assert [fixed[k] for k in ("t", "p", "significant", "ci95", "relative_std")] == [None] * 5
    k2 = by["k2"]
    assert k2["significant"] is True and k2["ci95"] == pytest.approx(list(res.stiffness_intervals()[2]))


def test_calibration_files_with_and_without_the_new_keys(fits, tmp_path):
    _, res, *_ = fits[0]
    res.save(tmp_path / "new.json")
    doc = json.loads((tmp_path / "new.json").read_text())
    back = load_calibration(tmp_path / "new.json")
    assert back.statistics.to_dict() == pytest.approx(res.statistics.to_dict())
    again = json.loads(json.dumps(back.to_dict()))["parameters"]
    assert [sorted(e) for e in again] == [sorted(e) for e in doc["parameters"]]
    for e, f in zip(again, doc["parameters"]):       # equal up to the rounding of units back and forth
        for k, v in f.items():
            for x, y in zip(e[k] if isinstance(v, list) else [e[k]], v if isinstance(v, list) else [v]):
                assert x == (pytest.approx(y, rel=1e-9, abs=1e-15) if isinstance(y, float) else y), (k, e, f)
    # a file of an earlier version: no statistics, no tests; the fit's dof come from its 'uncertainty'
    del doc["statistics"]
    for e in doc["parameters"]:
        for k in ("t", "p", "significant", "ci95", "relative_std"):
            e.pop(k)
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = load_calibration(tmp_path / "old.json")
    assert old.statistics.dof == res.statistics.dof
    assert old.significance()["c2"].ci == pytest.approx(res.significance()["c2"].ci)
    np.testing.assert_allclose(old.predict(Measurements({"q1_deg": [0.0], "q2_deg": [10.0], "q3_deg": [20.0],
                                                         "q4_deg": [0.0]})),
                               res.predict(Measurements({"q1_deg": [0.0], "q2_deg": [10.0], "q3_deg": [20.0],
                                                         "q4_deg": [0.0]})), atol=1e-12)
    # nothing to go by: the normal distribution
    doc.pop("uncertainty")
    (tmp_path / "older.json").write_text(json.dumps(doc))
    assert load_calibration(tmp_path / "older.json").statistics is None
    assert load_calibration(tmp_path / "older.json").significance()["c2"].t == pytest.approx(
        res.significance()["c2"].t)


# --- calibrate --validate ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("validate")
    robot = robot_from_dict(ARM4)
    (d / "arm4.toml").write_text(to_toml(ARM4))
    cal, truth = simulate(robot, 50, Effects(stiffness={2: STIFF}), seed=11, floor_z=None)
    val, _ = simulate(robot, 40, truth=truth, seed=12, floor_z=None)
    cal.write_csv(d / "cal.csv")
    val.write_csv(d / "val.csv")
    return d


def _cli(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.strip().splitlines() if line]


def test_cli_calibrate_validate(files, tmp_path, capsys):
    out_json = tmp_path / "cal.json"
    code, out, _ = _cli(capsys, "calibrate", files / "arm4.toml", files / "cal.csv", "--model", TRUE,
                        "--validate", files / "val.csv", "--out", out_json)
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("validation poses ("))
    doc = json.loads(out_json.read_text())
    cal = load_calibration(out_json)
    val = Measurements.read_csv(files / "val.csv")
    stats = cal.stats(val)
    assert doc["validation"]["file"] == str(files / "val.csv") and doc["validation"]["n_poses"] == 40
    for k in ("mean_mm", "max_mm", "std_mm", "rms_mm"):
        assert doc["validation"][k] == pytest.approx(getattr(stats, k), rel=1e-9)
    assert f"mean {stats.mean_mm:.4f}" in line and f"rms {stats.rms_mm:.4f} mm over 40 poses" in line
    assert cal.validation.stats.mean_mm == pytest.approx(stats.mean_mm)
    assert stats.mean_mm < 0.1                        # the same robot: the noise, not a mismatch
    assert "fit: 150 equations" in out and "AIC" in out


def test_cli_validate_poses_are_checked_like_predict(files, tmp_path, capsys):
    """Poses of another robot, or beyond the limits: one line naming the validation file, nothing written."""
    out_json = tmp_path / "cal.json"
    other = robot_from_dict(ARM4)
    for j in other.joints:
        j.a, j.d = 1.3 * j.a + 0.2, 1.2 * j.d
    poses, _ = simulate(other, 30, Effects(), seed=5, floor_z=None)
    poses.write_csv(tmp_path / "other.csv")
    args = ["calibrate", files / "arm4.toml", files / "cal.csv", "--model", "kinematic", "--out", out_json,
            "--validate", tmp_path / "other.csv"]
    code, _, err = _cli(capsys, *args)
    assert code == 2 and not out_json.exists()
    assert len(err) == 1 and err[0].startswith("casadical: error: ") and "other.csv" in err[0]
    assert f"fitted to {files / 'cal.csv'}" in err[0] and "--allow-mismatch" in err[0]
    code, out, err = _cli(capsys, *args, "--allow-mismatch")
    assert code == 0 and out_json.exists() and any("mean error of" in e and "other.csv" in e for e in err)
    # beyond joint 2's limits (-80, 60 deg)
    text = (files / "val.csv").read_text().splitlines()
    head = text[0].split(",")
    row = text[3].split(",")
    row[head.index("q2_deg")] = "75"
    (tmp_path / "limits.csv").write_text("\n".join(text[:3] + [",".join(row)] + text[4:]) + "\n")
    code, _, err = _cli(capsys, "calibrate", files / "arm4.toml", files / "cal.csv", "--model", "kinematic",
                        "--out", tmp_path / "c2.json", "--validate", tmp_path / "limits.csv")
    assert code == 2 and not (tmp_path / "c2.json").exists()
    assert len(err) == 1 and "limits.csv, row 4, column 'q2_deg'" in err[0] and "--allow-outside-limits" in err[0]


def test_cli_validate_file_problems_stop_before_the_fit(files, tmp_path, capsys):
    (tmp_path / "nopos.csv").write_text("q1_deg,q2_deg,q3_deg,q4_deg\n0,0,0,0\n")
    for val, what in ((tmp_path / "nopos.csv", "x_mm"), (tmp_path / "none.csv", "none.csv")):
        code, out, err = _cli(capsys, "calibrate", files / "arm4.toml", files / "cal.csv", "--out",
                              tmp_path / "c.json", "--validate", val)
        assert code == 2 and out == "" and len(err) == 1 and what in err[0], err
    # the validation file is an input: never an output
    code, _, err = _cli(capsys, "calibrate", files / "arm4.toml", files / "cal.csv", "--out", files / "val.csv",
                        "--validate", files / "val.csv", "--force")
    assert code == 2 and "names an input file" in err[0]


def test_validate_in_python(files):
    robot = load_robot(files / "arm4.toml")
    cal = Measurements.read_csv(files / "cal.csv", n_joints=4, require_positions=True)
    val = Measurements.read_csv(files / "val.csv", n_joints=4, require_positions=True)
    res = calibrate(robot, cal, TRUE, warn=False)
    stats = res.validate(val)
    assert stats == res.validation.stats and res.validation.file == val.path
    assert stats.mean_mm == pytest.approx(res.stats(val).mean_mm)
    assert "validation poses (" in res.summary() and res.to_dict()["validation"]["n_poses"] == len(val)
