"""Robot programs filtered with a calibration (compensate CAL.json PROGRAM): URScript on a six-axis arm, KUKA KRL
on the YS100 on a 4 m track (E1, the track, a linear axis), ABB RAPID on the YS100; each program 22 targets (joint
and Cartesian, two tools, two bases), written here as a programmer would. The truth (tests/truth) measures the
robot, makes the targets (its nominal model) and checks the result; the conventions are the tests' own
(tests/programs/conventions.py). What is checked:

- only the targets' numbers change, byte for byte;
- the filtered file read back (by the test's own reading): joint targets are the corrected joints, poses are
  what the truth's nominal model reaches at them with the target's tool, in its base (to 1e-6 deg, 1e-6 mm);
- the true robot at the corrected joints reaches what each target means (the nominal model's point, placed by
  the calibration's base pose) to the calibration's accuracy, where it missed by a millimetre before.

A position-only calibration cannot tell the flange from the measured point's mounting (the last link's own
parameters are fixed by it and the mounting absorbs their errors): the truth keeps the last link exact, so that
a program's tool, whose data are on the flange the controller knows, is where the program says.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from casadical import calibrate, load_robot
from casadical.data import Measurements
from casadical.robot import BUILTIN_DIR
from tests.helpers.arms import ARM6, to_toml
from tests.helpers.cli import cli, one_error
from tests.programs import conventions as cv
from tests.truth import Arm, Effects, Session, TrueRobot, measure, sample

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def robot_text(name: str) -> str:
    return to_toml(ARM6) if name == "arm6" else (BUILTIN_DIR / f"{name}.toml").read_text()


LANGUAGES = {"urscript": "arm6", "krl": "track6", "rapid": "ys100"}
TOOLS = {1: cv.frame([0.01, 0.02, 0.15], cv.abc_to_matrix(0, 0, 20)),
         2: cv.frame([0.08, -0.03, 0.25], cv.abc_to_matrix(10, -15, 5))}
BASES = {1: cv.frame([0.3, -0.2, 0.1], cv.abc_to_matrix(30, 0, 0)), 0: np.eye(4)}


def tcp(robot: TrueRobot, q, tool) -> np.ndarray:
    """The tool frames (N, 4, 4) of ``robot`` at readings q, robot base frame."""
    return robot.state(np.atleast_2d(q)).flange @ tool


def jacobian_ok(nominal: TrueRobot, q, floor=0.05) -> bool:
    """Away from singular configurations: the smallest singular value of the pose Jacobian (m and rad per rad)."""
    h = 1e-6
    F0 = tcp(nominal, q, np.eye(4))[0]
    cols = []
    for k in range(len(q)):
        d = q.copy()
        d[k] += h
        F = tcp(nominal, d, np.eye(4))[0]
        w = F[:3, :3] @ F0[:3, :3].T
        cols.append(np.r_[(F[:3, 3] - F0[:3, 3]) / h, np.array([w[2, 1], w[0, 2], w[1, 0]]) / h])
    return np.linalg.svd(np.array(cols).T, compute_uv=False)[-1] > floor


@pytest.fixture(scope="module", params=sorted(LANGUAGES))
def setup(request, tmp_path_factory):
    language = request.param
    name = LANGUAGES[language]
    d = tmp_path_factory.mktemp(language)
    text = robot_text(name)
    (d / "robot.toml").write_text(text)
    arm = Arm.from_toml(text)
    rng = np.random.default_rng(7)
    true = TrueRobot.draw(arm, Effects(), rng)
    g = true.geometry
    for f in ("alpha", "a", "d", "theta", "beta", "b"):          # the last link exact (module docstring)
        getattr(g, f)[-1] = getattr(TrueRobot(arm).geometry, f)[-1]
    session = Session(base_xyz=(1.6, -0.4, 0.2), base_rpy=(0.0, 0.0, 0.7))
    shots = measure(true, sample(true, 160, rng, floor_z=None), rng, session=session, noise=20e-6)
    val = measure(true, sample(true, 80, rng, floor_z=None), rng, session=session, noise=0.0)
    robot = load_robot(d / "robot.toml")
    shots.write_csv(d / "cal.csv")
    val.write_csv(d / "val.csv")
    cal = calibrate(robot, Measurements.read_csv(d / "cal.csv", robot=robot), "kinematic", "lm", warn=False)
    cal.save(d / "cal.json")
    accuracy = cal.stats(Measurements.read_csv(d / "val.csv", robot=robot)).rms_mm
    nominal = TrueRobot(arm)
    q = []
    lo, hi = shots.q.min(axis=0), shots.q.max(axis=0)
    while len(q) < 22:
        c = sample(nominal, 1, rng, floor_z=None)[0]
        if np.all((c > lo) & (c < hi)) and jacobian_ok(nominal, c):      # within what the calibration saw
            q.append(c)
    q = np.array(q)
    program = WRITERS[language](d, q, nominal, arm)
    return language, d, program, arm, true, nominal, session, cal, accuracy


# --- the programs, as a programmer writes them ----------------------------------------------------------------


def _pose_of(nominal, q, tool, base):
    return np.linalg.inv(base) @ tcp(nominal, q, tool)[0]


def write_urscript(d: Path, q, nominal, arm):
    """10 joint targets (movej lists, two as variables), 12 poses (movel/movep, two as variables); two TCPs."""
    rv = np.round(cv.matrix_to_rotvec(TOOLS[1][:3, :3]), 6)
    TOOLS[1] = cv.frame(TOOLS[1][:3, 3], cv.rotvec_to_matrix(rv))
    lines = ["def cell():", "  # welding cell, station 3",
             f"  set_tcp(p[0.01, 0.02, 0.15, {rv[0]:.6f}, {rv[1]:.6f}, {rv[2]:.6f}])"]
    meaning = {}
    tool = 1
    for i, row in enumerate(q):
        if i == 11:
            tool = 2
            rv = cv.matrix_to_rotvec(TOOLS[2][:3, :3])
            lines.append("  set_tcp(p[0.08, -0.03, 0.25, " + ", ".join(f"{v:.6f}" for v in rv) + "])")
            TOOLS[2] = cv.frame(TOOLS[2][:3, 3], cv.rotvec_to_matrix(np.round(rv, 6)))
        if i % 2 == 0:
            values = ", ".join(f"{v:.5f}" for v in row)
            if i in (4, 16):
                lines.append(f"  global j{i} = [{values}]")
                meaning[len(lines)] = ("joints", tool, 0)
                lines.append(f"  movej(j{i}, a=1.4, v=1.05)")
            else:
                lines.append(f"  movej([{values}], a=1.4, v=1.05, r=0.002)")
                meaning[len(lines)] = ("joints", tool, 0)
        else:
            P = _pose_of(nominal, row, TOOLS[tool], np.eye(4))
            values = ", ".join(f"{v:.6f}" for v in list(P[:3, 3]) + list(cv.matrix_to_rotvec(P[:3, :3])))
            if i in (5, 17):
                lines.append(f"  pose{i} = p[{values}]")
                meaning[len(lines)] = ("pose", tool, 0)
                lines.append(f"  movep(pose{i}, a=1.2, v=0.25, r=0.01)")
            else:
                lines.append(f"  movel(p[{values}], a=1.2, v=0.25)")
                meaning[len(lines)] = ("pose", tool, 0)
        lines.append("  sleep(0.5)")
    lines += ["  set_digital_out(2, True)", "end"]
    path = d / "cell.script"
    path.write_text("\n".join(lines) + "\n")
    return path, meaning


def _e6(row, prismatic):
    return (["A%d %.3f" % (k + 1, math.degrees(v)) for k, v in enumerate(row[~prismatic])]
            + ["E1 %.3f" % (row[prismatic][0] * 1000.0) if prismatic.any() else "E1 0.0"]
            + ["E%d 0.0" % k for k in range(2, 7)])


def write_krl(d: Path, q, nominal, arm):
    """The YS100 on its track: 10 E6AXIS, 12 E6POS (E1 the track), expert and inline forms; TOOL_DATA[1], [2] in a
    $config.dat, BASE_DATA[1] given as an option, the robot base ($NULLFRAME) too."""
    prismatic = np.array(arm.prismatic)
    dat = ["&ACCESS RVP", "&REL 12", "DEFDAT  CELL", ";FOLD EXTERNAL DECLARATIONS;%{PE}%V3.2.0",
           ";ENDFOLD (EXTERNAL DECLARATIONS)"]
    src = ["&ACCESS RVP", "&REL 12", "DEF CELL( )", ";FOLD INI", "  BAS (#INITMOV,0 )", ";ENDFOLD (INI)",
           "$TOOL = TOOL_DATA[1]", "$BASE = BASE_DATA[1]"]
    meaning = {}
    for i, row in enumerate(q):
        tool, base = (1, 1) if i < 11 else (2, 0)
        if i == 11:
            src += ["BAS(#TOOL, 2)", "$BASE = $NULLFRAME"]
        if i % 2 == 0:
            dat.append(f"DECL E6AXIS XP{i}={{{','.join(_e6(row, prismatic))}}}")
            kind = "joints"
        else:
            P = _pose_of(nominal, row, TOOLS[tool], BASES[base])
            abc = cv.matrix_to_abc(P[:3, :3])
            t = sum(1 << k for k, v in enumerate(row[~prismatic]) if v < 0)
            fields = [f"X {P[0, 3] * 1000:.3f}", f"Y {P[1, 3] * 1000:.3f}", f"Z {P[2, 3] * 1000:.3f}",
                      f"A {abc[0]:.4f}", f"B {abc[1]:.4f}", f"C {abc[2]:.4f}", "S 2", f"T {t}"]
            fields += _e6(row, prismatic)[6:]
            dat.append(f"DECL E6POS XP{i}={{{','.join(fields)}}}")
            kind = "pose"
        word = "PTP" if i % 4 < 2 else "LIN"
        if i >= 14:           # the inline form: a fold with FDAT_ACT naming the tool and base
            dat.append(f"DECL FDAT FP{i}={{TOOL_NO 2,BASE_NO 0,IPO_FRAME #BASE,POINT2[] \" \"}}")
            src += [f";FOLD {word} P{i} Vel=100 % PDAT1 Tool[2] Base[0];%{{PE}}", "  $BWDSTART=FALSE",
                    "  PDAT_ACT=PPDAT1", f"  FDAT_ACT=FP{i}", "  BAS(#PTP_PARAMS,100)", f"  {word} XP{i}",
                    ";ENDFOLD"]
        else:
            src.append(f"{word} XP{i} C_DIS")
        meaning[f"XP{i}"] = (kind, tool, base)
        src.append("WAIT SEC 0.5")
    src += ["$OUT[3]=TRUE", "END"]
    dat.append("ENDDAT")
    (d / "CELL.src").write_text("\r\n".join(src) + "\r\n")
    (d / "CELL.dat").write_text("\r\n".join(dat) + "\r\n")
    config = ["DEFDAT $CONFIG", "DECL FRAME TOOL_DATA[16]"]
    for k in (1, 2):
        abc = cv.matrix_to_abc(TOOLS[k][:3, :3])
        x = TOOLS[k][:3, 3] * 1000
        config.append(f"TOOL_DATA[{k}]={{X {x[0]:.3f},Y {x[1]:.3f},Z {x[2]:.3f},A {abc[0]:.6f},B {abc[1]:.6f},"
                      f"C {abc[2]:.6f}}}")
        TOOLS[k] = cv.frame(np.round(x, 3) / 1000, cv.abc_to_matrix(*np.round(abc, 6)))
    config.append("ENDDAT")
    (d / "config.dat").write_text("\n".join(config) + "\n")
    return d / "CELL.src", meaning


def _quat_text(R):
    return ",".join(f"{v:.6f}" for v in cv.matrix_to_quaternion(R))


def write_rapid(d: Path, q, nominal, arm):
    """The YS100: 10 jointtargets, 12 robtargets with cf1, cf4, cf6, tools tGun and tPen, work objects wTable
    (user and object frames) and wobj0."""
    uf = cv.frame([0.2, -0.1, 0.05], cv.abc_to_matrix(20, 0, 0))
    of = cv.frame([0.1, -0.1, 0.05], cv.abc_to_matrix(10, 0, 0))
    BASES[2] = uf @ of
    head = ["MODULE Cell", "  ! deburring, line 2"]
    names = {1: "tGun", 2: "tPen"}
    for k in (1, 2):
        x = TOOLS[k][:3, 3] * 1000
        head.append(f"  PERS tooldata {names[k]} := [TRUE,[[{x[0]:.3f},{x[1]:.3f},{x[2]:.3f}],"
                    f"[{_quat_text(TOOLS[k][:3, :3])}]],[2.5,[0,0,100],[1,0,0,0],0,0,0]];")
        TOOLS[k] = cv.frame(np.round(x, 3) / 1000,
                            cv.quaternion_to_matrix(np.round(cv.matrix_to_quaternion(TOOLS[k][:3, :3]), 6)))
    head.append(f"  TASK PERS wobjdata wTable := [FALSE,TRUE,\"\",[[200,-100,50],[{_quat_text(uf[:3, :3])}]],"
                f"[[100,-100,50],[{_quat_text(of[:3, :3])}]]];")
    BASES[2] = (cv.frame(uf[:3, 3], cv.quaternion_to_matrix(np.round(cv.matrix_to_quaternion(uf[:3, :3]), 6)))
                @ cv.frame(of[:3, 3], cv.quaternion_to_matrix(np.round(cv.matrix_to_quaternion(of[:3, :3]), 6))))
    body = ["  PROC main()", "    ConfJ \\On;"]
    meaning = {}
    for i, row in enumerate(q):
        tool, base = (1, 2) if i < 11 else (2, 0)
        wobj = "\\WObj:=wTable" if base == 2 else ""
        if i % 2 == 0:
            rax = ",".join(f"{math.degrees(v):.4f}" for v in row)
            head.append(f"  CONST jointtarget j{i} := [[{rax}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
            body.append(f"    MoveAbsJ j{i}\\NoEOffs, v1000, z50, {names[tool]}{wobj};")
            meaning[f"j{i}"] = ("joints", tool, base)
        else:
            P = _pose_of(nominal, row, TOOLS[tool], BASES[base])
            cf = [math.floor(math.degrees(row[k]) / 90) for k in (0, 3, 5)]
            x = P[:3, 3] * 1000
            head.append(f"  CONST robtarget p{i} := [[{x[0]:.3f},{x[1]:.3f},{x[2]:.3f}],[{_quat_text(P[:3, :3])}],"
                        f"[{cf[0]},{cf[1]},{cf[2]},0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
            body.append(f"    Move{'L' if i % 4 == 1 else 'J'} p{i}, v500, z10, {names[tool]}{wobj};")
            meaning[f"p{i}"] = ("pose", tool, base)
        body.append("    WaitTime 0.5;")
    body += ["  ENDPROC", "ENDMODULE"]
    path = d / "cell.mod"
    path.write_text("\n".join(head + body) + "\n")
    return path, meaning


WRITERS = {"urscript": write_urscript, "krl": write_krl, "rapid": write_rapid}


# --- reading back (the test's own reading) ------------------------------------------------------------------


def read_back(language, path: Path) -> dict:
    """Target -> ("joints", values as written) or ("pose", 4x4 m, its base), by name (URScript: by line)."""
    out = {}
    if language == "urscript":
        for k, line in enumerate(path.read_text().splitlines(), start=1):
            m = re.search(r"(?:\bp)?\[([^\]]*)\]", line)
            if m and ("move" in line or re.match(r"\s*(global )?\w+ = ", line)) and "set_tcp" not in line:
                v = [float(x) for x in m.group(1).split(",")]
                out[k] = (("pose", cv.frame(v[:3], cv.rotvec_to_matrix(v[3:]))) if "p[" in line
                            else ("joints", np.array(v)))
    elif language == "krl":
        dat = path.with_suffix(".dat").read_text()
        for typ, name, body in re.findall(r"DECL (E6AXIS|E6POS) (\w+)=\{([^}]*)\}", dat):
            f = dict((kv.split()[0], float(kv.split()[1])) for kv in body.split(","))
            if typ == "E6AXIS":
                out[name] = ("joints", np.array([f["E1"]] + [f[f"A{k}"] for k in range(1, 7)]))
            else:
                out[name] = ("pose", cv.frame(np.array([f["X"], f["Y"], f["Z"]]) / 1000,
                                              cv.abc_to_matrix(f["A"], f["B"], f["C"])), f["E1"], int(f["T"]))
    else:
        text = path.read_text()
        for name, rax in re.findall(r"jointtarget (\w+) := \[\[([^\]]*)\]", text):
            out[name] = ("joints", np.array([float(x) for x in rax.split(",")]))
        for name, x, qt, cf in re.findall(r"robtarget (\w+) := \[\[([^\]]*)\],\[([^\]]*)\],\[([^\]]*)\]", text):
            out[name] = ("pose", cv.frame(np.array([float(v) for v in x.split(",")]) / 1000,
                                          cv.quaternion_to_matrix([float(v) for v in qt.split(",")])),
                         [int(v) for v in cf.split(",")])
    return out


def readings(values, arm):
    """Joint values in the files' units (deg; mm for a linear axis), robot order -> rad (m)."""
    v = np.asarray(values, float)
    return np.where(arm.prismatic, v / 1000.0, np.radians(v))


