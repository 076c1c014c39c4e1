"""ISO 9283 (casadical iso9283): the pose and distance characteristics of simulated repeated cycles, checked
against the standard's formulas computed here; before and after compensation; the bundled series D.

The truth (tests/truth) is a six-axis arm with hidden geometric errors whose joints scatter from cycle to cycle
(the repeatability) and whose tracker adds its noise; it is measured in its base frame (--frame base). The
commanded poses are the truth's nominal model's: positions and, in one test, orientations (R = Rx Ry Rz)."""

from __future__ import annotations

import hashlib
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from casadical import calibrate, load_robot
from casadical.apply import compensate
from casadical.data import Measurements
from casadical.importers import convert_iso_cubes
from tests.helpers.arms import ARM6, to_toml
from tests.helpers.cli import cli, one_error
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample
from tests.truth import transforms as tf

DATASET = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"
CYCLES, JITTER, NOISE = 30, math.radians(0.004), 8e-6


def cube_poses(nominal: TrueRobot, rng, n_cubes=2):
    """Joints of P1..P5 of ``n_cubes`` ISO cubes (P1 the centre, P2..P5 on a diagonal plane, 10 % of the diagonal in
    from the corners), found on the nominal model from a pose by Newton steps on the tool point, orientation
    free."""
    out = []
    while len(out) < n_cubes:
        q0 = sample(nominal, 1, rng, floor_z=None)[0]
        c = nominal.tool_point(nominal.state(q0[None]))[0]
        h = 0.15
        corners = np.array([[-1, -1, -1], [1, -1, 1], [1, 1, 1], [-1, 1, -1]]) * h * 0.8
        goals = np.vstack([c, c + corners])
        qs, ok = [], True
        for g in goals:
            q = q0.copy()
            for _ in range(12):
                batch = np.vstack([q, q + 1e-7 * np.eye(len(q))])
                pts = nominal.tool_point(nominal.state(batch, iterations=1))
                J = (pts[1:] - pts[0]).T / 1e-7
                q = q + np.linalg.lstsq(J, g - pts[0], rcond=None)[0]
            ok &= np.linalg.norm(nominal.tool_point(nominal.state(q[None]))[0] - g) < 1e-9
            qs.append((q + np.pi) % (2 * np.pi) - np.pi)           # the same pose, the readings within +-180 deg
        if ok:
            out.append(np.array(qs))
    return out


def flange_angles(robot: TrueRobot, q):
    return np.degrees(tf.intrinsic_xyz(robot.state(q).flange))


def write_file(path, cubes, true, nominal, rng, *, compensated=None, orientation=True):
    """Cycle by cycle over P1..P5 of each cube: the commanded pose (nominal) and the attained (true, jittered)."""
    header = ["cycle", "cube", "pose", *[f"q{j}_deg" for j in range(1, 7)], "cmd_x_mm", "cmd_y_mm", "cmd_z_mm",
              "x_mm", "y_mm", "z_mm"]
    if orientation:
        header += ["cmd_rx_deg", "cmd_ry_deg", "cmd_rz_deg", "rx_deg", "ry_deg", "rz_deg"]
    if compensated is not None:
        header.append("compensated")
    rows = []
    for k, qs in enumerate(cubes, start=1):
        cmd = nominal.tool_point(nominal.state(qs)) * 1000
        ang = flange_angles(nominal, qs)
        drive = qs if compensated is None else compensated[k - 1]
        for cycle in range(1, CYCLES + 1):
            jq = drive + rng.normal(0, JITTER, drive.shape)
            s = true.state(jq)
            att = true.tool_point(s) * 1000 + rng.normal(0, NOISE * 1000, (len(qs), 3))
            att_ang = np.degrees(tf.intrinsic_xyz(s.flange))
            for i in range(len(qs)):
                row = [cycle, k, f"P{i + 1}", *np.degrees(qs[i]), *cmd[i], *att[i]]
                if orientation:
                    row += [*ang[i], *att_ang[i]]
                if compensated is not None:
                    row.append(1)
                rows.append(row)
    text = ",".join(header) + "\n" + "\n".join(",".join(repr(float(v)) if not isinstance(v, str) else v
                                                          for v in r) for r in rows) + "\n"
    Path(path).write_text(text)
    return header, rows


