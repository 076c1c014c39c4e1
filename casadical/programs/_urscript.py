"""URScript (Universal Robots, ``.script``/``.urscript``): read a program's targets, write a measurement run.

What is read, statement by statement (a statement is a line; ``#`` starts a comment):

- ``movej``, ``movel``, ``movep`` with a joint list ``[q1, ..., qn]`` (rad; m for a linear axis), a pose
  ``p[x, y, z, rx, ry, rz]`` (m, rotation vector in rad, robot base frame) or the name of a variable
  assigned one (``global home = [...]``, ``pick = p[...]``; the last assignment before the move), or
  ``get_inverse_kin(pose, qnear=joints)`` of such a pose (as PolyScope writes waypoints: the inverse kinematics
  nearest ``qnear``);
- ``set_tcp(p[...])`` or ``set_tcp(name)``: the tool (TCP) of the moves after it; ``--tool`` gives the one
  the program starts with (the installation's), else a move before any ``set_tcp`` is an error.

A move to an expression (``pose_trans(...)``, ``get_actual_tcp_pose()``) is computed at run time: it is listed,
not filtered. ``movec``, ``servoj``, ``servoc`` and any other ``move...`` are errors naming the line and token.
A move to a pose takes the inverse kinematics nearest the joints before it, as the controller does.
"""

from __future__ import annotations

import numpy as np

from ..errors import ProgramError
from ._program import (
    Cursor,
    Number,
    Program,
    Skipped,
    Target,
    Use,
    frame,
    matrix_rotvec,
    rotvec_matrix,
    statements,
    tokenize,
)

MOVES = ("movej", "movel", "movep")
#: instructions that move to targets this filter does not correct
UNKNOWN_MOVES = ("movec", "servoj", "servoc", "servol")
POSE_FIELDS = ("x", "y", "z", "rx", "ry", "rz")


def read(path: str, prismatic: tuple[bool, ...], tool: np.ndarray | None = None) -> Program:
    """The program at ``path`` for a robot whose joints are ``prismatic`` (per joint); ``tool``: the TCP the
    program starts with (4x4, m), None: unknown."""
    text = open(path, encoding="utf-8", newline="").read()
    tokens = tokenize(text, "#")
    n = len(prismatic)
    variables: dict[str, Target | np.ndarray] = {}
    targets: list[Target] = []
    tools: dict[str, np.ndarray] = {}
    if tool is not None:
        tools["--tool"] = tool
    active = "--tool" if tool is not None else None
    skipped: list[Skipped] = []
    used: set[int] = set()
    for a, b in statements(tokens):
        c = Cursor(path, text, tokens, a, b)
        if c.at("global") or c.at("local"):
            c.next()
        first = c.peek()
        if first.kind == "name" and c.at("=", 1) and (c.at("p", 2) and c.at("[", 3) or c.at("[", 2)):
            c.next()
            c.next()
            variables[first.text] = _literal(c, first.text, n, prismatic)
            continue
        if first.kind != "name":
            continue
        name = first.text.lower()
        if name == "set_tcp":
            c.next()
            c.expect("(")
            arg = c.peek()
            if c.at("p") and c.at("[", 1):
                t = _literal(c, "", n, prismatic)
                key = f"set_tcp line {first.line}"
                tools[key] = t.pose
            elif arg.kind == "name" and isinstance(variables.get(arg.text), Target) \
                    and variables[arg.text].kind == "pose":
                key = arg.text
                tools[key] = variables[arg.text].pose
            else:
                c.error("set_tcp takes a pose p[x, y, z, rx, ry, rz] or a variable assigned one", arg)
            active = key
            continue
        if name in UNKNOWN_MOVES or (name.startswith("move") and name not in MOVES and c.at("(", 1)):
            c.error(f"unknown instruction for compensate: {first.text} moves to targets it does not correct (it "
                    f"reads {', '.join(MOVES)}); replace it, or filter the program without it", first)
        if name not in MOVES:
            continue
        c.next()
        c.expect("(")
        arg = c.peek()
        target = None
        if c.at("p") and c.at("[", 1) or c.at("["):
            target = _literal(c, "", n, prismatic)
            if not (c.at(",") or c.at(")")):     # a literal in an expression
                skipped.append(Skipped(path, arg.line, arg.text, "an expression computed at run time"))
                continue
            targets.append(target)
        elif arg.kind == "name" and isinstance(variables.get(arg.text), Target) and (c.at(",", 1) or c.at(")", 1)):
            target = variables[arg.text]
            if id(target) not in used:
                used.add(id(target))
                targets.append(target)
        elif arg.text == "get_inverse_kin" and c.at("(", 1):
            c.next()
            c.next()
            target = _inverse_kin(c, variables, n, prismatic)
            if target is None:
                skipped.append(Skipped(path, arg.line, arg.text, "an expression computed at run time"))
                continue
            if id(target) not in used:
                used.add(id(target))
                targets.append(target)
        else:
            skipped.append(Skipped(path, arg.line, arg.text, "an expression computed at run time"))
            continue
        if active is None:
            raise ProgramError(f"a target without a tool: {first.text} before any set_tcp; add set_tcp(p[...]) "
                               "before it, or give the installation's TCP with --tool X,Y,Z,RX,RY,RZ (m, rad)",
                               path, first.line, arg.text)
        target.uses.append(Use(path, first.line, first.text, active, "base"))
    main = list(range(n))
    return Program("urscript", path, {path: text}, targets, tools, {"base": np.eye(4)}, skipped, main, [])


