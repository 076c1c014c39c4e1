"""The seed papers' methods by name, their claims on simulated robots, and ``compare``."""

import json
import math
import sys

import numpy as np
import pytest

from casadical import cli
from casadical.data import Effects, simulate
from casadical.errors import InputError
from casadical.loading import load_robot
from casadical.methods import MethodResult, compare, format_table, method_names, run_method
from casadical.model import Model
from casadical.terms import make_term

ROBOT = load_robot("ys100")
K = {2: 1.73e6, 3: 1.203e6, 4: 0.299e6, 5: 0.5724e6}          # the CA paper's Table 3
BASE = dict(base_xyz=(2.5, -1.0, 0.2), base_rpy=(0.0, 0.0, math.radians(150.0)))
FAST = {"NN-SKCM": {"epochs": 300, "folds": 3}, "TLBO-NN-SKCM": {"epochs": 30, "folds": 3},
        "GA-RBF": {"folds": 3}, "SKCM-CA": {"generations": 40}, "SKCM-GA": {"generations": 40},
        "SKCM-IPOPT-CA": {"generations": 30}, "SKCM-IPOPT-GA": {"generations": 30},
        "SKCM-IPOPT-TLBO": {"generations": 30}}


def cell(n, seed, wrist=45.0):
    """Poses in a cell in front of the robot (the papers' restricted workspaces)."""
    lo = np.radians([-45, 45, -10, -wrist, -wrist, -wrist])
    hi = np.radians([45, 105, 60, wrist, wrist, wrist])
    return np.random.default_rng(seed).uniform(lo, hi, (n, 6))


def sets(effects, seed, n_cal=30, n_val=40, n_extra=None, q=None):
    cal, truth = simulate(ROBOT, q(n_cal, seed) if q else n_cal, effects, seed=seed)
    val, _ = simulate(ROBOT, q(n_val, seed + 100) if q else n_val, truth=truth, seed=seed + 100)
    extra = None
    if n_extra:
        extra, _ = simulate(ROBOT, q(n_extra, seed + 200) if q else n_extra, truth=truth, seed=seed + 200)
    return cal, val, extra, truth


@pytest.fixture(scope="module")
def small():
    return sets(Effects(stiffness=K, **BASE), 7, n_cal=20, n_val=15, n_extra=20)


def test_registry_lists_the_papers_methods():
    names = method_names()
    for n in ("Nominal", "KM", "SKCM", "SKCM-CA", "SKCM-GA", "GA-RBF", "NN-SKCM", "TLBO-NN-SKCM",
              "SKCM-IPOPT-CA", "SKCM-IPOPT-GA", "SKCM-IPOPT-TLBO"):
        assert n in names
    assert names[:3] == ["Nominal", "KM", "SKCM"]


def test_bad_name_and_setting_are_one_line():
    with pytest.raises(InputError) as e:
        run_method("SKCM-XX", ROBOT, None)
    msg = str(e.value)
    assert "\n" not in msg and "SKCM-XX" in msg and "SKCM-CA" in msg and "TLBO-NN-SKCM" in msg
    with pytest.raises(InputError, match="unknown setting"):
        run_method("KM", ROBOT, None, bogus=1)


@pytest.mark.parametrize("name", method_names())
def test_each_method_runs(name, small):
    cal, val, extra, truth = small
    r = run_method(name, ROBOT, cal, val, extra=extra, seed=1, **FAST.get(name, {}))
    assert isinstance(r, MethodResult) and r.name == name
    assert r.calibration.n_poses == 20 and r.validation.n_poses == 15 and r.extra.n_poses == 20
    assert r.time_s > 0 and np.isfinite(r.validation.mean_mm)
    assert r.predict(val).shape == (15, 3)
    assert np.isclose(r.stats(val).mean_mm, r.validation.mean_mm)
    d = r.to_dict()
    assert set(d["calibration"]) == {"mean_mm", "max_mm", "std_mm", "rms_mm"}
    json.dumps(d, allow_nan=False)
    if name == "Nominal":
        assert r.validation.mean_mm > 1.0
    elif name not in ("KM", "GA-RBF"):
        # every compliance method reaches the noise floor (20 um per axis) on this robot
        assert r.validation.mean_mm < 0.1, r.validation


