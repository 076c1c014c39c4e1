"""ABB RAPID (``.mod``): read a module's targets, write a measurement run.

What is read (``!`` starts a comment; a statement ends with ``;``):

- declarations (``CONST``, ``PERS``, ``VAR``) of ``jointtarget`` (``[[rax_1..rax_6], [eax_a..eax_f]]``, deg; mm for
  a linear axis), ``robtarget`` (``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a..eax_f]]``: mm, a
  unit quaternion ``[w, x, y, z]``, the configuration), ``tooldata`` (its ``tframe``) and ``wobjdata`` (its user
  and object frames, ``uframe * oframe``);
- ``MoveJ``, ``MoveL``, ``MoveJDO``, ``MoveLDO``, ``MoveAbsJ`` and ``MoveC`` (two targets) to a declared target
  or a literal, with their tool and ``\\WObj`` (default ``wobj0``, the robot base; ``tool0`` is the flange).

A pose names its configuration with ``cf1, cf4, cf6`` (the quadrants of axes 1, 4 and 6, ``floor(angle / 90
deg)``), which the inverse kinematics keeps and the filter writes again from the corrected joints; ``cfx`` is the
robot type's own and kept as written. A tool or work object not declared is an error, as are a robot-held work
object or a stationary tool (conventions this filter does not know), any other ``Move...``, ``Search...`` or
``Trigg...`` instruction, and a quaternion that is not a unit one, each naming the line and token. A move to an
expression (``Offs(...)``, ``RelTool(...)``, ``CRobT()``) is listed, not filtered; an external axis the robot has
given as ``9E9`` (not used) leaves the target as written.
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
    axes_of,
    axis_fields,
    frame,
    matrix_quaternion,
    quadrant,
    quaternion_matrix,
    reading,
    tokenize,
)

MOVES = {"movej": 1, "movel": 1, "movejdo": 1, "moveldo": 1, "moveabsj": 1, "movec": 2}
UNKNOWN = ("move", "search", "trigg")
RAX = tuple(f"rax_{k}" for k in range(1, 7))
EAX = tuple(f"eax_{k}" for k in "abcdef")
#: an external axis not used
UNUSED = 9e8


def _frame(trans, rot) -> np.ndarray:
    return frame(np.asarray(trans, float) / 1000.0, quaternion_matrix(rot))


def read(path: str, prismatic: tuple[bool, ...]) -> Program:
    """The module at ``path`` for a robot whose joints are ``prismatic`` (per joint)."""
    text = open(path, encoding="utf-8", errors="surrogateescape", newline="").read()
    tokens = [t for t in tokenize(text, "!") if t.kind != "newline"]
    main, external = axes_of(prismatic)
    r = _Reader(path, text, tokens, prismatic, main, external)
    r.read()
    targets = r.used + [t for t in r.variables.values() if t not in r.used]
    return Program("rapid", path, {path: text}, targets, r.tools, r.wobjs, r.skipped, main, external)


class _Reader:
    def __init__(self, path, text, tokens, prismatic, main, external):
        self.path, self.text, self.tokens = path, text, tokens
        self.prismatic, self.main, self.external = prismatic, main, external
        self.variables: dict[str, Target] = {}
        self.tools: dict[str, np.ndarray] = {"tool0": np.eye(4)}
        self.wobjs: dict[str, np.ndarray] = {"wobj0": np.eye(4)}
        self.used: list[Target] = []
        self.skipped: list[Skipped] = []

    def read(self) -> None:
        i, N = 0, len(self.tokens)
        while i < N:
            t = self.tokens[i]
            stop = self._end(i)
            word = t.text.lower()
            if t.kind == "name" and word in ("const", "pers", "var"):
                self.declaration(Cursor(self.path, self.text, self.tokens, i + 1, stop))
                i = stop + 1
            elif t.kind == "name" and word in MOVES and not self._called(i):
                self.move(Cursor(self.path, self.text, self.tokens, i + 1, stop), t)
                i = stop + 1
            elif t.kind == "name" and word.startswith(UNKNOWN) and not self._called(i) and i + 1 < N \
                    and self.tokens[i + 1].text not in (":=", "(", ",", ")", ";"):
                raise ProgramError(f"unknown instruction for compensate: {t.text} (it reads MoveJ, MoveL, MoveJDO, "
                                   "MoveLDO, MoveAbsJ, MoveC); replace it, or filter the module without it",
                                   self.path, t.line, t.text)
            else:
                i += 1

    def _called(self, i: int) -> bool:
        """The name at ``i`` is not an instruction (a declaration's type, an argument)."""
        prev = self.tokens[i - 1] if i else None
        return prev is not None and prev.text in (",", "(", ":=", "\\")

    def _end(self, i: int) -> int:
        """The index of the ``;`` ending the statement at ``i`` (or the end)."""
        depth = 0
        for k in range(i, len(self.tokens)):
            t = self.tokens[k]
            if t.text in "([{":
                depth += 1
            elif t.text in ")]}":
                depth -= 1
            elif t.text == ";" and depth <= 0:
                return k
        return len(self.tokens)

    # --- declarations --------------------------------------------------------------------------------------

    def declaration(self, c: Cursor) -> None:
        typ_tok = c.next()
        typ = typ_tok.text.lower()
        if typ not in ("jointtarget", "robtarget", "tooldata", "wobjdata"):
            return
        name_tok = c.next()
        if c.at("{") or not c.at(":="):        # an array, or no value
            return
        c.next()
        value = self.value(c)
        name = name_tok.text
        if typ == "tooldata":
            robhold, tframe = _flag(value[0]), value[1]
            if not robhold:
                c.error("a stationary tool (robhold FALSE): a convention this filter does not know", name_tok)
            self.tools[name.lower()] = self._pose_frame(c, tframe, name_tok)
        elif typ == "wobjdata":
            if _flag(value[0]):
                c.error("a work object the robot holds (robhold TRUE): a convention this filter does not know",
                        name_tok)
            self.wobjs[name.lower()] = (self._pose_frame(c, value[3], name_tok)
                                        @ self._pose_frame(c, value[4], name_tok))
        else:
            self.variables[name.lower()] = self.target(c, name, name_tok, typ, value)

    def value(self, c: Cursor):
        """A RAPID value: a nested list of :class:`Number` s, booleans (1/0) and strings."""
        t = c.peek()
        if t.text == "[":
            c.next()
            out = []
            while not c.at("]"):
                out.append(self.value(c))
                if c.at(","):
                    c.next()
                elif not c.at("]"):
                    c.error("expected ',' or ']'")
            c.next()
            return out
        if t.kind == "number" or t.text in "+-":
            return c.number()
        c.next()
        if t.text.upper() in ("TRUE", "FALSE"):
            return t.text.upper() == "TRUE"
        return t.text

    def _pose_frame(self, c, pose, tok) -> np.ndarray:
        trans, rot = [_numbers(c, v, 3 if k == 0 else 4, tok) for k, v in enumerate(pose)]
        self._unit(c, rot, tok)
        return _frame([x.value for x in trans], [x.value for x in rot])

    @staticmethod
    def _unit(c, rot, tok):
        norm = np.linalg.norm([x.value for x in rot])
        if abs(norm - 1.0) > 1e-3:
            c.error(f"the quaternion [{', '.join(x.text for x in rot)}] is not a unit one (norm {norm:.6g}): not "
                    "the orientation convention of a robtarget", tok)

    def target(self, c: Cursor, name: str, tok, typ: str, value) -> Target:
        prismatic, main, external = self.prismatic, self.main, self.external
        if typ == "jointtarget":
            rax, eax = _numbers(c, value[0], 6, tok), _numbers(c, value[1], 6, tok)
            numbers = {**dict(zip(RAX, rax)), **dict(zip(EAX, eax))}
            t = Target(name, "joints", c.file, tok.line, tok.text, numbers)
            q = np.zeros(len(prismatic))
            for j, x in zip(main + external, rax[:len(main)] + eax[:len(external)]):
                q[j] = reading(x.value, prismatic[j])
            unused = [k for j, k, x in zip(external, EAX, eax) if abs(x.value) >= UNUSED]
            if unused:
                t.unfit = f"gives {', '.join(unused)} as not used (9E9), an axis of the robot"
                return t
            t.q = q
            t.write = lambda q, P: {**axis_fields(q, prismatic, main, RAX), **axis_fields(q, prismatic, external, EAX)}
            return t
        trans, rot = _numbers(c, value[0], 3, tok), _numbers(c, value[1], 4, tok)
        conf, eax = _numbers(c, value[2], 4, tok), _numbers(c, value[3], 6, tok)
        self._unit(c, rot, tok)
        numbers = {**dict(zip("xyz", trans)), **dict(zip(("q1", "q2", "q3", "q4"), rot)),
                   **dict(zip(("cf1", "cf4", "cf6", "cfx"), conf)), **dict(zip(EAX, eax))}
        t = Target(name, "pose", c.file, tok.line, tok.text, numbers)
        unused = [k for j, k, x in zip(external, EAX, eax) if abs(x.value) >= UNUSED]
        if unused:
            t.unfit = f"gives {', '.join(unused)} as not used (9E9), an axis of the robot"
            return t
        t.pose = _frame([x.value for x in trans], [x.value for x in rot])
        t.external = {j: reading(x.value, prismatic[j]) for j, x in zip(external, eax)}
        quads = [(k, main[a]) for k, a in (("cf1", 0), ("cf4", 3), ("cf6", 5)) if a < len(main)]
        t.config = {k: int(numbers[k].value) for k, _ in quads}

        def write(q, P, t=t):
            quat = matrix_quaternion(P[:3, :3], np.array([t.numbers[k].value for k in ("q1", "q2", "q3", "q4")]))
            out = {k: (P[i, 3] * 1000.0, "mm") for i, k in enumerate("xyz")}
            out.update({k: (quat[i], "quaternion") for i, k in enumerate(("q1", "q2", "q3", "q4"))})
            out.update({k: (quadrant(q[j]), "int") for k, j in quads})
            out.update(axis_fields(q, prismatic, external, EAX))
            return out
        t.write = write
        t.matches = lambda q, t=t: np.all([quadrant(q[:, j]) == t.config[k] for k, j in quads] or [True], axis=0)
        return t

    # --- moves ---------------------------------------------------------------------------------------------

    def move(self, c: Cursor, ins) -> None:
        args = self.arguments(c)
        n_targets = MOVES[ins.text.lower()]
        positional = [a for a in args if a[0] is None]
        switches = {a[0].lower(): a[1] for a in args if a[0] is not None}
        if len(positional) < n_targets + 3:
            c.error(f"{ins.text} needs {'two targets' if n_targets == 2 else 'a target'}, a speed, a zone and a tool",
                    ins)
        tool_tok = positional[n_targets + 2][1][0]
        tool = tool_tok.text.lower()
        if tool not in self.tools:
            raise ProgramError(f"a target without a tool: {tool_tok.text} is not a tooldata this module declares",
                               c.file, tool_tok.line, tool_tok.text)
        wobj = "wobj0"
        if "wobj" in switches:
            w = switches["wobj"][0]
            wobj = w.text.lower()
            if wobj not in self.wobjs:
                raise ProgramError(f"{w.text} is not a wobjdata this module declares", c.file, w.line, w.text)
        for k in range(n_targets):
            toks = positional[k][1]
            first = toks[0]
            if first.text == "[":
                sub = Cursor(c.file, c.text, self.tokens, self.tokens.index(first), self.tokens.index(toks[-1]) + 1)
                value = self.value(sub)
                typ = "jointtarget" if ins.text.lower() == "moveabsj" else "robtarget"
                target = self.target(sub, "", first, typ, value)
            elif len(toks) == 1 and first.text.lower() in self.variables:
                target = self.variables[first.text.lower()]
            else:
                self.skipped.append(Skipped(c.file, first.line, first.text, "an expression computed at run time"))
                continue
            if target not in self.used:
                self.used.append(target)
            target.uses.append(Use(c.file, ins.line, ins.text, tool, wobj))

    def arguments(self, c: Cursor) -> list[tuple[str | None, list]]:
        """The instruction's arguments: ``(None, tokens)`` for a positional one, ``(name, tokens)`` for an
        optional one (``\\Name:=value`` or ``\\Switch``), in order."""
        out, current, depth = [], [], 0
        name = None
        while c.peek() is not None:
            t = c.next()
            if t.text in "([{":
                depth += 1
            elif t.text in ")]}":
                depth -= 1
            if depth == 0 and t.text in (",", "\\"):
                if current or name:
                    out.append((name, current))
                current, name = [], None
                if t.text == "\\":
                    name = c.next().text
                    if c.at(":="):
                        c.next()
                continue
            current.append(t)
        if current or name:
            out.append((name, current))
        return out


def _flag(v) -> bool:
    return bool(v) if isinstance(v, bool) else False


def _numbers(c: Cursor, value, n: int, tok) -> list[Number]:
    if not isinstance(value, list) or len(value) != n or not all(isinstance(x, Number) for x in value):
        c.error(f"expected a list of {n} numbers", tok)
    return value


def measurement_program(name: str, values: np.ndarray, prismatic: tuple[bool, ...], wait_s: float | None,
                        handshake: tuple[int, int] | None) -> str:
    """A RAPID module that moves to each row of ``values`` (deg; mm for a linear axis) with ``MoveAbsJ`` and waits
    for the measurement: ``WaitTime wait_s``, or sets digital output ``do<o>`` and waits for input ``di<i>``
    (``handshake = (o, i)``), then clears it and waits for the input to fall."""
    main, external = axes_of(prismatic)
    lines = [f"MODULE {name}", "  ! casadical plan-poses: the measurement run, one pose after another"]
    for i, row in enumerate(values, start=1):
        rax = [repr(float(row[j])) for j in main] + ["0"] * (6 - len(main))
        eax = [repr(float(row[j])) for j in external] + ["9E9"] * (6 - len(external))
        lines.append(f"  CONST jointtarget jm{i} := [[{','.join(rax)}],[{','.join(eax)}]];")
    lines.append("  PROC main()")
    for i in range(1, len(values) + 1):
        lines += [f"    ! pose {i}", f"    MoveAbsJ jm{i}\\NoEOffs, v200, fine, tool0;"]
        if handshake is None:
            lines.append(f"    WaitTime {wait_s!r};")
        else:
            out, inp = handshake
            lines += [f"    SetDO do{out}, 1;", f"    WaitDI di{inp}, 1;", f"    SetDO do{out}, 0;",
                      f"    WaitDI di{inp}, 0;"]
    lines += ["  ENDPROC", "ENDMODULE"]
    return "\n".join(lines) + "\n"