def frames(language, d) -> list:
    """The KRL program's TOOL_DATA (its $config.dat) and BASE_DATA[1] (an option) on the command line."""
    if language != "krl":
        return []
    return ["--config", d / "config.dat", "--base", "1=" + ",".join(
        f"{v:.9f}" for v in list(BASES[1][:3, 3] * 1000) + list(cv.matrix_to_abc(BASES[1][:3, :3])))]


def test_filter_touches_only_targets_and_reaches_them(setup, capsys):
    language, d, (path, meaning), arm, true, nominal, session, cal, accuracy = setup
    out = d / ("filtered" + path.suffix)
    args = ["compensate", d / "cal.json", path, "--out", out, "--json", d / "report.json", *frames(language, d)]
    code, text, err = cli(capsys, *args)
    assert code == 0, err
    report = json.loads((d / "report.json").read_text())
    assert "positions alone" in report["held"] and not report["hold_orientation"]
    assert report["corrected"] == 22 == len(report["targets"]) and report["left"] == 0, text
    # 1. byte for byte: the files differ in numbers only, and only on the targets' lines
    pairs = [(path, out)] + ([(path.with_suffix(".dat"), out.with_suffix(".dat"))] if language == "krl" else [])
    lines = {(Path(t["file"]).name, t["line"]) for t in report["targets"]}
    changed = 0
    for a, b in pairs:
        ta, tb = a.read_bytes().decode(), b.read_bytes().decode()
        assert NUMBER.sub("#", ta) == NUMBER.sub("#", tb)
        for k, (la, lb) in enumerate(zip(ta.split("\n"), tb.split("\n")), start=1):
            if la != lb:
                changed += 1
                assert (a.name, k) in lines, (a.name, k, la, lb)
    assert changed >= 22
    # 2. read back: the corrected joints, within 1e-6 deg (poses: what the nominal model reaches there)
    back = read_back(language, out)
    B = {0: np.eye(4), 1: BASES[1], 2: BASES.get(2)}
    for t in report["targets"]:
        key = t["line"] if language == "urscript" else t["name"]
        kind, tool, base = meaning[key]
        assert t["kind"] == kind
        q_new = readings(t["joints"], arm)
        entry = back[key]
        if kind == "joints":
            written = entry[1] if language == "urscript" else readings(entry[1], arm)
            scale = np.where(arm.prismatic, 1e3, np.degrees(1.0))      # mm, deg
            assert np.abs((written - q_new) * scale).max() < 1e-6
        else:
            P = np.linalg.inv(B[base]) @ tcp(nominal, q_new, TOOLS[tool])[0]
            assert np.linalg.norm(entry[1][:3, 3] - P[:3, 3]) * 1e3 < 1e-6
            assert math.degrees(cv.angle(entry[1][:3, :3], P[:3, :3])) < 1e-6, (key, t)
            if language == "krl":
                assert abs(entry[2] - q_new[0] * 1000) < 1e-6           # E1: the track
                assert entry[3] == sum(1 << k for k, v in enumerate(q_new[1:]) if v < 0)
            if language == "rapid":
                assert entry[2][:3] == [math.floor(math.degrees(q_new[k]) / 90) for k in (0, 3, 5)]
            # the programmed joints are the nominal inverse kinematics of the target as the program wrote it
            q0 = readings(t["programmed_joints"], arm)
            original = read_back(language, path)[key][1]
            P0 = np.linalg.inv(B[base]) @ tcp(nominal, q0, TOOLS[tool])[0]
            assert np.linalg.norm(original[:3, 3] - P0[:3, 3]) * 1e3 < 1e-5
    # 3. the true robot reaches what each target means, to the calibration's accuracy: the calibrated model's own
    # error at those joints for that tool point (its prediction, the tool point moved to the tool's, against the
    # truth; beyond the measured point's error, the flange orientation a position-only calibration sees badly)
    Bc, Bs = cal.base_matrix(), session.base()
    before, after, model = [], [], []
    for t in report["targets"]:
        key = t["line"] if language == "urscript" else t["name"]
        _, tool, _ = meaning[key]
        q0, q1 = readings(t["programmed_joints"], arm), readings(t["joints"], arm)
        goal = (Bc @ tcp(nominal, q0, TOOLS[tool])[0])[:3, 3]
        before.append(np.linalg.norm((Bs @ tcp(true, q0, TOOLS[tool])[0])[:3, 3] - goal) * 1e3)
        reached = (Bs @ tcp(true, q1, TOOLS[tool])[0])[:3, 3]
        after.append(np.linalg.norm(reached - goal) * 1e3)
        p = cal.parameters.values.copy()
        for k, axis in enumerate("xyz"):
            p[cal.parameters.index(f"tool_{axis}")] = TOOLS[tool][k, 3]
        model.append(np.linalg.norm(cal.model.predict(q1[None], p, None, cal.base0)[0] - reached) * 1e3)
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))          # noqa: E731
    assert rms(before) > 0.5 and rms(before) > 5 * rms(after), (rms(before), rms(after))
    assert rms(after) < 1.2 * rms(model) + 0.005, (rms(after), rms(model), accuracy)
    assert rms(model) < 0.3 and accuracy < 0.05, (rms(model), accuracy)


