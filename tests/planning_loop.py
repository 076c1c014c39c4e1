"""The planning loop on simulated data (tests and benchmarks/study_next_poses.py).

A cause the first poses cannot resolve is hidden in an arm measured by the
independent truth (tests/truth: its own forward model, no casadical code);
the diagnosis reports an open question; ``plan-poses REPORT.json`` picks M
of a work cell's candidates (most repeat the measured region, a few reach
beyond it); the picked poses are "measured" on the same true robot and the
diagnosis of both sets must name the cause. M random candidates of the same
pool are the baseline.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from casadical.cli import main
from casadical.data import Measurements
from truth import Arm, Effects, TrueRobot, measure as shoot, sample

from arms import ARM5, ARM7_DH, to_toml


@dataclass
class Scenario:
    """A hidden cause, the narrow region the first poses cover, and where the few far candidates reach."""

    name: str
    arm: dict
    effects: Effects
    narrow: dict                     # joint (1-based) -> (lo_deg, hi_deg) of the measured region
    n_cal: int = 60
    m: int = 10
    truth: tuple = ()                # (cause, joint, harmonic) the diagnosis must name
    rival: tuple = ()                # the alternative it must no longer be ambiguous with


SCENARIOS = {
    # a scale error of joint 2 over 40 deg of its range: a first harmonic fits as well
    "narrow range": Scenario("narrow range", ARM5, Effects(encoder_scale={2: 6e-4}), {2: (40, 80)},
                             truth=("encoder_scale", 2, None), rival=("joint_periodic", 2, 1)),
    # a gear error of harmonic 19 on joint 1 over 30 deg: harmonics 18..21 fit about as well
    "harmonic band": Scenario("harmonic band", ARM7_DH, Effects(periodic=[(1, 19, math.radians(0.01), 0.7)]),
                              {1: (-15, 15)}, truth=("joint_periodic", 1, 19)),
}


def region(robot: TrueRobot, sc: Scenario, n: int, rng) -> np.ndarray:
    q = sample(robot, n, rng, floor_z=None)
    for j, (lo, hi) in sc.narrow.items():
        q[:, j - 1] = np.radians(rng.uniform(lo, hi, n))
    return q


def setup(sc: Scenario, seed: int, folder, n_candidates: int = 500, n_far: int = 15) -> dict:
    """Write the robot, the measured and validation poses, the candidates; return paths and the truth."""
    rng = np.random.default_rng(seed)
    robot = TrueRobot.draw(Arm.from_dict(sc.arm), sc.effects, rng)
    q_cal, q_val = region(robot, sc, sc.n_cal, rng), region(robot, sc, 100, rng)
    qn = region(robot, sc, n_candidates - n_far, rng)       # the measured region again
    qf = sample(robot, n_far, rng, floor_z=None)            # the few that reach beyond it
    q = np.concatenate([qn, qf])
    order = rng.permutation(len(q))
    cand = Measurements.from_arrays(q[order])
    paths = {k: str(folder / f"{k}.csv") for k in ("cal", "val", "cand")}
    (folder / "arm.toml").write_text(to_toml(sc.arm))
    paths["robot"] = str(folder / "arm.toml")
    shoot(robot, q_cal, rng).write_csv(paths["cal"])
    shoot(robot, q_val, rng).write_csv(paths["val"])
    cand.write_csv(paths["cand"], overwrite=True)
    return {"paths": paths, "truth": robot, "cand": cand,
            "far": {int(k) for k in np.flatnonzero(order >= len(qn))}}


def diagnose(robot_path: str, data: list[str], val: str, out: str) -> dict:
    assert main(["diagnose", robot_path, *data, "--validate", val, "--json", out, "--no-blackbox", "-q",
                 "--force"]) == 0
    return json.loads(open(out).read())


def measure(env: dict, rows, seed: int, path: str) -> None:
    """The candidates ``rows`` measured on the same true robot, in the same session."""
    shoot(env["truth"], env["cand"].q[np.asarray(rows)], np.random.default_rng(seed)).write_csv(path)


def resolved(report: dict, sc: Scenario) -> bool:
    """The diagnosis names the true cause, in its model, and no longer finds it ambiguous with the rival."""
    cause, joint, harmonic = sc.truth
    for f in report["findings"]:
        if f["cause"] == cause and f.get("joint") == joint and f.get("harmonic") == harmonic and f["in_model"]:
            rivals = {(a["cause"], a.get("joint"), a.get("harmonic")) for a in f.get("ambiguous_with", [])}
            return tuple(sc.rival) not in rivals if sc.rival else True
    return False


def loop(sc: Scenario, seed: int, folder) -> dict:
    """One seed: diagnose the first poses, plan M, measure them (and M random candidates), diagnose again."""
    env = setup(sc, seed, folder)
    p = env["paths"]
    first = diagnose(p["robot"], [p["cal"]], p["val"], str(folder / "first.json"))
    assert main(["plan-poses", str(folder / "first.json"), p["cand"], "-m", str(sc.m), "--out",
                 str(folder / "next.csv"), "--json", str(folder / "plan.json"), "--force", "-q",
                 "--random-sets", "50"]) == 0
    plan = json.loads(open(folder / "plan.json").read())
    rows = plan["indices"]
    rng = np.random.default_rng(seed + 1000)
    random_rows = np.sort(rng.choice(len(env["cand"]), sc.m, replace=False))
    out = {"first": resolved(first, sc), "plan": plan, "far_picked": len(set(rows) & env["far"]),
           "far_random": len(set(random_rows.tolist()) & env["far"])}
    for name, picked in (("planned", rows), ("random", random_rows)):
        new = str(folder / f"{name}.csv")
        measure(env, picked, seed + 2000, new)
        merged = str(folder / f"{name}_all.csv")
        _concat(p["cal"], new, merged)
        rep = diagnose(p["robot"], [merged], p["val"], str(folder / f"{name}.json"))
        out[name] = resolved(rep, sc)
        out[name + "_findings"] = [(f["cause"], f.get("joint"), f.get("harmonic"), f["in_model"],
                                    [a["label"] for a in f.get("ambiguous_with", [])]) for f in rep["findings"]]
    return out


def _concat(a: str, b: str, out: str) -> None:
    """Two measurement files of one session as one (the header of the first; the same columns)."""
    la = open(a).read().splitlines()
    lb = open(b).read().splitlines()
    assert la[0] == lb[0], (la[0], lb[0])
    open(out, "w").write("\n".join(la + lb[1:]) + "\n")
