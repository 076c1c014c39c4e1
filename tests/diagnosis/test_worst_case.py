"""diagnose --worst-case (issue 38 item 4): where the final model's worst validation error is above a kinematic
calibration's, the report says which corrections to drop to restore it and what that costs in the mean; with
``worst_case`` that model is the final one."""

import math
import re
import runpy
from pathlib import Path

import numpy as np
import pytest

from casadical import load_robot
from casadical.data import Measurements
from casadical.diagnosis import DiagnosisSettings, diagnose

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "problems" / "datasets" / "ur10-ipa"
#: the example that teaches the worst case: this module runs it (tests/test_examples.py leaves it to this module)
EXAMPLE = ROOT / "examples" / "08_trust.py"


def test_worst_case_names_what_to_drop_and_drops_it_when_asked(monkeypatch, capsys):
    """UR10 series A, 300 calibration poses (seed 0), the rest held out: two poses at joint 2's end of range
    (-169 deg, inside the calibration poses' range, where few of them are) are missed 18 % worse than by the
    kinematic model; the note names what restores it at the least cost in the mean: periodic terms dropped, the
    GP compensator kept (it lowers the error there), far cheaper than dropping the GP compensator first; with
    worst_case the final model is that one, its worst error within 5 % of the kinematic's.

    These are examples/08_trust.py's two diagnoses: the example runs here, from the repository root as a user runs
    it (in this process, to read its reports; tests/test_examples.py leaves it to this test), and prints its key
    line; the poses it chose are checked against the seed's."""
    monkeypatch.chdir(ROOT)
    ran = runpy.run_path(str(EXAMPLE), run_name="__main__")
    assert "worst case restored: held-out mean / worst" in capsys.readouterr().out
    robot, cal, val, rep, safe = ran["robot"], ran["cal"], ran["val"], ran["report"], ran["safe"]
    src = Measurements.read_csv(DATA / "series_a.csv", n_joints=6)
    idx = np.sort(np.random.default_rng(0).permutation(len(src))[:300])
    assert robot.name == load_robot("ur10").name and len(cal) == 300 and len(val) == len(src) - 300
    np.testing.assert_array_equal(cal.q, src.subset(idx).q)
    np.testing.assert_array_equal(val.xyz, src.subset(np.setdiff1d(np.arange(len(src)), idx)).xyz)
    assert rep.to_dict()["settings"]["worst_case"] is False
    kin_max = next(s for s in rep.steps if s.model == "kinematic").validation.max_mm
    named = next(s for s in rep.steps if s.model.endswith("+gp_compensator")).parent_mm   # without the compensator
    note = next(n for n in rep.notes if n.startswith("worst case:"))
    assert rep.final_validation.max_mm > 1.05 * kin_max
    assert "cost in the validation mean" in note and "diagnose --worst-case makes that the final model" in note
    assert safe.final_validation.max_mm <= 1.05 * kin_max
    # cheaper than the named causes alone (the GP compensator dropped): what the note named before
    assert safe.final_validation.mean_mm < named, (safe.final_validation.mean_mm, named)
    assert f"{safe.final_validation.mean_mm:.4f} mm" in note
    dropped = [f.label() for f in rep.findings if f.in_model and f.label() not in {g.label() for g in safe.findings}]
    assert dropped and all(d in note for d in dropped), (dropped, note)
    if "gp_compensator" in safe.final_model:
        assert "the GP compensator kept" in note
    else:
        assert not any(f.cause == "unexplained" and "shrink" in f.holds_up for f in safe.findings)
    # why: joint 2 at -169 deg, in a gap of the calibration poses' readings wider than half harmonic 32's period
    assert re.search(r"why: joint 2 reads -16\d\.\d deg there, in a gap of the calibration poses' readings from "
                     r"-1\d\d\.\d to -1\d\d\.\d deg, wider than half the period of joint_periodic joint 2 harmonic 32",
                     note), note
    assert safe.to_dict()["settings"]["worst_case"] is True
    assert "--worst-case made that the final model" in next(n for n in safe.notes if n.startswith("worst case:"))


