"""The independent truth's touch rows (tests/truth/touch.py) against their definitions, read back from the CSV.

Nothing here uses casadical. Each test writes the rows as a user's file, reads it back as text, and checks it
with the true robot (tests/truth/robot.py) or by hand: the tool point at the written readings sits in its
socket, on its plane, at its distance from the pivot; the readings are what the encoders say; the tracker rows
of a tool of several points are one rigid body; the file has the columns of docs/formats.md and no others.
"""

import csv
import math
import tomllib

import numpy as np
import pytest

from tests.helpers.arms import ARM6, ARM7, ARM7_DH
from tests.truth import Arm, Effects, Session, TrueRobot, sample
from tests.truth.touch import (
    Fixture,
    fixture_session,
    fixture_toml,
    pivot_rows,
    plane_rows,
    reachable_point,
    socket_rows,
    tool_rows,
    two_sockets,
)

#: a session whose measurement frame (the world) is not the robot's base frame
WORLD = Session("front", base_xyz=(0.8, -0.3, 0.25), base_rpy=(0.01, -0.02, 0.6))
#: effects of every kind the truth acts on the drives: compliance under the arm's masses, a gear error, an encoder
#: scale, the motion side of backlash, the mount's compliance
EFFECTS = Effects(stiffness={2: 2e5, 4: 1e5}, periodic=[(3, 2, 2e-4, 0.4)], encoder_scale={1: 3e-4, 5: -2e-4},
                  backlash_motion={6: 1e-4}, mount_compliance=2e-7)


def draw(doc, seed, effects=EFFECTS):
    rng = np.random.default_rng(seed)
    return TrueRobot.draw(Arm.from_dict(doc), effects, rng), rng


def read(path):
    """The file as a user's program reads it: the header, and per row its cells as text."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], [dict(zip(rows[0], r)) for r in rows[1:]]


def readings(rows, n):
    return np.radians([[float(r[f"q{j + 1}_deg"]) for j in range(n)] for r in rows])


def true_points(robot, q, session, offset=None):
    """The true tool point (world) at readings ``q`` in their row order, written here from TrueRobot's state."""
    state = robot.state(q, mount=session.mount_compliance)
    shift = np.zeros(3) if offset is None else np.asarray(offset) - robot.geometry.tool
    p = robot.tool_point(state, None, shift)
    B = session.base()
    return p @ B[:3, :3].T + B[:3, 3]


@pytest.mark.parametrize("doc,seed", [(ARM7, 0), (ARM7_DH, 1), (ARM6, 2)], ids=["arm7-mdh", "arm7-dh", "arm6-dh"])
def test_the_true_tool_point_sits_in_the_socket_at_the_written_readings(tmp_path, doc, seed):
    robot, rng = draw(doc, seed)
    fixture = two_sockets()
    rows = fixture_session(robot, fixture, 8, rng, WORLD)
    path = rows.write_csv(tmp_path / "touch.csv")
    head, cells = read(path)
    n = robot.arm.n
    assert head == [f"q{j + 1}_deg" for j in range(n)] + ["point"]          # no x/y/z on touch rows
    assert [r["point"] for r in cells] == ["socket0"] * 8 + ["socket1"] * 8
    q = readings(cells, n)
    lim = robot.arm.limits
    assert ((q >= lim[:, 0]) & (q <= lim[:, 1])).all()
    name, pose = rows.truth["fixtures"]["front"]
    sockets = fixture.place(pose)
    want = np.array([sockets[r["point"]] for r in cells])
    assert np.abs(true_points(robot, q, WORLD) - want).max() < 1e-9
    # the fixture's two sockets are 50 mm apart wherever it stands
    assert np.linalg.norm(sockets["socket1"] - sockets["socket0"]) == pytest.approx(0.05, abs=1e-15)
    # the readings are the true robot's, not the rigid arm's: without the drives' effects it misses
    rigid = robot.with_effects(Effects())
    assert np.linalg.norm(true_points(rigid, q, WORLD) - want, axis=1).max() > 1e-4
    # a random redundancy: the poses in one socket differ (3 equations, 6 or 7 readings)
    assert np.degrees(np.ptp(q[:8], axis=0)).max() > 30


