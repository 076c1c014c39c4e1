"""diagnose --worst-case (issue 38 item 4): where the final model's worst validation error is above a kinematic
calibration's, the report says which corrections to drop to restore it and what that costs in the mean; with
``worst_case`` that model is the final one."""

from pathlib import Path

import numpy as np

from casadical import load_robot
from casadical.data import Measurements
from casadical.diagnosis import DiagnosisSettings, diagnose

DATA = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"


def test_worst_case_names_what_to_drop_and_drops_it_when_asked():
    """UR10 series A, 300 calibration poses (seed 0), the rest held out: two poses at joint 2's end of range
    (-169 deg, inside the calibration poses' range, where few of them are) are missed 18 % worse than by the
    kinematic model; the note names what restores it at the least cost in the mean: periodic terms dropped, the
    GP compensator kept (it lowers the error there), far cheaper than dropping the GP compensator first; with
    worst_case the final model is that one, its worst error within 5 % of the kinematic's."""
    robot = load_robot("ur10")
    src = Measurements.read_csv(DATA / "series_a.csv", n_joints=6)
    idx = np.sort(np.random.default_rng(0).permutation(len(src))[:300])
    cal, val = src.subset(idx), src.subset(np.setdiff1d(np.arange(len(src)), idx))
    rep = diagnose(robot, cal, val, DiagnosisSettings(seed=0))
    kin_max = next(s for s in rep.steps if s.model == "kinematic").validation.max_mm
    named = next(s for s in rep.steps if s.model.endswith("+gp_compensator")).parent_mm   # without the compensator
    note = next(n for n in rep.notes if n.startswith("worst case:"))
    assert rep.final_validation.max_mm > 1.05 * kin_max
    assert "cost in the validation mean" in note and "diagnose --worst-case makes that the final model" in note
    safe = diagnose(robot, cal, val, DiagnosisSettings(seed=0, worst_case=True))
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
    assert safe.to_dict()["settings"]["worst_case"] is True
    assert "--worst-case made that the final model" in next(n for n in safe.notes if n.startswith("worst case:"))


def test_the_screened_search_names_what_the_whole_search_names(monkeypatch):
    """The search refits in full only the causes its linearised screen ranks first (worst_case.SCREENED); on UR10
    series A (seed 2: 7 named causes, the note applies) it names the same drop at the same cost as refitting
    every kept cause in full."""
    from casadical.diagnosis import worst_case

    robot = load_robot("ur10")
    src = Measurements.read_csv(DATA / "series_a.csv", n_joints=6)
    idx = np.sort(np.random.default_rng(2).permutation(len(src))[:300])
    cal, val = src.subset(idx), src.subset(np.setdiff1d(np.arange(len(src)), idx))
    notes = []
    for screened in (worst_case.SCREENED, 1000):
        monkeypatch.setattr(worst_case, "SCREENED", screened)
        rep = diagnose(robot, cal, val, DiagnosisSettings(seed=2))
        notes.append(next(n for n in rep.notes if n.startswith("worst case:")))
    assert notes[0] == notes[1], notes