def _inverse_kin(c: Cursor, variables: dict, n: int, prismatic) -> Target | None:
    """``get_inverse_kin(pose[, qnear=joints][, ...])`` after its ``(``: the pose target, its ``near`` the joints
    qnear names (a list or a joint variable); None when the pose is an expression."""
    t = c.peek()
    if c.at("p") and c.at("[", 1):
        target = _literal(c, "", n, prismatic)
    elif t.kind == "name" and isinstance(variables.get(t.text), Target) and variables[t.text].kind == "pose":
        c.next()
        target = variables[t.text]
    else:
        return None
    if not (c.at(",") or c.at(")")):
        return None
    if c.at(","):
        c.next()
        if c.at("qnear") and c.at("=", 1):
            c.next()
            c.next()
        q = c.peek()
        if c.at("["):
            target.near = _literal(c, "", n, prismatic).q
        elif q is not None and q.kind == "name" and isinstance(variables.get(q.text), Target) \
                and variables[q.text].kind == "joints":
            target.near = variables[q.text].q
    return target


def _literal(c: Cursor, name: str, n: int, prismatic) -> Target:
    """A joint list ``[...]`` (``n`` values) or pose ``p[...]`` at the cursor."""
    start = c.peek()
    pose = c.at("p")
    if pose:
        c.next()
    c.expect("[")
    numbers: list[Number] = []
    while True:
        numbers.append(c.number())
        if c.at("]"):
            c.next()
            break
        c.expect(",")
    if pose:
        if len(numbers) != 6:
            c.error(f"a pose has 6 values x, y, z, rx, ry, rz (m, rad), this one {len(numbers)}", start)
        v = np.array([x.value for x in numbers])
        fields = dict(zip(POSE_FIELDS, numbers))
        t = Target(name, "pose", c.file, start.line, start.text, fields, pose=frame(v[:3], rotvec_matrix(v[3:])))

        def write(q, P, t=t):
            rv = matrix_rotvec(P[:3, :3], np.array([t.numbers[k].value for k in POSE_FIELDS[3:]]))
            return {**{k: (P[i, 3], "m") for i, k in enumerate("xyz")},
                    **{k: (rv[i], "rad") for i, k in enumerate(POSE_FIELDS[3:])}}
        t.write = write
        t.matches = lambda q: np.ones(len(q), bool)
        return t
    if len(numbers) != n:
        c.error(f"a joint list of {len(numbers)} values, but the calibrated robot has {n} joints", start)
    fields = {f"q{j + 1}": x for j, x in enumerate(numbers)}
    t = Target(name, "joints", c.file, start.line, start.text, fields, q=np.array([x.value for x in numbers]))
    t.write = lambda q, P: {f"q{j + 1}": (q[j], "m" if prismatic[j] else "rad") for j in range(n)}
    return t


def measurement_program(name: str, values: np.ndarray, prismatic: tuple[bool, ...], wait_s: float | None,
                        handshake: tuple[int, int] | None) -> str:
    """A URScript program that moves to each row of ``values`` (the files' units: deg; mm for a linear axis; written
    in rad and m) with ``movej`` and waits for the measurement: ``wait_s`` seconds, or sets digital output
    ``handshake[0]`` and waits for input ``handshake[1]`` (then clears the output and waits for the input to
    fall)."""
    lines = [f"def {name}():", "  # casadical plan-poses: the measurement run, one pose after another"]
    for i, row in enumerate(values, start=1):
        joints = ", ".join(repr(float(v) / 1000.0 if p else float(np.radians(v))) for v, p in zip(row, prismatic))
        lines += [f"  # pose {i}", f"  movej([{joints}], a=0.5, v=0.3)"]
        if handshake is None:
            lines.append(f"  sleep({wait_s!r})")
        else:
            out, inp = handshake
            lines += [f"  set_standard_digital_out({out}, True)",
                      f"  while not get_standard_digital_in({inp}):", "    sync()", "  end",
                      f"  set_standard_digital_out({out}, False)",
                      f"  while get_standard_digital_in({inp}):", "    sync()", "  end"]
    lines.append("end")
    return "\n".join(lines) + "\n"