def test_readings_are_what_the_encoders_say():
    """The drive stands at q + s q + A sin(h q + phi): the arm without those errors, at that angle, is in the
    socket; at the reading it is not."""
    s1, A, h, phi = 4e-4, math.radians(0.03), 3, 0.7
    robot, rng = draw(ARM6, 5, Effects(encoder_scale={1: s1}, periodic=[(4, h, A, phi)]))
    socket = reachable_point(robot, rng, WORLD)
    rows = socket_rows(robot, {"s": socket}, 6, rng, WORLD)
    q = rows.q
    drive = q.copy()
    drive[:, 0] += s1 * q[:, 0]
    drive[:, 3] += A * np.sin(h * q[:, 3] + phi)
    plain = robot.with_effects(Effects())
    assert np.abs(true_points(plain, drive, WORLD) - socket).max() < 1e-9
    assert np.linalg.norm(true_points(plain, q, WORLD) - socket, axis=1).min() > 1e-5


def test_contact_noise_scatters_the_ball_about_the_socket():
    robot, rng = draw(ARM6, 3, Effects())
    socket = reachable_point(robot, rng, WORLD)
    sd = 50e-6
    rows = socket_rows(robot, {"s": socket}, 120, rng, WORLD, contact_noise=sd)
    off = true_points(robot, rows.q, WORLD) - socket
    assert np.abs(off - (rows.truth["targets"] - socket)).max() < 1e-9      # where the noise put it
    assert np.std(off, axis=0) == pytest.approx([sd] * 3, rel=0.2)
    assert np.abs(off.mean(axis=0)).max() < 4 * sd / math.sqrt(120)


def test_two_balls_each_in_the_socket(tmp_path):
    """Touch rows of a tool of two points (``tool`` column): each ball at its own true offset sits in the socket."""
    robot, rng = draw(ARM7, 4)
    socket = reachable_point(robot, rng, WORLD)
    balls = {"ball_a": robot.geometry.tool + [0.03, 0.0, 0.0], "ball_b": robot.geometry.tool + [-0.02, 0.01, 0.04]}
    a, b = (socket_rows(robot, {"s": socket}, 5, rng, WORLD, tool=k, offset=v) for k, v in balls.items())
    head, cells = read((a + b).write_csv(tmp_path / "balls.csv"))
    assert head[-2:] == ["point", "tool"]
    q = readings(cells, robot.arm.n)
    for k, offset in balls.items():
        mine = [i for i, r in enumerate(cells) if r["tool"] == k]
        assert len(mine) == 5
        assert np.abs(true_points(robot, q[mine], WORLD, offset) - socket).max() < 1e-9
    assert (a + b).truth["tools"].keys() == balls.keys()


def test_points_on_a_plane(tmp_path):
    robot, rng = draw(ARM7_DH, 6)
    origin = reachable_point(robot, rng, WORLD)
    normal = np.array([0.1, -0.2, 1.0])
    rows = plane_rows(robot, "table", origin, normal, 12, rng, WORLD, radius=0.08, cone=math.radians(60))
    head, cells = read(rows.write_csv(tmp_path / "plane.csv"))
    assert head[-1] == "plane" and {r["plane"] for r in cells} == {"table"}
    q = readings(cells, robot.arm.n)
    p = true_points(robot, q, WORLD)
    u = normal / np.linalg.norm(normal)
    assert np.abs((p - origin) @ u).max() < 1e-9                            # on the plane
    assert np.linalg.norm(p - origin, axis=1).max() < 0.08 + 1e-9
    assert np.ptp(p @ np.linalg.svd(np.eye(3) - np.outer(u, u))[0][:, :2], axis=0).min() > 0.04   # spread on it
    # the tool's axis points into the face, within 60 degrees of its inward normal
    axis = robot.state(q, mount=WORLD.mount_compliance).flange[:, :3, 2] @ WORLD.base()[:3, :3].T
    assert (axis @ -u > math.cos(math.radians(60.5))).all()