def test_hold_orientation_holds_each_tools_orientation(setup, capsys):
    """--hold-orientation: the calibrated model's tool takes the orientation each target means too (its miss in
    degrees is corrected, not only its point)."""
    language, d, (path, _), *_ = setup
    out = d / ("held" + path.suffix)
    args = ["compensate", d / "cal.json", path, "--out", out, "--json", d / "held.json", "--hold-orientation",
            *frames(language, d)]
    code, text, err = cli(capsys, *args)
    assert code == 0, err
    report = json.loads((d / "held.json").read_text())
    assert report["hold_orientation"] and "orientation each target means" in report["held"]
    done = [t for t in report["targets"] if t["corrected"]]
    assert len(done) >= 18, text                     # a few may be too near a singular configuration to hold it
    assert max(t["residual_deg"] for t in done) < 1e-6 < min(t["miss_deg"] for t in done)
    assert max(t["residual_mm"] for t in done) < 1e-4


@pytest.mark.parametrize("setup, edit, token", [
    ("urscript", lambda s: s.replace("movel(p[", "movec(p[", 1), "movec"),
    ("urscript", lambda s: re.sub(r"  set_tcp\(p\[0.01, [^\n]*\n", "", s, count=1), None),
    ("krl", lambda s: s.replace("LIN XP", "SLIN XP", 1), "SLIN"),
    ("krl", lambda s: s.replace("$TOOL = TOOL_DATA[1]", "$TOOL = TOOL_DATA[7]"), "XP0"),
    ("rapid", lambda s: s.replace("MoveL p", "MoveExtJ p", 1), "MoveExtJ"),
    ("rapid", lambda s: s.replace(", tGun\\WObj", ", tDrill\\WObj", 1), "tDrill"),
    ("rapid", lambda s: s.replace("TASK PERS wobjdata wTable := [FALSE", "TASK PERS wobjdata wTable := [TRUE"),
     "wTable"),
], indirect=["setup"])
def test_bad_program_is_one_line_and_nothing_is_written(setup, capsys, edit, token):
    language, d, (path, _), *_ = setup
    bad = d / ("bad" + path.suffix)
    bad.write_text(edit(path.read_text()))
    if language == "krl":
        bad.with_suffix(".dat").write_text(path.with_suffix(".dat").read_text())
    out = d / ("never" + path.suffix)
    args = ["compensate", d / "cal.json", bad, "--out", out]
    if language == "krl":
        args += ["--config", d / "config.dat", "--base", "1=0,0,0,0,0,0"]
    code, _, err = cli(capsys, *args)
    assert code == 2
    one_error(err, str(bad), "line ", *([f"token '{token}'"] if token else ["token"]))
    assert not out.exists() and not out.with_suffix(".dat").exists()