def independent(header, rows):
    """The standard's formulas, written here: per (cube, pose) AP_p, RP_l, AP_a.., RP_a..; per cube AD, RD of
    P2-P4."""
    col = {h: i for i, h in enumerate(header)}
    out, dist = {}, {}
    keys = sorted({(r[col["cube"]], r[col["pose"]]) for r in rows})
    for key in keys:
        sel = [r for r in rows if (r[col["cube"]], r[col["pose"]]) == key]
        x = np.array([[r[col[c]] for c in ("x_mm", "y_mm", "z_mm")] for r in sel])
        xc = np.array([sel[0][col[c]] for c in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
        xbar = x.mean(axis=0)
        l = np.sqrt(((x - xbar) ** 2).sum(axis=1))
        S_l = math.sqrt(((l - l.mean()) ** 2).sum() / (len(l) - 1))
        d = {"AP_p": math.sqrt(((xbar - xc) ** 2).sum()), "RP_l": l.mean() + 3 * S_l}
        if "rx_deg" in col:
            for a, (att, cmd) in zip("abc", (("rx_deg", "cmd_rx_deg"), ("ry_deg", "cmd_ry_deg"),
                                             ("rz_deg", "cmd_rz_deg"))):
                dev = np.array([(r[col[att]] - r[col[cmd]] + 180) % 360 - 180 for r in sel])
                d[f"AP_{a}"] = dev.mean()
                d[f"RP_{a}"] = 3 * math.sqrt(((dev - dev.mean()) ** 2).sum() / (len(dev) - 1))
        out[key] = d
    for cube in sorted({k[0] for k in keys}):
        a = sorted([r for r in rows if r[col["cube"]] == cube and r[col["pose"]] == "P2"], key=lambda r: r[0])
        b = sorted([r for r in rows if r[col["cube"]] == cube and r[col["pose"]] == "P4"], key=lambda r: r[0])
        P = lambda r, p="": np.array([r[col[p + c]] for c in ("x_mm", "y_mm", "z_mm")])   # noqa: E731
        Dc = np.linalg.norm(P(a[0], "cmd_") - P(b[0], "cmd_"))
        D = np.array([np.linalg.norm(P(ra) - P(rb)) for ra, rb in zip(a, b)])
        dist[cube] = {"AD_p": D.mean() - Dc, "RD_p": 3 * math.sqrt(((D - D.mean()) ** 2).sum() / (len(D) - 1))}
        if "rx_deg" in col:
            for a_, name in zip("abc", ("rx_deg", "ry_deg", "rz_deg")):
                Da = np.array([(ra[col[name]] - rb[col[name]] + 180) % 360 - 180 for ra, rb in zip(a, b)])
                Dca = (a[0][col["cmd_" + name]] - b[0][col["cmd_" + name]] + 180) % 360 - 180
                dist[cube][f"AD_{a_}"] = Da.mean() - Dca
                dist[cube][f"RD_{a_}"] = 3 * math.sqrt(((Da - Da.mean()) ** 2).sum() / (len(Da) - 1))
    return out, dist


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    d = tmp_path_factory.mktemp("iso")
    (d / "robot.toml").write_text(to_toml(ARM6))
    a = Arm.from_dict(ARM6)
    return d, a


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ap_rp_ad_rd_match_the_standard(arm, capsys, seed):
    d, a = arm
    rng = np.random.default_rng(seed)
    true, nominal = TrueRobot.draw(a, Effects(), rng), TrueRobot(a)
    cubes = cube_poses(nominal, rng)
    header, rows = write_file(d / f"m{seed}.csv", cubes, true, nominal, rng)
    code, _, err = cli(capsys, "iso9283", d / "robot.toml", d / f"m{seed}.csv", "--frame", "base",
                       "--json", d / f"r{seed}.json")
    assert code == 0, err
    report = json.loads((d / f"r{seed}.json").read_text())
    poses, dist = independent(header, rows)
    got = {(int(p["cube"]), p["pose"]): p for p in report["before"]["poses"]}
    assert len(got) == 10
    for key, want in poses.items():
        for k, v in want.items():
            assert got[key][k] == pytest.approx(v, rel=1e-9, abs=1e-9), (key, k)
    assert len(report["before"]["distances"]) == 2
    for p in report["before"]["distances"]:
        want = dist[int(p["cube"])]
        assert len(want) == 8
        for k, v in want.items():
            assert p[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
    # what the truth hides: an error of tenths of a millimetre or more, a scatter of its joints of 0.004 deg (at an
    # arm's reach under a millimetre, 3 sigma and more)
    assert min(p["AP_p"] for p in got.values()) > 0.2
    assert 0.01 < min(p["RP_l"] for p in got.values()) and max(p["RP_l"] for p in got.values()) < 0.5


def test_commanded_from_joints_and_after_compensation(arm, capsys):
    """Commanded positions from the joints (the nominal model), a calibration's predicted figures after
    compensation, and rows measured after compensating the joints (compensated = 1) by the true robot: the
    prediction holds to the calibration's accuracy, and both are far better than before."""
    d, a = arm
    rng = np.random.default_rng(5)
    true, nominal = TrueRobot.draw(a, Effects(), rng), TrueRobot(a)
    robot = load_robot(d / "robot.toml")
    measure(true, sample(true, 150, rng, floor_z=None), rng, session=Session(), noise=10e-6).write_csv(d / "cal.csv")
    cal = calibrate(robot, Measurements.read_csv(d / "cal.csv", robot=robot), "kinematic", "lm", warn=False)
    cal.save(d / "cal.json")
    cubes = cube_poses(nominal, rng)
    comp = []
    for qs in cubes:
        goal = nominal.tool_point(nominal.state(qs))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            comp.append(compensate(cal, Measurements.from_arrays(qs, goal)).q)
    h1, r1 = write_file(d / "b.csv", cubes, true, nominal, rng, orientation=False)
    h2, r2 = write_file(d / "a.csv", cubes, true, nominal, rng, orientation=False, compensated=comp)
    keep = [h for h in h1 if not h.startswith("cmd_")]
    text = ",".join(keep + ["compensated"]) + "\n" + "\n".join(
        ",".join(repr(float(r[h1.index(h)])) if h != "pose" else r[h1.index(h)] for h in keep) + ",0" for r in r1) \
        + "\n" + "\n".join(",".join(repr(float(r[h2.index(h)])) if h != "pose" else r[h2.index(h)] for h in keep)
                           + ",1" for r in r2) + "\n"
    (d / "both.csv").write_text(text)
    code, out, err = cli(capsys, "iso9283", d / "cal.json", d / "both.csv", "--frame", "base", "--json",
                         d / "both.json", "--html", d / "both.html")
    assert code == 0, err
    rep = json.loads((d / "both.json").read_text())
    assert rep["states"] == ["before", "after (predicted)", "after (measured)"]
    ap = {s: np.array([p["AP_p"] for p in rep[s]["poses"]]) for s in rep["states"]}
    assert ap["before"].mean() > 5 * ap["after (measured)"].mean()
    assert np.abs(ap["after (predicted)"] - ap["after (measured)"]).max() < 0.05
    assert "AP_p after (predicted)" in (d / "both.html").read_text()
    assert "commanded joints" in out or "nominal model" in out


def test_bad_file_is_one_line(arm, tmp_path, capsys):
    d, _ = arm
    (tmp_path / "bad.csv").write_text("cycle,pose,x_mm,y_mm,z_mm\n1,P1,1,2,3\n")
    code, _, err = cli(capsys, "iso9283", d / "robot.toml", tmp_path / "bad.csv")
    assert code == 2
    one_error(err, "bad.csv", "row 1", "cmd_x_mm")


def test_series_d_bundled_byte_for_byte_and_converted(tmp_path):
    """The raw files of series D are the repository's (the README's checksums), and series_d.csv is a fresh
    conversion of them; 70 cubes of nine poses and two poses in none."""
    sums = dict((p, h) for h, p in re.findall(r"([0-9a-f]{64})  (raw/Series_D/\S+)",
                                              (DATASET / "README.md").read_text()))
    assert len(sums) == 4
    for path, digest in sums.items():
        assert hashlib.sha256((DATASET / path).read_bytes()).hexdigest() == digest
    with pytest.warns(Warning, match="no usable timestamps"):
        n = convert_iso_cubes(DATASET / "raw" / "Series_D" / "measurements_iso_cubes.csv", tmp_path / "d.csv")
    assert n == 632 and (tmp_path / "d.csv").read_text() == (DATASET / "series_d.csv").read_text()
    m = Measurements.read_csv(DATASET / "series_d.csv")
    cube = m.columns["cube"]
    assert cube.max() == 70 and (cube == 0).sum() == 2


def test_series_d_report_says_repeatability_needs_cycles(capsys):
    code, out, err = cli(capsys, "iso9283", "ur10", DATASET / "series_d.csv", "--json", "-")
    assert code == 0, err
    rep = json.loads(out)
    assert len(rep["before"]["cubes"]) == 71 and all(p["RP_l"] is None for p in rep["before"]["poses"])
    assert any("repeatability (RP, RD) need repeated cycles" in n for n in rep["notes"])