def test_the_screened_search_names_what_the_whole_search_names(monkeypatch):
    """The search refits in full only the causes its linearised screen ranks first (worst_case.SCREENED); on UR10
    series A (seed 2: 7 named causes, the note applies) it names the same drop at the same cost as refitting
    every kept cause in full. The stages before keep_worst_case (which no SCREENED changes) run once, as
    diagnose() runs them; the stage then runs with each setting on that run (without worst_case it only returns
    its note)."""
    from casadical.diagnosis import STAGES, DiagnosisRun
    from casadical.diagnosis import _worst_case as worst_case
    from casadical.runtime import limited_threads

    robot = load_robot("ur10")
    src = Measurements.read_csv(DATA / "series_a.csv", n_joints=6)
    idx = np.sort(np.random.default_rng(2).permutation(len(src))[:300])
    cal, val = src.subset(idx), src.subset(np.setdiff1d(np.arange(len(src)), idx))
    run = DiagnosisRun(robot, cal, val, DiagnosisSettings(seed=2), lambda _: None)
    notes = []
    with limited_threads():
        for stage in STAGES[:STAGES.index(worst_case.keep_worst_case)]:
            made = stage(run)
            if made is not None:
                run.install(made)
        if len(run.accepted) <= worst_case.SCREENED:
            pytest.skip(f"{len(run.accepted)} named causes here: the screen keeps them all (premise: more)")
        for screened in (worst_case.SCREENED, 1000):
            monkeypatch.setattr(worst_case, "SCREENED", screened)
            made = worst_case.keep_worst_case(run)
            assert made is not None and made.final is None and made.model is None   # without worst_case: a note
            notes.append(next(n for n in made.notes if n.startswith("worst case:")))
    assert notes[0] == notes[1], notes


def _gear_with_a_worn_stretch(c: float, w: float):
    """A gear error of 9 cycles per turn (0.02 deg) whose sign turns over ``w`` rad of the reading about ``c``: a
    worn or re-cut section, in no catalogue (its harmonic holds everywhere else)."""
    return lambda q: math.radians(0.02) * np.sin(9 * q + 0.7) * np.where(np.abs(q - c) < w / 2, -1.0, 1.0)


@pytest.mark.parametrize("arm, seed", [("arm7-dh", 0), ("arm7-dh", 1), ("arm5", 2)])
def test_the_worst_case_note_says_why_a_term_no_calibration_pose_checks(tmp_path, arm, seed):
    """Hidden: joint 3's gear error turns its sign over 40 deg of its reading (40 .. 80 deg), where no calibration
    pose lies (100 poses elsewhere); 40 of 200 validation poses lie there. The diagnosis names joint 3's ninth
    harmonic from the calibration poses; it doubles the error in the stretch, above the kinematic model's worst. The
    worst-case note must name the pose, drop the harmonic, and say why: the pose's reading of joint 3 in a gap of the
    calibration poses' readings that holds the stretch, wider than half the harmonic's period (40 deg)."""
    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARM5, ARM7_DH
    from tests.helpers.hidden import BASE_RPY, BASE_XYZ
    from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

    doc = {"arm7-dh": ARM7_DH, "arm5": ARM5}[arm]
    c, w = math.radians(60), math.radians(40)
    rng = np.random.default_rng(seed)
    true = TrueRobot.draw(Arm.from_dict(doc), Effects(reading_error={3: _gear_with_a_worn_stretch(c, w)}), rng)
    q = sample(true, 3000, rng, floor_z=None)
    worn = np.abs(q[:, 2] - c) < w / 2
    data = []
    for name, rows in (("cal", q[~worn][:100]), ("val", np.vstack([q[~worn][100:260], q[worn][:40]]))):
        shots = measure(true, rows, rng, session=Session("A", base_xyz=BASE_XYZ, base_rpy=BASE_RPY))
        data.append(Measurements.read_csv(shots.write_csv(tmp_path / f"{name}.csv"), n_joints=true.arm.n))
    cal, val = data
    rep = diagnose(robot_from_dict(doc, arm), cal, val, DiagnosisSettings(seed=seed))
    assert "joint_periodic[3:9]" in rep.final_model, rep.final_model
    note = next(n for n in rep.notes if n.startswith("worst case:"))
    line = int(re.search(r"val\.csv:(\d+)\)", note).group(1))
    assert line - 2 >= 160, note            # a pose of the worn stretch (the file's last 40 rows; header line 1)
    dropped = note.split("why:")[0].split("; without ")[1]
    assert dropped.startswith(("joint_periodic joint 3 harmonic 9", "every correction (the kinematic model)")), note
    m = re.search(r"why: joint 3 reads ([\d.]+) deg there, in a gap of the calibration poses' readings from ([\d.]+) "
                  r"to ([\d.]+) deg, wider than half the period of joint_periodic joint 3 harmonic 9 \(40\.00 deg\)",
                  note)
    assert m, note
    at, lo, hi = map(float, m.groups())
    assert lo <= 40.0 <= 80.0 <= hi and lo < at < hi, note
    assert abs(at - math.degrees(val.q[line - 2, 2])) < 0.06