def test_a_draw_wire_pivot_reads_the_distance(tmp_path):
    robot, rng = draw(ARM6, 7)
    pivot = reachable_point(robot, rng, WORLD) + [0.0, 0.0, -0.2]
    exact = pivot_rows(robot, "wire", pivot, 20, rng, WORLD, reach=(0.2, 0.5))
    head, cells = read(exact.write_csv(tmp_path / "wire.csv"))
    assert head[-2:] == ["point", "distance_mm"]
    q = readings(cells, robot.arm.n)
    d = np.linalg.norm(true_points(robot, q, WORLD) - pivot, axis=1)
    written = np.array([float(r["distance_mm"]) for r in cells]) / 1000
    assert np.abs(written - d).max() < 1e-12
    assert ((d >= 0.2) & (d <= 0.5)).all() and np.ptp(d) > 0.1
    sd = 30e-6
    noisy = pivot_rows(robot, "wire", pivot, 200, rng, WORLD, reach=(0.2, 0.5), noise=sd)
    err = noisy.distance - np.linalg.norm(true_points(robot, noisy.q, WORLD) - pivot, axis=1)
    assert np.std(err) == pytest.approx(sd, rel=0.2)


def test_tracker_rows_of_a_tool_of_several_points(tmp_path):
    """One pose measured at each nest: consecutive rows with the same readings; the nests are one rigid body."""
    robot, rng = draw(ARM6, 8)
    nests = {"smr1": np.array([0.05, 0.0, 0.09]), "smr2": np.array([-0.04, 0.03, 0.1]),
             "smr3": np.array([0.0, -0.06, 0.08])}
    q = sample(robot, 5, rng)
    rows = tool_rows(robot, q, nests, rng, WORLD, noise=0.0)
    head, cells = read(rows.write_csv(tmp_path / "nests.csv"))
    assert head[robot.arm.n:] == ["x_mm", "y_mm", "z_mm", "tool"]
    assert [r["tool"] for r in cells] == ["smr1", "smr2", "smr3"] * 5
    qq = readings(cells, robot.arm.n)
    xyz = np.array([[float(r[c]) for c in ("x_mm", "y_mm", "z_mm")] for r in cells]) / 1000
    for i in range(5):
        assert np.ptp(qq[3 * i:3 * i + 3], axis=0).max() == 0          # one pose
        for a in range(3):
            for b in range(a):
                ka, kb = f"smr{a + 1}", f"smr{b + 1}"
                assert np.linalg.norm(xyz[3 * i + a] - xyz[3 * i + b]) == pytest.approx(
                    np.linalg.norm(nests[ka] - nests[kb]), abs=1e-12)
    for k, offset in nests.items():
        mine = [i for i, r in enumerate(cells) if r["tool"] == k]
        assert np.abs(xyz[mine] - true_points(robot, q, WORLD, offset)).max() < 1e-12


