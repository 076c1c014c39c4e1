"""``casadical export``: URDF, CSV and Markdown parameter tables from a calibration or a robot."""

import csv
import json
import math
import warnings

import numpy as np
import pytest
import yourdfpy

from casadical import calibrate, load_calibration, load_robot
from casadical.apply import COLUMNS, parameter_table
from casadical.cli import main
from casadical.data import Effects, simulate
from casadical.robot import robot_from_dict
from tests.helpers.arms import ARM7_DH


def read_table(path) -> tuple[str, list[dict]]:
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# ")
    return lines[0], list(csv.DictReader(lines[1:]))


def number(cell: str) -> float:
    return math.nan if cell == "" else float(cell)


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    """A YS100 calibrated on simulated data with two compliant joints; the JSON and the data."""
    folder = tmp_path_factory.mktemp("cal")
    robot = load_robot("ys100")
    data, truth = simulate(robot, 60, Effects(stiffness={2: 1.5e6, 3: 9e5}, base_xyz=(2.0, -1.0, 0.5),
                                              base_rpy=(0.0, 0.02, 1.2)), seed=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = calibrate(robot, data, "kinematic+compliance[2,3]")
    path = folder / "cal.json"
    result.save(path)
    return path, result, data


def test_export_writes_urdf_csv_and_markdown(tmp_path, calibration):
    cal_path, result, data = calibration
    out = {k: tmp_path / f"out.{k}" for k in ("urdf", "csv", "md")}
    args = ["export", str(cal_path), "--urdf", str(out["urdf"]), "--table", str(out["csv"]),
            "--markdown", str(out["md"]), "--quiet", "--as-fitted"]
    assert main(args) == 0
    doc = json.loads(cal_path.read_text())

    # the table's numbers are the calibration JSON's (to 15 significant digits)
    title, rows = read_table(out["csv"])
    assert "YS100" in title and "MDH" in title and "Rx(alpha) Tx(a) Rz(q + theta) Tz(d)" in title
    assert "Hayati's Ry(beta) Ty(b) after Tx(a)" in title
    assert list(rows[0]) == list(COLUMNS)
    by_name = {r["name"]: r for r in rows}
    expected = [p for p in doc["parameters"]
                if (p.get("term") == "geometric" and not p["name"].startswith("base_"))
                or p.get("term") == "joint_compliance" or p.get("derived")]
    assert len(rows) == len(expected) + 6          # plus the six base pose rows
    for p in expected:
        r = by_name[p["name"]]
        assert number(r["identified"]) == pytest.approx(p["value"], rel=1e-14) and r["unit"] == p["unit"]
        assert (r["std"] == "") == (p["std"] is None)
        if p["std"] is not None:
            assert number(r["std"]) == pytest.approx(p["std"], rel=1e-14)
        assert r["identifiable"] == ("true" if p["identifiable"] else "false")
        if not p.get("derived"):
            assert number(r["nominal"]) == pytest.approx(p["nominal"], rel=1e-14)
            assert number(r["difference"]) == pytest.approx(p["value"] - p["nominal"], abs=1e-12)
            assert r["fixed"] == ("true" if p["fixed"] else "false") and r["reason"] == p["reason"]
    for k, axis in enumerate("xyz"):
        assert number(by_name[f"base_pose_{axis}"]["identified"]) == pytest.approx(
            doc["base_pose"]["xyz_m"][k] * 1000, abs=1e-9)
    for k, axis in enumerate(("roll", "pitch", "yaw")):
        assert number(by_name[f"base_pose_{axis}"]["identified"]) == pytest.approx(
            doc["base_pose"]["rpy_deg"][k], abs=1e-9)
    assert {"c2", "c3", "k2", "k3"} <= set(by_name)
    assert number(by_name["k2"]["identified"]) == pytest.approx(1.5e6, rel=0.05)     # the hidden stiffness

    # Markdown: same rows, the convention in the header
    md = out["md"].read_text().splitlines()
    assert md[0] == "# YS100: MDH parameter table with Hayati's beta on joints 1, 3"
    # the parameters' rows and header, then the base as a pose: its header and its one row
    assert sum(line.startswith("| ") for line in md) == (len(rows) - 6 + 1) + 2
    assert md[-3] == "| x (mm) | y (mm) | z (mm) | roll (deg) | pitch (deg) | yaw (deg) |"
    assert md[-1] == "| " + " | ".join(f"{number(by_name['base_pose_' + a]['identified']):.{4 if a in 'xyz' else 6}f}"
                                       for a in ("x", "y", "z", "roll", "pitch", "yaw")) + " |"
    assert all(by_name[f"base_pose_{a}"]["nominal"] == by_name[f"base_pose_{a}"]["difference"] == "" for a in "xyz")

    # URDF of the loaded JSON: yourdfpy's forward kinematics is the calibration's prediction
    u = yourdfpy.URDF.load(str(out["urdf"]), load_meshes=False)
    xyz = []
    for q in data.q[:10]:
        u.update_cfg(q)
        xyz.append(u.get_transform("tool_point", "measurement_frame")[:3, 3])
    geometric_only = result.model.predict(data.q[:10], np.where(
        [p.term == "joint_compliance" for p in result.parameters], 0.0, result.parameters.values), base0=result.base0)
    assert np.abs(np.array(xyz) - geometric_only).max() < 1e-9
    text = out["urdf"].read_text()
    assert "joint compliance (stiffness)" in text and "terms left out: joint_compliance[2,3]" in text


def urdf_errors(path, data) -> np.ndarray:
    """Position errors (mm) of a URDF's tool point on measured poses, by yourdfpy's forward kinematics."""
    u = yourdfpy.URDF.load(str(path), load_meshes=False)
    xyz = []
    for q in data.q:
        u.update_cfg(q)
        xyz.append(u.get_transform("tool_point", "measurement_frame")[:3, 3])
    return np.linalg.norm(np.array(xyz) - data.xyz, axis=1) * 1000


ARMS = {"YS100 (MDH)": ("ys100", Effects(stiffness={2: 1.5e6, 3: 9e5}, periodic=[(2, 17, math.radians(0.01), 0.4)])),
        "seven-axis DH": (ARM7_DH, Effects(stiffness={2: 2e4, 4: 1e4}))}


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_the_exported_geometry_is_the_best_geometry(tmp_path, capsys, arm):
    """A model with terms a URDF cannot carry, exported: the URDF (read by yourdfpy, an independent library)
    predicts held-out measurements no worse than the URDF of a kinematic calibration of the same poses (within
    1 %), and better than the model's own geometry as fitted; what the geometry leaves is printed."""
    spec_robot, effects = ARMS[arm]
    robot = load_robot(spec_robot) if isinstance(spec_robot, str) else robot_from_dict(spec_robot)
    cal, truth = simulate(robot, 150, effects, seed=3, floor_z=None)
    val, _ = simulate(robot, 150, truth=truth, seed=4, floor_z=None)
    terms = "+".join([f"joint_compliance[{','.join(map(str, sorted(effects.stiffness)))}]"]
                     + ([f"joint_periodic[{effects.periodic[0][0]}:{effects.periodic[0][1]}]"]
                        if effects.periodic else []))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = calibrate(robot, cal, "kinematic+" + terms, "lm")
        kin = calibrate(robot, cal, "kinematic", "lm")
    full.save(tmp_path / "full.json")
    kin.save(tmp_path / "kin.json")
    paths = {k: tmp_path / f"{k}.urdf" for k in ("best", "fitted", "kin")}
    capsys.readouterr()
    assert main(["export", str(tmp_path / "full.json"), "--urdf", str(paths["best"])]) == 0
    said = capsys.readouterr().err
    assert "departs from the full model by" in said and "the full model (compensate) gives the rest" in said
    assert main(["export", str(tmp_path / "full.json"), "--urdf", str(paths["fitted"]), "--as-fitted", "-q"]) == 0
    assert main(["export", str(tmp_path / "kin.json"), "--urdf", str(paths["kin"]), "-q"]) == 0
    e = {k: urdf_errors(p, val).mean() for k, p in paths.items()}
    assert e["best"] <= 1.01 * e["kin"], e
    assert e["best"] < 0.9 * e["fitted"], e
    assert "refitted to reproduce the full model" in paths["best"].read_text()


def test_export_refuses_to_overwrite(tmp_path, calibration):
    cal_path, _, _ = calibration
    table = tmp_path / "t.csv"
    assert main(["export", str(cal_path), "--table", str(table), "-q"]) == 0
    table.write_text("the user's own notes\n")
    urdf = tmp_path / "new.urdf"
    assert main(["export", str(cal_path), "--urdf", str(urdf), "--table", str(table), "-q"]) == 2
    assert table.read_text() == "the user's own notes\n" and not urdf.exists()   # nothing written at all
    assert main(["export", str(cal_path), "--urdf", str(urdf), "--table", str(table), "--force", "-q"]) == 0
    assert table.read_text().startswith("# YS100") and urdf.exists()
    assert main(["export", str(cal_path), "--table", str(cal_path), "--force"]) == 2   # never over an input


def test_export_needs_an_output_and_says_what_urdf_cannot_carry(tmp_path, capsys):
    assert main(["export", "ys100"]) == 2
    assert "nothing to write" in capsys.readouterr().err
    # the HH800's parallelogram loop has no URDF form: one line, and the table is not written either
    table, urdf = tmp_path / "t.csv", tmp_path / "h.urdf"
    assert main(["export", "hh800", "--table", str(table), "--urdf", str(urdf)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "four-bar loop" in err[0] and "Traceback" not in err[0]
    assert not table.exists() and not urdf.exists()


def test_payload_is_the_load_the_geometry_is_refitted_at(tmp_path, capsys, calibration):
    """--payload-kg chooses the best geometry of a compliant model (another load, another geometry); with
    --as-fitted or a robot it has no meaning (one line), and with a model that no load changes it is a warning."""
    cal_path, _, data = calibration
    urdfs = {}
    for kg in ("0", "110"):
        urdfs[kg] = tmp_path / f"p{kg}.urdf"
        assert main(["export", str(cal_path), "--urdf", str(urdfs[kg]), "--payload-kg", kg, "-q"]) == 0
    assert urdfs["0"].read_text() != urdfs["110"].read_text()
    for args, words in ((["--as-fitted"], "give one of the two"), ([], "is a robot")):
        source = str(cal_path) if args else "ys100"
        assert main(["export", source, "--urdf", str(tmp_path / "x.urdf"), "--payload-kg", "5", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--payload-kg" in err[0] and words in err[0]
        assert not (tmp_path / "x.urdf").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        calibrate(load_robot("ys100"), data, "kinematic").save(tmp_path / "kin.json")
    assert main(["export", str(tmp_path / "kin.json"), "--urdf", str(tmp_path / "k.urdf"), "--payload-kg", "5"]) == 0
    assert "--payload-kg 5: no effect" in capsys.readouterr().err


def test_nominal_robot_table(tmp_path):
    out = tmp_path / "ur10.csv"
    assert main(["export", "ur10", "--table", str(out), "-q"]) == 0
    title, rows = read_table(out)
    assert "standard DH" in title
    robot = load_robot("ur10")
    table = parameter_table(robot)
    assert [r["name"] for r in rows] == [r.name for r in table.rows]
    a2 = next(r for r in rows if r["name"] == "a2")
    assert number(a2["nominal"]) == number(a2["identified"]) == robot.joints[1].a * 1000
    assert all(r["std"] == "" and r["fixed"] == "true" and r["difference"] in ("0.0", "-0.0") for r in rows)
    assert not any(r["name"].startswith(("c", "k")) for r in rows)


def test_loaded_calibration_gives_the_same_table(calibration):
    cal_path, result, _ = calibration
    fresh, loaded = parameter_table(result), parameter_table(load_calibration(cal_path))
    for a, b in zip(fresh.rows, loaded.rows):
        assert a.name == b.name
        np.testing.assert_allclose([a.nominal, a.identified, a.std], [b.nominal, b.identified, b.std],
                                   rtol=1e-12, atol=1e-12)


def test_help(capsys):
    with pytest.raises(SystemExit) as e:
        main(["export", "--help"])
    assert e.value.code == 0 and "--urdf" in capsys.readouterr().out


def test_readme_export_is_no_worse_than_a_kinematic_calibration(tmp_path, capsys):
    """The README's flow on the real UR10 data (series B, 300 calibration poses): the diagnosed final model,
    exported, gives a URDF whose forward kinematics (yourdfpy) predicts the 1,195 held-out poses no worse than
    a kinematic calibration's URDF (within 1 %: 0.4048 against 0.4036 mm; the diagnosed model's own geometry
    gave 0.94 mm against 0.41 mm), and the DH table holds the same geometry."""
    from pathlib import Path

    from casadical.data import Measurements

    series_b = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa" / "series_b.csv"
    cal, val = tmp_path / "cal.csv", tmp_path / "val.csv"
    assert main(["split", str(series_b), "-n", "300", "--seed", "0", "--out-cal", str(cal), "--out-val", str(val)]) == 0
    final, kin = tmp_path / "final.json", tmp_path / "kin.json"
    assert main(["diagnose", "ur10", str(cal), "--validate", str(val), "--json", str(tmp_path / "r.json"),
                 "--out", str(final), "-q"]) == 0
    assert main(["calibrate", "ur10", str(cal), "--model", "kinematic", "--out", str(kin)]) == 0
    capsys.readouterr()
    urdf, table = tmp_path / "final.urdf", tmp_path / "final.csv"
    assert main(["export", str(final), "--urdf", str(urdf), "--table", str(table)]) == 0
    assert "departs from the full model by" in capsys.readouterr().err
    assert main(["export", str(kin), "--urdf", str(tmp_path / "kin.urdf"), "-q"]) == 0
    data = Measurements.read_csv(val, n_joints=6, require_positions=True)
    best, plain = urdf_errors(urdf, data).mean(), urdf_errors(tmp_path / "kin.urdf", data).mean()
    assert best <= 1.01 * plain, (best, plain)
    title, rows = read_table(table)
    assert "refitted to reproduce the full model" in title
    a2 = next(r for r in rows if r["name"] == "a2")
    u = yourdfpy.URDF.load(str(urdf), load_meshes=False)
    assert u is not None and abs(number(a2["identified"])) > 600     # the table is the exported geometry's (mm)