@pytest.mark.parametrize("arm, seed", [("arm7-dh", 0), ("arm5", 1), ("arm5", 2)])
def test_the_worst_case_note_says_why_a_compliance_extrapolates(tmp_path, arm, seed):
    """Hidden: joint 2's drive stiffens under load (a cubic part that takes back 80 % of the linear compliance's
    deflection at the largest gravity torque, in no model the data can see: the 100 calibration poses load joint 2
    to at most 35 % of that torque); 40 of 200 validation poses load it beyond 85 %. The diagnosis names the
    compliance of joint 2, which extrapolates linearly to the loaded poses and misses them by more than the
    kinematic model does. The worst-case note must name a loaded pose, drop the compliance and say why: the
    joint's gravity torque there beyond the calibration poses' range."""
    from casadical.robot import robot_from_dict
    from tests.helpers.arms import ARM5, ARM7_DH
    from tests.helpers.hidden import BASE_RPY, BASE_XYZ
    from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

    doc = {"arm7-dh": ARM7_DH, "arm5": ARM5}[arm]
    rng = np.random.default_rng(seed)
    shape = Arm.from_dict(doc)
    q = sample(TrueRobot(shape), 4000, rng, floor_z=None)
    top = np.abs(TrueRobot(shape).state(q).drive_torque[:, 1]).max()
    k = top / 1.0e-3
    true = TrueRobot.draw(shape, Effects(stiffness={2: k}, cubic={2: -0.8 / (k * top ** 2)}), rng)
    tau = true.state(q).drive_torque[:, 1]
    light, loaded = np.abs(tau) < 0.35 * top, np.abs(tau) > 0.85 * top
    data = []
    for name, rows in (("cal", q[light][:100]), ("val", np.vstack([q[light][100:260], q[loaded][:40]]))):
        shots = measure(true, rows, rng, session=Session("A", base_xyz=BASE_XYZ, base_rpy=BASE_RPY))
        data.append(Measurements.read_csv(shots.write_csv(tmp_path / f"{name}.csv"), n_joints=true.arm.n))
    rep = diagnose(robot_from_dict(doc, arm), data[0], data[1], DiagnosisSettings(seed=seed))
    assert "joint_compliance[2]" in rep.final_model, rep.final_model
    note = next(n for n in rep.notes if n.startswith("worst case:"))
    assert int(re.search(r"val\.csv:(\d+)\)", note).group(1)) - 2 >= 160, note     # a loaded pose
    dropped = note.split("why:")[0].split("; without ")[1]
    assert dropped.startswith(("joint_compliance joint 2", "every correction (the kinematic model)")), note
    m = re.search(r"why: joint 2's gravity torque there, (-?[\d.]+) N m, lies beyond the calibration poses' "
                  r"\((-?[\d.]+) \.\. (-?[\d.]+) N m\): joint_compliance joint 2 extrapolates there", note)
    assert m, note
    at, lo, hi = map(float, m.groups())
    assert max(abs(lo), abs(hi)) < 0.37 * top and abs(at) > 0.8 * top, (at, lo, hi, top)