@pytest.mark.parametrize("setup", ["urscript"], indirect=True)
def test_polyscope_waypoints_through_get_inverse_kin(setup, capsys):
    """PolyScope writes a waypoint as a pose and the joints its inverse kinematics starts from: movej(
    get_inverse_kin(Waypoint_p, qnear=Waypoint_q)). The pose is filtered (the branch nearest qnear), qnear is kept;
    every other byte too."""
    language, d, _, arm, true, nominal, session, cal, accuracy = setup
    rng = np.random.default_rng(11)
    lines = ["def Program():", "  set_tcp(p[0.0,0.0,0.1,0.0,0.0,0.0])", '  $ 1 "Robot Program"']
    tool = cv.frame([0.0, 0.0, 0.1], np.eye(3))
    q = []
    while len(q) < 4:
        c = sample(nominal, 1, rng, floor_z=None)[0]
        if jacobian_ok(nominal, c):
            q.append(c)
    for k, row in enumerate(q, start=1):
        P = tcp(nominal, row, tool)[0]
        pose = ", ".join(f"{v:.6f}" for v in [*P[:3, 3], *cv.matrix_to_rotvec(P[:3, :3])])
        lines += [f"  global Waypoint_{k}_p=p[{pose}]",
                  f"  global Waypoint_{k}_q=[{', '.join(f'{v:.6f}' for v in row)}]",
                  f'  $ {k + 1} "Waypoint_{k}" "breakAfter"',
                  f"  movej(get_inverse_kin(Waypoint_{k}_p, qnear=Waypoint_{k}_q), a=1.39, v=1.04)"]
    lines.append("end")
    path = d / "polyscope.script"
    path.write_text("\n".join(lines) + "\n")
    out = d / "polyscope_filtered.script"
    code, text, err = cli(capsys, "compensate", d / "cal.json", path, "--out", out, "--json", d / "ps.json")
    assert code == 0, err
    report = json.loads((d / "ps.json").read_text())
    assert report["corrected"] == 4 and [t["name"] for t in report["targets"]] == [f"Waypoint_{k}_p"
                                                                                     for k in range(1, 5)]
    before, after = path.read_text().splitlines(), out.read_text().splitlines()
    for k, t in enumerate(report["targets"]):
        # the branch nearest qnear: the waypoint's own joints (to the pose's 6 decimals as written)
        assert np.abs(np.array(t["programmed_joints"]) - np.degrees(q[k])).max() < 2e-3
        line = t["line"] - 1
        assert before[line] != after[line] and before[line + 1] == after[line + 1]      # qnear kept
        v = [float(x) for x in re.search(r"p\[([^\]]*)\]", after[line]).group(1).split(",")]
        P = tcp(nominal, np.radians(t["joints"]), tool)[0]
        assert np.linalg.norm(np.array(v[:3]) - P[:3, 3]) * 1e3 < 1e-6
    assert sum(a != b for a, b in zip(before, after)) == 4
