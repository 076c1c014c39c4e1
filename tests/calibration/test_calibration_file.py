"""Calibration files: every malformed key of a calibration JSON is one line naming it, and a stiffness that
Levenberg-Marquardt leaves without a positive value is saved and reported (casadical/result.py; issue 10).
"""

import json
import warnings

import numpy as np
import pytest

from casadical import calibrate, load_calibration, load_robot
from casadical.data import Effects, simulate
from casadical.errors import CalibrationFileError
from tests.helpers.cli import cli, one_error


@pytest.fixture(scope="module")
def ys(tmp_path_factory):
    """Simulated YS100 calibration and validation files and a calibration JSON of them."""
    d = tmp_path_factory.mktemp("ys")
    robot = load_robot("ys100")
    cal, truth = simulate(robot, 30, Effects(), seed=3)
    val, _ = simulate(robot, 30, truth=truth, seed=4)
    cal.write_csv(d / "cal.csv")
    val.write_csv(d / "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        calibrate(robot, cal, "kinematic").save(d / "cal.json")
    return d


# --- calibration JSON -----------------------------------------------------------------------------


def _set(path, value):
    def mutate(doc):
        *head, last = path
        for k in head:
            doc = doc[k]
        if value is KeyError:
            del doc[last]
        else:
            doc[last] = value
    return mutate


@pytest.mark.parametrize("mutate,column", [
    (_set(["parameters", 3, "value"], float("nan")), "parameters[3].value"),
    (_set(["parameters", 3, "value"], "abc"), "parameters[3].value"),
    (_set(["parameters", 3, "value"], 10 ** 400), "parameters[3].value"),
    (_set(["parameters", 3, "std"], -1.0), "parameters[3].std"),
    (_set(["parameters", 3, "name"], "zzz"), "parameters[3].name"),
    (_set(["parameters", 4, "name"], "base_x"), "parameters[4].name"),
    (_set(["parameters", 3], 7), "parameters[3]"),
    (_set(["parameters", 3, "fixed"], "no"), "parameters[3].fixed"),
    (lambda d: d["parameters"].pop(5), "parameters"),
    (_set(["parameters"], {}), "parameters"),
    (_set(["base0"], [1, 2]), "base0"),
    (_set(["base0"], [2.0] * 12), "base0"),
    (_set(["base0", 0], 1e200), "base0"),     # found by the slow fuzz test (R^T R overflowed)
    (_set(["base0"], KeyError), "base0"),
    (_set(["model"], 5), "model"),
    (_set(["model"], "kinematic+compliance[9]"), "model"),
    (_set(["terms"], []), "terms"),
    (_set(["terms", "kinematic", "bogus"], 3), "terms.kinematic.bogus"),
    (_set(["terms", "kinematic", "length_box"], 0), "terms.kinematic.length_box"),
    (_set(["calibration"], {"a": 1}), "calibration.a"),
    (_set(["calibration", "mean_mm"], None), "calibration.mean_mm"),
    (_set(["notes"], 3), "notes"),
    (_set(["robot", "joint"], 3), "robot.joint"),
    (_set(["robot", "joint", 1, "a_m"], 1e300), "robot.joint[2].a_m"),
    (_set(["robot"], KeyError), "robot"),
    (_set(["coverage", "poses_deg"], 10 ** 400), "coverage.poses_deg"),     # found by the slow fuzz test
    (_set(["coverage", "q_min_deg", 2], 10 ** 400), "coverage.q_min_deg"),
    (_set(["coverage", "poses_deg", 1], [1.0]), "coverage.poses_deg[1]"),
    (_set(["coverage", "spacing_deg"], KeyError), "coverage.spacing_deg"),
    (_set(["parameters", 3, "t"], "x"), "parameters[3].t"),
    (_set(["parameters", 3, "p"], 1.5), "parameters[3].p"),
    (_set(["parameters", 3, "relative_std"], -0.1), "parameters[3].relative_std"),
    (_set(["parameters", 3, "significant"], "yes"), "parameters[3].significant"),
    (_set(["parameters", 3, "ci95"], [1.0]), "parameters[3].ci95"),
    (_set(["parameters", 3, "ci95"], [1.0, "x"]), "parameters[3].ci95"),
    (_set(["statistics"], 3), "statistics"),
    (_set(["statistics", "dof"], 5), "statistics.dof"),
    (_set(["statistics", "aic"], None), "statistics.aic"),
    (_set(["statistics", "sigma_mm"], 0.0), "statistics.sigma_mm"),
    (_set(["statistics", "n_equations"], 2.5), "statistics.n_equations"),
    (_set(["statistics", "n_equations"], 10 ** 400), "statistics.n_equations"),
    (_set(["statistics", "level"], 95), "statistics.level"),
    (_set(["statistics", "bic"], KeyError), "statistics.bic"),
    (_set(["statistics", "more"], 1), "statistics.more"),
    (_set(["validation"], {"file": 3, "n_poses": 9, "mean_mm": 1, "max_mm": 2, "std_mm": 0.5, "rms_mm": 1.1}),
     "validation.file"),
    (_set(["validation"], {"file": "v.csv", "n_poses": 9, "mean_mm": -1, "max_mm": 2, "std_mm": 0.5,
                           "rms_mm": 1.1}), "validation.mean_mm"),
    (_set(["validation"], [1]), "validation"),
    (_set(["uncertainty", "interval_k"], "wide"), "uncertainty.interval_k"),
    (_set(["uncertainty", "interval_k"], -2.8), "uncertainty.interval_k"),
    (_set(["uncertainty", "interval_k"], float("inf")), "uncertainty.interval_k"),
])
def test_malformed_calibration_json(ys, tmp_path, capsys, mutate, column):
    doc = json.loads((ys / "cal.json").read_text())
    mutate(doc)
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(CalibrationFileError) as e:
        load_calibration(tmp_path / "bad.json")
    assert e.value.column == column and e.value.file == str(tmp_path / "bad.json")
    code, _, err = cli(capsys, "predict", tmp_path / "bad.json", ys / "val.csv", "--out", tmp_path / "o.csv")
    assert code == 2
    one_error(err, "bad.json", repr(column))


@pytest.mark.parametrize("content", [b"", b"null", b"[1, 2]", b"{\"robot\": ", b"\xff\xfe{}", b"[" * 100000])
def test_not_a_calibration_json(tmp_path, content):
    (tmp_path / "x.json").write_bytes(content)
    with pytest.raises(CalibrationFileError):
        load_calibration(tmp_path / "x.json")


# --- Levenberg-Marquardt on a stiff joint ----------------------------------------------------------


def test_lm_with_compliance_below_zero_is_saved_and_reported(tmp_path, capsys):
    """A stiff joint (true compliance ~0): LM comes out negative on some seeds, never inf stiffness."""
    robot = load_robot("ys100")
    negative = 0
    for seed in range(4):
        data, _ = simulate(robot, 40, Effects(stiffness={2: 1.5e6, 3: 1e12}), seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = calibrate(robot, data, "kinematic+compliance[2,3]", "lm")
        c3 = res.parameters["c3"].value
        res.save(tmp_path / f"lm{seed}.json")
        doc = json.loads((tmp_path / f"lm{seed}.json").read_text())
        k3 = next(p for p in doc["parameters"] if p["name"] == "k3")
        if c3 <= 0:
            negative += 1
            assert k3["value"] is None and "no positive stiffness" in k3["reason"]
            assert "no positive stiffness" in res.summary()
            data.write_csv(tmp_path / f"stiff{seed}.csv")
            code, out, _ = cli(capsys, "calibrate", "ys100", tmp_path / f"stiff{seed}.csv", "--solver", "lm",
                               "--model", "kinematic+compliance[2,3]", "--out", tmp_path / f"cli{seed}.json")
            assert code == 0 and "k3: no positive stiffness" in out and (tmp_path / f"cli{seed}.json").exists()
        else:
            assert k3["value"] == pytest.approx(1 / c3)
        back = load_calibration(tmp_path / f"lm{seed}.json")
        np.testing.assert_allclose(back.predict(data), res.predict(data), atol=1e-12)
    assert negative >= 1
