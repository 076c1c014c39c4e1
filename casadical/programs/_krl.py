"""KUKA KRL (``.src`` with its ``.dat``): read a program's targets, write a measurement run.

What is read (``;`` starts a comment, so folds are read through):

- the ``.dat`` (and ``.src``) declarations and assignments of ``E6AXIS``, ``AXIS`` (joint targets: ``A1..A6``
  in deg, ``E1..E6`` in deg or mm for a linear axis), ``E6POS``, ``POS`` and ``FRAME`` (poses: ``X Y Z`` in mm,
  ``A B C`` in deg, ``R = Rz(A) Ry(B) Rx(C)``, with ``S`` and ``T``) and ``FDAT`` (``TOOL_NO``, ``BASE_NO``);
- ``TOOL_DATA[n]`` and ``BASE_DATA[n]`` assignments (a ``$config.dat``-style file: ``--config``, or the program's
  files), or ``--tool n=X,Y,Z,A,B,C`` / ``--base n=...``;
- in the ``.src``, in order: ``PTP``, ``LIN`` (a variable or an aggregate ``{...}``) and ``CIRC`` (two); the tool
  and base they move with: ``$TOOL = TOOL_DATA[n]`` (or a ``FRAME`` variable or aggregate), ``$BASE = ...``
  likewise (``$NULLFRAME``: the robot base), ``BAS(#TOOL, n)``, ``BAS(#BASE, n)``, and the inline forms'
  ``FDAT_ACT = F...`` (its ``TOOL_NO``, ``BASE_NO``; ``TOOL_NO 0`` the flange, ``BASE_NO 0`` the robot base).

``$BASE`` is taken in the robot's base frame (for a robot on a track: the track's fixed frame, frame 0 of the
robot file). A pose names its configuration with ``T`` (bit k set: axis k+1 negative), which the inverse
kinematics keeps (``S``'s bits are the robot type's own and are kept as written). A move before any tool, or with
``TOOL_DATA[n]`` not given, is an error; ``SPTP``, ``SLIN``, ``SCIRC``, ``SPL`` and the relative moves are errors
naming the line and token. An aggregate that leaves out a component (the current position's is taken at run
time) is listed and left as written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ProgramError
from ._program import (
    Cursor,
    Program,
    Skipped,
    Target,
    Use,
    abc_matrix,
    axes_of,
    axis_fields,
    frame,
    matrix_abc,
    reading,
    statements,
    tokenize,
)

MOVES = ("PTP", "LIN", "CIRC")
UNKNOWN_MOVES = ("SPTP", "SLIN", "SCIRC", "SPL", "PTP_REL", "LIN_REL", "CIRC_REL", "SPTP_REL", "SLIN_REL",
                 "SCIRC_REL", "SPLINE", "PTP_SPLINE")
POSE = ("X", "Y", "Z", "A", "B", "C")
JOINTS = ("A1", "A2", "A3", "A4", "A5", "A6")
EXTERNAL = ("E1", "E2", "E3", "E4", "E5", "E6")
NULLFRAME = "$NULLFRAME"


def frame_of(values) -> np.ndarray:
    """X, Y, Z (mm), A, B, C (deg) -> 4x4 (m)."""
    v = np.asarray(values, float)
    return frame(v[:3] / 1000.0, abc_matrix(v[3:]))


def read(path: str, prismatic: tuple[bool, ...], tools: dict[str, np.ndarray] | None = None,
         bases: dict[str, np.ndarray] | None = None, config: str | None = None) -> Program:
    """The program ``path`` (``.src``) and its ``.dat`` beside it (if any); ``tools``/``bases``: ``TOOL_DATA[n]``
    / ``BASE_DATA[n]`` given (key ``"n"``, 4x4 in m); ``config``: a ``$config.dat``-style file with more."""
    main, external = axes_of(prismatic)
    reader = _Reader(prismatic, main, external)
    dat = Path(path).with_suffix(".dat")
    if not dat.exists():
        dat = next((p for p in Path(path).parent.glob("*") if p.name.lower() == dat.name.lower()), dat)
    files = {}
    if config is not None:
        reader.declarations(config, open(config, encoding="utf-8", errors="surrogateescape", newline="").read(),
                            frames_only=True)
    for f in ([str(dat)] if dat.exists() else []) + [path]:
        files[f] = open(f, encoding="utf-8", errors="surrogateescape", newline="").read()
    if dat.exists():
        reader.declarations(str(dat), files[str(dat)])
    for k, T in (tools or {}).items():
        reader.tools[f"TOOL_DATA[{k}]"] = T
    for k, T in (bases or {}).items():
        reader.bases[f"BASE_DATA[{k}]"] = T
    reader.program(path, files[path])
    return Program("krl", path, files, reader.ordered(), reader.tools, reader.bases, reader.skipped, main, external)


class _Reader:
    def __init__(self, prismatic, main, external):
        self.prismatic, self.main, self.external = prismatic, main, external
        self.variables: dict[str, Target] = {}
        self.frames: dict[str, np.ndarray] = {}
        self.fdat: dict[str, tuple[int | None, int | None]] = {}
        self.tools: dict[str, np.ndarray] = {"TOOL_DATA[0]": np.eye(4)}
        self.bases: dict[str, np.ndarray] = {NULLFRAME: np.eye(4), "BASE_DATA[0]": np.eye(4)}
        self.used: list[Target] = []
        self.skipped: list[Skipped] = []

    # --- declarations ------------------------------------------------------------------------------------

    def declarations(self, file: str, text: str, frames_only: bool = False) -> None:
        tokens = tokenize(text, ";")
        for a, b in statements(tokens):
            c = Cursor(file, text, tokens, a, b)
            self.declaration(c, frames_only)

    def declaration(self, c: Cursor, frames_only: bool = False) -> bool:
        """``[DECL [GLOBAL] [CONST] TYPE] NAME = {...}`` or ``TOOL_DATA[n] = {...}`` at the cursor: read it (True),
        or leave the cursor (False)."""
        start = c.i
        typ = None
        if c.at("DECL"):
            c.next()
            while c.at("GLOBAL") or c.at("CONST"):
                c.next()
            typ = c.next().text.upper()
        name_tok = c.peek()
        if name_tok is None or name_tok.kind != "name":
            c.i = start
            return False
        c.next()
        name = name_tok.text.upper()
        if c.at("["):        # TOOL_DATA[n], BASE_DATA[n]
            c.next()
            index = c.next()
            c.expect("]")
            name = f"{name}[{index.text}]"
        if not (c.at("=") and c.at("{", 1)):
            c.i = start
            return False
        c.next()
        values, numbers, kind = self.aggregate(c)
        if name.startswith(("TOOL_DATA[", "BASE_DATA[")) or typ == "FRAME":
            if not all(k in values for k in POSE):
                c.error(f"a frame needs X, Y, Z, A, B, C; {name} has {', '.join(values) or 'none'}", name_tok)
            T = frame_of([values[k] for k in POSE])
            if name.startswith("TOOL_DATA["):
                self.tools[name] = T
            elif name.startswith("BASE_DATA["):
                self.bases[name] = T
            else:
                self.frames[name] = T
        if typ == "FDAT" or "TOOL_NO" in values or "BASE_NO" in values:
            self.fdat[name] = (values.get("TOOL_NO"), values.get("BASE_NO"))
        elif not frames_only and kind is not None and not name.startswith(("TOOL_DATA[", "BASE_DATA[")):
            self.variables[name] = self.target(c, name, name_tok, values, numbers, kind)
        return True

    def aggregate(self, c: Cursor) -> tuple[dict, dict, str | None]:
        """``{[TYPE:] FIELD value, ...}``: numeric fields' values and numbers, and the kind of target it spells."""
        c.expect("{")
        if c.peek(1) is not None and c.at(":", 1):
            c.next()
            c.next()
        values, numbers = {}, {}
        while not c.at("}"):
            field_tok = c.next()
            key = field_tok.text.upper()
            if c.at("["):
                c.next()
                c.expect("]")
            t = c.peek()
            if t.kind == "number" or (t.kind == "op" and t.text in "+-"):
                num = c.number()
                numbers[key], values[key] = num, num.value
            elif t.text == "{":
                self.aggregate(c)
            else:
                c.next()
            if c.at(","):
                c.next()
            elif not c.at("}"):
                c.error("expected ',' or '}' in an aggregate")
        c.next()
        keys = set(values)
        kind = "joints" if keys & set(JOINTS) else "pose" if keys & set(POSE) else None
        return values, numbers, kind

    def target(self, c: Cursor, name, tok, values, numbers, kind) -> Target:
        t = Target(name, kind, c.file, tok.line, tok.text, numbers)
        prismatic, main, external = self.prismatic, self.main, self.external
        ext_names = EXTERNAL[:len(external)]
        if kind == "joints":
            need = list(JOINTS[:len(main)]) + list(ext_names)
            missing = [k for k in need if k not in values]
            if missing:
                t.unfit = f"leaves out {', '.join(missing)} (taken from the current position at run time)"
                return t
            q = np.zeros(len(prismatic))
            for j, k in zip(main + external, JOINTS[:len(main)] + ext_names):
                q[j] = reading(values[k], prismatic[j])
            t.q = q
            t.write = lambda q, P: {**axis_fields(q, prismatic, main, JOINTS), **axis_fields(q, prismatic, external,
                                                                                            ext_names)}
            return t
        missing = [k for k in POSE if k not in values] + [k for k in ext_names if k not in values]
        if missing:
            t.unfit = f"leaves out {', '.join(missing)} (taken from the current position at run time)"
            return t
        t.pose = frame_of([values[k] for k in POSE])
        t.external = {j: reading(values[k], prismatic[j]) for j, k in zip(external, ext_names)}
        if "T" in values:
            t.config["T"] = int(values["T"])
        if "S" in values:
            t.config["S"] = int(values["S"])

        def write(q, P, t=t):
            abc = matrix_abc(P[:3, :3], np.array([t.numbers[k].value for k in "ABC"]))
            out = {k: (P[i, 3] * 1000.0, "mm") for i, k in enumerate("XYZ")}
            out.update({k: (abc[i], "deg") for i, k in enumerate("ABC")})
            out.update(axis_fields(q, prismatic, external, ext_names))
            if "T" in t.numbers:
                out["T"] = (turn_bits(q, main, int(t.numbers["T"].value)), "int")
            return out
        t.write = write
        t.matches = lambda q, t=t: (np.ones(len(q), bool) if "T" not in t.config else np.all(
            [(q[:, j] < 0) == bool(t.config["T"] >> k & 1) for k, j in enumerate(main)], axis=0))
        return t

    # --- the program ---------------------------------------------------------------------------------------

    def program(self, file: str, text: str) -> None:
        tokens = tokenize(text, ";")
        tool: str | None = None
        base: str | None = NULLFRAME
        for a, b in statements(tokens):
            c = Cursor(file, text, tokens, a, b)
            first = c.peek()
            word = first.text.upper()
            if word in ("$TOOL", "$BASE") and c.at("=", 1):
                c.next()
                c.next()
                key = self.frame_value(c, word, first)
                if word == "$TOOL":
                    tool = key
                else:
                    base = key
                continue
            if word == "BAS" and c.at("(", 1):
                c.next()
                c.next()
                what = c.next().text.upper()
                if what in ("#TOOL", "#BASE") and c.at(","):
                    c.next()
                    n = int(c.number().value)
                    if what == "#TOOL":
                        tool = f"TOOL_DATA[{n}]"
                    else:
                        base = f"BASE_DATA[{n}]" if n else NULLFRAME
                continue
            if word == "FDAT_ACT" and c.at("=", 1):
                c.next()
                c.next()
                ref = c.next()
                if ref.text.upper() not in self.fdat:
                    c.error(f"FDAT_ACT names {ref.text}, which no FDAT declaration of the program defines", ref)
                tn, bn = self.fdat[ref.text.upper()]
                if tn is not None:
                    tool = f"TOOL_DATA[{int(tn)}]"
                if bn is not None:
                    base = f"BASE_DATA[{int(bn)}]" if int(bn) else NULLFRAME
                continue
            if word in UNKNOWN_MOVES:
                c.error(f"unknown instruction for compensate: {first.text} (it reads {', '.join(MOVES)}); replace "
                        "it, or filter the program without it", first)
            if word in MOVES:
                c.next()
                for k in range(2 if word == "CIRC" else 1):
                    if k:
                        c.expect(",")
                    self.move(c, word, first, tool, base)
                continue
            if word == "DECL" or (first.kind == "name" and c.at("=", 1) and c.at("{", 2)):
                self.declaration(c)

    def frame_value(self, c: Cursor, word: str, first) -> str:
        """The right-hand side of ``$TOOL =`` / ``$BASE =``: the key of the frame it names."""
        t = c.peek()
        frames = self.tools if word == "$TOOL" else self.bases
        if t.text == "{":
            values, _, _ = self.aggregate(c)
            if not all(k in values for k in POSE):
                c.error(f"{word} needs X, Y, Z, A, B, C", t)
            key = f"{word} line {first.line}"
            frames[key] = frame_of([values[k] for k in POSE])
            return key
        name = c.next().text.upper()
        if c.at("["):
            c.next()
            index = c.next().text
            c.expect("]")
            return f"{name}[{index}]"
        if name in ("$NULLFRAME", "$WORLD"):
            return NULLFRAME if word == "$BASE" else "TOOL_DATA[0]"
        if name in self.frames:
            frames[name] = self.frames[name]
            return name
        c.error(f"{word} = {t.text}: not a frame the program or its options define (TOOL_DATA[n], BASE_DATA[n], a "
                "FRAME, an aggregate)", t)

    def move(self, c: Cursor, word: str, first, tool, base) -> None:
        t = c.peek()
        if t.text == "{":
            values, numbers, kind = self.aggregate(c)
            if kind is None:
                c.error(f"{word} to an aggregate without A1..A6 or X, Y, Z, A, B, C", t)
            target = self.target(c, "", t, values, numbers, kind)
        elif t.kind == "name" and t.text.upper() in self.variables:
            c.next()
            target = self.variables[t.text.upper()]
        else:
            self.skipped.append(Skipped(c.file, t.line, t.text, "not a point the program declares: computed at "
                                                                "run time"))
            c.next()
            return
        if tool is None or tool not in self.tools:
            what = "before any $TOOL, BAS(#TOOL, n) or FDAT_ACT" if tool is None else f"{tool} is not given"
            raise ProgramError(f"a target without a tool: {word} {what}; give it with --tool N=X,Y,Z,A,B,C "
                               "(mm, deg) or --config $config.dat", c.file, first.line, t.text)
        if base not in self.bases:
            raise ProgramError(f"a target without a base: {base} is not given; give it with --base N=X,Y,Z,A,B,C "
                               "(mm, deg) or --config $config.dat", c.file, first.line, t.text)
        if target not in self.used:
            self.used.append(target)
        target.uses.append(Use(c.file, first.line, word, tool, base))

    def ordered(self) -> list[Target]:
        """The targets moved to, in order, then those declared and never moved to (frames not: they are tools and
        bases)."""
        return self.used + [t for k, t in self.variables.items() if t not in self.used and k not in self.frames]