def test_one_file_of_every_kind_and_several_sessions(tmp_path):
    """Touch rows, pivot rows and tracker rows in one file: the touch rows leave x/y/z empty, distance_mm stands on
    pivot rows only, a session column names each row's session; each placement of the fixture is its own."""
    robot, rng = draw(ARM6, 9, Effects(stiffness={2: 3e5}))
    fixture = two_sockets()
    a = fixture_session(robot, fixture, 4, rng, Session("left"))
    b = fixture_session(robot, fixture, 4, rng, Session("right", base_xyz=(0.0, 1.0, 0.0)))
    wire = pivot_rows(robot, "wire", reachable_point(robot, rng, Session("left")), 4, rng, Session("left"),
                      reach=(0.1, 0.6))
    nests = tool_rows(robot, sample(robot, 2, rng), {"n1": np.array([0.0, 0.0, 0.1]), "n2": np.array([0.03, 0, 0.1])},
                      rng, Session("left"))
    every = a + b + wire + nests
    head, cells = read(every.write_csv(tmp_path / "all.csv"))
    n = robot.arm.n
    assert head == [f"q{j + 1}_deg" for j in range(n)] + ["x_mm", "y_mm", "z_mm", "point", "distance_mm", "tool",
                                                          "session"]
    kinds = [("touch" if r["point"].startswith("socket") else "wire" if r["point"] else "tracker") for r in cells]
    assert kinds == ["touch"] * 16 + ["wire"] * 4 + ["tracker"] * 4
    for r, kind in zip(cells, kinds):
        assert (r["x_mm"] != "") == (kind == "tracker") and (r["distance_mm"] != "") == (kind == "wire")
        assert (r["tool"] != "") == (kind == "tracker")
    assert [r["session"] for r in cells] == ["left"] * 8 + ["right"] * 8 + ["left"] * 8
    poses = every.truth["fixtures"]
    assert set(poses) == {"left", "right"} and np.abs(poses["left"][1] - poses["right"][1]).max() > 1e-3
    q = readings(cells, n)
    for name, ses in (("left", Session("left")), ("right", Session("right", base_xyz=(0.0, 1.0, 0.0)))):
        rows = [i for i, r in enumerate(cells) if r["session"] == name and r["point"].startswith("socket")]
        want = fixture.place(poses[name][1])
        # each session's rows alone, in their order (the same readings and moves as in the whole file)
        assert np.abs(true_points(robot, q[rows], ses) - [want[cells[i]["point"]] for i in rows]).max() < 1e-9


def test_the_fixture_file():
    blocks = [two_sockets(), Fixture("plate", {"p1": np.array([0.0, 0.0, 0.0]), "p2": np.array([0.1, 0.0, 0.0]),
                                               "p3": np.array([0.0, 0.1, 0.0]), "p4": np.array([0.1, 0.1, 0.002])},
                                     sd_mm=0.005)]
    doc = tomllib.loads(fixture_toml(blocks))
    assert [f["name"] for f in doc["fixture"]] == ["two_sockets", "plate"]
    assert [f["sd_mm"] for f in doc["fixture"]] == [0.01, 0.005]
    for f, block in zip(doc["fixture"], blocks):
        assert f["points"].keys() == block.points.keys()
        for k, p in f["points"].items():
            assert np.allclose(np.array(p) / 1000, block.points[k], rtol=1e-15, atol=1e-18)


def test_a_payload_per_row_is_carried_and_written(tmp_path):
    """With a compliant joint, the payload of each row bends the arm: the readings are solved under it, and the file
    says it (payload_kg)."""
    robot, rng = draw(ARM6, 10, Effects(stiffness={2: 1e5, 3: 1e5}))
    socket = reachable_point(robot, rng, WORLD)
    load = np.array([0.0, 5.0, 10.0, 2.5])
    rows = socket_rows(robot, {"s": socket}, 4, rng, WORLD, payload=load)
    head, cells = read(rows.write_csv(tmp_path / "load.csv"))
    assert head[-2:] == ["point", "payload_kg"] and [float(r["payload_kg"]) for r in cells] == load.tolist()
    q = readings(cells, robot.arm.n)
    state = robot.state(q, load, mount=WORLD.mount_compliance)
    B = WORLD.base()
    assert np.abs(robot.tool_point(state) @ B[:3, :3].T + B[:3, 3] - socket).max() < 1e-9
    empty = robot.state(q, np.zeros(4), mount=WORLD.mount_compliance)
    assert np.linalg.norm(robot.tool_point(empty) - robot.tool_point(state), axis=1)[1:].min() > 1e-5