@pytest.mark.parametrize("name", ["SKCM-CA", "SKCM-GA"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_two_phase_recovers_planted_stiffness(name, seed):
    cal, val, _, truth = sets(Effects(stiffness=K, **BASE), seed, n_cal=30, n_val=10)
    r = run_method(name, ROBOT, cal, val, seed=seed)
    k = r.stiffness()
    for j, kt in K.items():
        assert abs(k[j] / kt - 1.0) < 0.05, (j, k[j], kt)
    assert r.info["rounds"] and r.info["nfev"] > 100
    # the metaheuristic's answer is as good as the simultaneous least squares'
    sk = run_method("SKCM", ROBOT, cal, val)
    assert r.calibration.rms_mm < 1.1 * sk.calibration.rms_mm


def test_global_start_matches_skcm():
    cal, val, _, truth = sets(Effects(stiffness=K, **BASE), 4, n_cal=30, n_val=20)
    r = run_method("SKCM-IPOPT-TLBO", ROBOT, cal, val, seed=4, generations=40)
    sk = run_method("SKCM", ROBOT, cal, val)
    assert abs(r.calibration.rms_mm - sk.calibration.rms_mm) < 1e-4
    assert r.info["starts"] and r.info["nfev"] > 0


def test_global_start_finds_a_far_joint_offset():
    """A joint zero 150 deg off: IPOPT from nominal ends in a wrong minimum; from the CA's points it does not."""
    cal, val, _, truth = sets(Effects(stiffness=K, **BASE), 1, n_cal=25, n_val=20)
    vals = truth.values.copy()
    vals[truth.model.parameters.index("theta3")] += math.radians(150.0)
    rng = np.random.default_rng(0)
    cal, val = (d.with_positions(truth.model.predict(d.q, vals, truth.model.covariates(d), truth.base0)
                                 + rng.normal(0, 2e-5, (len(d), 3))) for d in (cal, val))
    model = Model(ROBOT, [make_term("kinematic", angle_box=math.pi),
                          make_term("joint_compliance", joints=[2, 3, 4, 5])])
    from casadical.calibration import calibrate
    # the nominal model misses these poses by 1.2 m (a third of the reach): a robot file this far off is refused
    # unless the user says so (issue 21); the override marks the poses, so the method below takes them too
    local = calibrate(ROBOT, cal, model, "ipopt", warn=False, allow_mismatch=True)
    assert local.stats(val).mean_mm > 10.0
    r = run_method("SKCM-IPOPT-CA", ROBOT, cal, val, seed=1, model=model,
                   params_box={"theta3": (-math.pi, math.pi)}, generations=40)
    assert r.validation.mean_mm < 0.1
    assert abs(math.degrees(r.result.parameters["theta3"].value) - 150.0) < 0.5


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_ga_rbf_compensates_unmodelled_compliance(seed):
    # KM does not model compliance; in a cell with the wrist nearly still, the torques tell the pose
    cal, val, _, _ = sets(Effects(stiffness=K, **BASE), seed, n_cal=40, n_val=60, q=lambda n, s: cell(n, s, 10.0))
    km = run_method("KM", ROBOT, cal, val)
    rbf = run_method("GA-RBF", ROBOT, cal, val, seed=seed)
    assert rbf.compensator is not None
    assert rbf.validation.mean_mm < 0.95 * km.validation.mean_mm
    assert rbf.calibration.mean_mm > 0      # fewer centres than poses: not an interpolant


@pytest.mark.parametrize("name,seeds,limit", [("NN-SKCM", [1, 2, 3], 0.8), ("TLBO-NN-SKCM", [1, 2], 0.9)])
def test_networks_compensate_a_gear_error(name, seeds, limit):
    # a periodic gear error of joint 3 (2 per turn, 0.05 deg) is not in the SKCM model
    eff = Effects(stiffness=K, periodic=[(3, 2, math.radians(0.05), 0.5)], **BASE)
    for seed in seeds:
        cal, val, extra, _ = sets(eff, seed, n_cal=30, n_val=60, n_extra=60, q=cell)
        sk = run_method("SKCM", ROBOT, cal, val)
        r = run_method(name, ROBOT, cal, val, extra=extra, seed=seed,
                       **({"epochs": 1500} if name == "NN-SKCM" else {}))
        assert r.info["compensator"]["trained_on"] == "extra"
        assert r.validation.mean_mm < limit * sk.validation.mean_mm, (seed, r.validation, sk.validation)


@pytest.mark.parametrize("seed", [1, 3])
def test_compensators_do_not_blow_up_on_noise(seed):
    cal, val, extra, _ = sets(Effects(stiffness=K, **BASE), seed, n_cal=30, n_val=60, n_extra=50)
    sk = run_method("SKCM", ROBOT, cal, val)
    for name, kw in (("NN-SKCM", {"epochs": 1500}), ("TLBO-NN-SKCM", {"epochs": 200})):
        r = run_method(name, ROBOT, cal, val, extra=extra, seed=seed, **kw)
        assert r.validation.mean_mm < 1.15 * sk.validation.mean_mm, (name, r.validation, sk.validation)
    cal, val, _, _ = sets(Effects(**BASE), seed, n_cal=30, n_val=60)
    km = run_method("KM", ROBOT, cal, val)
    rbf = run_method("GA-RBF", ROBOT, cal, val, seed=seed)
    assert rbf.validation.mean_mm < 1.15 * km.validation.mean_mm


def test_same_seed_same_result(small):
    cal, val, extra, _ = small
    a = compare(ROBOT, cal, val, extra, "SKCM-CA,TLBO-NN-SKCM", seed=5,
                settings={k: FAST[k] for k in ("SKCM-CA", "TLBO-NN-SKCM")})
    b = compare(ROBOT, cal, val, extra, "SKCM-CA,TLBO-NN-SKCM", seed=5,
                settings={k: FAST[k] for k in ("SKCM-CA", "TLBO-NN-SKCM")})
    for ra, rb in zip(a, b):
        assert ra.validation.mean_mm == rb.validation.mean_mm
        assert ra.stiffness() == rb.stiffness()
    text = format_table(a)
    assert "SKCM-CA" in text and "validation (15 poses)" in text and "time (s)" in text


@pytest.fixture
def compare_cli():
    return cli.main


def test_compare_cli_writes_the_json(compare_cli, small, tmp_path, capsys):
    cal, val, _, _ = small
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    out = tmp_path / "out.json"
    args = ["compare", "ys100", str(tmp_path / "cal.csv"), "--validate", str(tmp_path / "val.csv"),
            "--json", str(out), "--methods", "KM,skcm", "--seed", "3"]
    assert compare_cli(args) == 0
    text = capsys.readouterr().out
    assert "KM" in text and "SKCM" in text and "mean" in text and "time (s)" in text
    doc = json.loads(out.read_text())
    assert [m["name"] for m in doc["methods"]] == ["KM", "SKCM"]
    for m in doc["methods"]:
        assert {"name", "calibration", "validation", "time_s"} <= set(m)
        for s in ("calibration", "validation"):
            assert set(m[s]) == {"mean_mm", "max_mm", "std_mm", "rms_mm"}
            assert m[s]["mean_mm"] <= m[s]["rms_mm"] <= m[s]["max_mm"]
        assert m["time_s"] > 0
    # refuses to overwrite without --force
    before = out.read_text()
    assert compare_cli(args) == 2
    assert "exists already" in capsys.readouterr().err and out.read_text() == before


def test_compare_cli_plot(compare_cli, small, tmp_path, capsys, monkeypatch):
    cal, val, _, _ = small
    cal.write_csv(tmp_path / "cal.csv")
    val.write_csv(tmp_path / "val.csv")
    png = tmp_path / "bars.png"
    args = ["compare", "ys100", str(tmp_path / "cal.csv"), "--validate", str(tmp_path / "val.csv"),
            "--methods", "Nominal,KM", "--plot", str(png)]
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        pass
    else:
        assert compare_cli(args) == 0
        assert png.read_bytes()[:4] == b"\x89PNG"
    monkeypatch.setitem(sys.modules, "matplotlib", None)     # as if it were not installed
    capsys.readouterr()
    assert compare_cli(args + ["--force"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "matplotlib" in err[0]


def test_compare_cli_bad_method_is_one_line(compare_cli, small, tmp_path, capsys):
    cal, _, _, _ = small
    cal.write_csv(tmp_path / "cal.csv")
    assert compare_cli(["compare", "ys100", str(tmp_path / "cal.csv"), "--methods", "KM,CA-SKCM"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "CA-SKCM" in err[0] and "SKCM-IPOPT-TLBO" in err[0]