def turn_bits(q: np.ndarray, main: list[int], old: int = 0) -> int:
    """KUKA ``T``: bit k set where main axis k+1 is negative (bits above the axes kept from ``old``)."""
    bits = old & ~((1 << len(main)) - 1)
    for k, j in enumerate(main):
        if q[j] < 0:
            bits |= 1 << k
    return bits


def measurement_program(name: str, values: np.ndarray, prismatic: tuple[bool, ...], wait_s: float | None,
                        handshake: tuple[int, int] | None) -> tuple[str, str]:
    """The ``.src`` and ``.dat`` of a KRL program that moves to each row of ``values`` (deg; mm for a linear axis)
    with ``PTP`` to an ``E6AXIS`` and waits for the measurement: ``WAIT SEC wait_s``, or sets ``$OUT[o]`` and
    waits for ``$IN[i]`` (``handshake = (o, i)``), then clears it and waits for the input to fall."""
    main, external = axes_of(prismatic)
    src = [f"DEF {name}( )", "; casadical plan-poses: the measurement run, one pose after another",
           "BAS(#INITMOV, 0)", "BAS(#TOOL, 0)", "BAS(#BASE, 0)"]
    dat = [f"DEFDAT {name}"]
    for i, row in enumerate(values, start=1):
        fields = [f"{k} {float(row[j])!r}" for j, k in zip(main, JOINTS)]
        fields += [f"{k} {float(row[j])!r}" for j, k in zip(external, EXTERNAL)]
        dat.append(f"DECL E6AXIS XM{i}={{{','.join(fields)}}}")
        src += [f"; pose {i}", f"PTP XM{i}"]
        if handshake is None:
            src.append(f"WAIT SEC {wait_s!r}")
        else:
            out, inp = handshake
            src += [f"$OUT[{out}]=TRUE", f"WAIT FOR $IN[{inp}]", f"$OUT[{out}]=FALSE", f"WAIT FOR NOT $IN[{inp}]"]
    src.append("END")
    dat.append("ENDDAT")
    return "\n".join(src) + "\n", "\n".join(dat) + "\n"
