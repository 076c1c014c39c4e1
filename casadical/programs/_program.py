"""What every robot language shares: the program's targets, their numbers in the text, the controllers'
conventions, and writing numbers back in the program's own format.

A program is read into a :class:`Program`: its files' text (a KUKA program is its ``.src`` and ``.dat``), its
:class:`Target` s (a joint target or a Cartesian pose, with the :class:`Number` s that spell it: where in which
file, as written) and the tool and base (work object) frames its moves name. Filtering replaces the numbers of
the targets and nothing else: every other byte is kept (:meth:`Program.edited`).

Conventions (each controller's own; the tests check them against an independent forward model):

- URScript: joints in rad, poses ``p[x, y, z, rx, ry, rz]`` in m with a rotation vector (axis times angle, rad);
- KUKA KRL: joints ``A1..A6`` in deg, external axes ``E1..E6`` (deg, or mm for a linear axis), poses ``X Y Z`` in
  mm and ``A B C`` in deg, ``R = Rz(A) Ry(B) Rx(C)`` (Z-Y-X Euler angles);
- ABB RAPID: joints ``rax_1..rax_6`` in deg, external axes ``eax_a..eax_f`` (deg, or mm), poses ``trans`` in mm
  and ``rot`` a unit quaternion ``[q1, q2, q3, q4] = [w, x, y, z]``.

The robot's joints map to a program's axes in order: its first six revolute joints are the main axes (``A1..A6``,
``rax_1..rax_6``, a URScript joint list), its other joints (a linear axis: a track, a lifting column) the external
axes in their order (``E1..``, ``eax_a..``). Rotations use scipy's, a well-kept library.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import ProgramError

#: program file types and their language
SUFFIXES = {".script": "urscript", ".urscript": "urscript", ".src": "krl", ".mod": "rapid"}

#: how close a written number is to the value it stands for, by what it is (its unit): far below what a controller
#: resolves, so that reading the program back gives the computed joints to 1e-6 deg
TOLERANCE = {"deg": 1e-9, "rad": 1e-11, "mm": 1e-7, "m": 1e-10, "quaternion": 1e-11, "int": 0.5}
#: decimals at most
MAX_DECIMALS = 12


def language_of(path: str | Path) -> str | None:
    """The language of a program file by its type (None: not a program; a CSV, say)."""
    return SUFFIXES.get(Path(path).suffix.lower())


# --- the text -----------------------------------------------------------------------------------------------


@dataclass
class Token:
    """One token of a program: ``name``, ``number``, ``string``, ``op`` (any other character, ``:=``) or
    ``newline``; ``start``/``end`` are offsets in the file's text, ``line`` 1-based."""

    kind: str
    text: str
    start: int
    end: int
    line: int


_TOKEN = re.compile(r"""
 (?P<newline>\n)
|(?P<space>[ \t\r\f\v]+)
|(?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
|(?P<name>[A-Za-z_$#][A-Za-z0-9_$]*)
|(?P<string>"[^"\n]*"|'[^'\n]*')
|(?P<op>:=|==|<>|<=|>=|\S)
""", re.X)


def tokenize(text: str, comment: str) -> list[Token]:
    """The tokens of ``text``; ``comment`` starts a comment to the end of its line (outside a string)."""
    out, line, pos = [], 1, 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        kind = m.lastgroup
        if kind == "op" and m.group() == comment:
            end = text.find("\n", pos)
            pos = len(text) if end < 0 else end
            continue
        if kind == "newline":
            out.append(Token("newline", "\n", m.start(), m.end(), line))
            line += 1
        elif kind != "space":
            out.append(Token(kind, m.group(), m.start(), m.end(), line))
        pos = m.end()
    return out


@dataclass
class Number:
    """A number as the program spells it: file, offsets of its text (a sign included), the text, its value."""

    file: str
    start: int
    end: int
    text: str
    value: float
    line: int


class Cursor:
    """Reads a file's tokens one at a time; errors name the file, line and token."""

    def __init__(self, file: str, text: str, tokens: list[Token], start: int = 0, stop: int | None = None):
        self.file, self.text, self.tokens = file, text, tokens
        self.i = start
        self.stop = len(tokens) if stop is None else stop

    def peek(self, k: int = 0) -> Token | None:
        j = self.i + k
        return self.tokens[j] if j < self.stop else None

    def next(self) -> Token:
        t = self.peek()
        if t is None:
            last = self.tokens[self.stop - 1] if self.stop else None
            raise ProgramError("unexpected end of the statement", self.file, last.line if last else None,
                               last.text if last else None)
        self.i += 1
        return t

    def at(self, text: str, k: int = 0) -> bool:
        t = self.peek(k)
        return t is not None and t.text.lower() == text.lower()

    def expect(self, text: str) -> Token:
        t = self.peek()
        if t is None or t.text.lower() != text.lower():
            self.error(f"expected {text!r}", t)
        return self.next()

    def number(self) -> Number:
        """A number with its sign (``-`` or ``+`` before it)."""
        t = self.next()
        sign, first = "", t
        if t.kind == "op" and t.text in "+-":
            sign, t = t.text, self.next()
        if t.kind != "number":
            self.error("expected a number", t)
        return Number(self.file, first.start, t.end, self.text[first.start:t.end], float(sign + t.text), t.line)

    def error(self, message: str, token: Token | None = None):
        t = token or self.peek() or (self.tokens[self.stop - 1] if self.stop else None)
        raise ProgramError(message, self.file, t.line if t else None, t.text if t else None)


def statements(tokens: list[Token], separators: str = "\n") -> list[tuple[int, int]]:
    """Token ranges ``[start, stop)`` of the statements: split at newlines (``separators`` with ``;`` for RAPID),
    never inside brackets (a RAPID declaration spans lines)."""
    out, depth, start = [], 0, 0
    for k, t in enumerate(tokens):
        if t.kind == "op" and t.text in "([{":
            depth += 1
        elif t.kind == "op" and t.text in ")]}":
            depth = max(depth - 1, 0)
        split = (t.kind == "newline" and "\n" in separators and depth == 0) or (
            t.kind == "op" and t.text in separators and depth == 0)
        if split:
            if k > start:
                out.append((start, k))
            start = k + 1
    if start < len(tokens):
        out.append((start, len(tokens)))
    return [(a, b) for a, b in ((a, _skip_newlines(tokens, a, b)) for a, b in out) if b > a]


def _skip_newlines(tokens, a, b):
    while b > a and tokens[b - 1].kind == "newline":
        b -= 1
    return b


# --- targets ------------------------------------------------------------------------------------------------


@dataclass
class Use:
    """A move to a target: where, the instruction, and the tool and base (work object) frames it names."""

    file: str
    line: int
    instruction: str
    tool: str | None
    base: str


@dataclass
class Target:
    """A joint target or a Cartesian pose of the program.

    Attributes
    ----------
    name : str
        Its variable's name, ``""`` for a literal in a move.
    kind : str
        ``joints`` or ``pose``.
    file, line, token : str, int, str
        Where it is spelt (its declaration or literal): for messages.
    numbers : dict
        Field -> :class:`Number` (``A1``, ``X``, ``q1`` ... : the language's names).
    q : ndarray or None
        A joint target's joints (robot order; rad, m for a linear axis).
    pose : ndarray or None
        A pose's 4x4 matrix (m) in its base frame (KRL ``$BASE``, RAPID work object; the robot base in
        URScript).
    external : dict
        A pose's external axes it gives: joint index (0-based) -> value (rad or m).
    config : dict
        The configuration a pose names (KUKA ``S``, ``T``; ABB ``cf1, cf4, cf6, cfx``).
    uses : list of Use
        The moves to it.
    unfit : str
        Why it cannot be corrected whatever the calibration (a partial aggregate, ...); "" when it can.
    write : callable
        ``write(q, pose)`` -> ``{field: (value, unit)}``: the fields' new values for joints ``q`` (SI, robot
        order) and, for a pose, the pose (4x4, m, its base frame); :meth:`Program.edited` formats them.
    matches : callable
        ``matches(q)`` -> bool per row: joints ``q`` (SI, (N, n)) are in the configuration the pose names.
    near : ndarray or None
        The joints the controller's inverse kinematics of the pose starts from, where the program names them
        (URScript ``get_inverse_kin(pose, qnear=...)``); None: the joints before it.
    """

    name: str
    kind: str
    file: str
    line: int
    token: str
    numbers: dict[str, Number]
    q: np.ndarray | None = None
    pose: np.ndarray | None = None
    external: dict[int, float] = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    uses: list[Use] = field(default_factory=list)
    unfit: str = ""
    write: Callable | None = None
    matches: Callable | None = None
    near: np.ndarray | None = None

    @property
    def label(self) -> str:
        """How the report names it: its variable, or the literal's line."""
        return self.name or f"{Path(self.file).name}:{self.line}"


@dataclass
class Skipped:
    """A move whose target the program computes at run time (an expression, a relative move): not filtered."""

    file: str
    line: int
    token: str
    why: str


@dataclass
class Program:
    """A program read from its files: text, targets, frames.

    Attributes
    ----------
    language : str
        ``urscript``, ``krl`` or ``rapid``.
    path : str
        The program file given (a KUKA ``.src``; its ``.dat`` is in ``files`` too).
    files : dict
        Path -> text of every file read.
    targets : list of Target
        In the order the program moves to them (then the targets it never moves to).
    tools, bases : dict
        Frame name -> 4x4 matrix (m): the tool (TCP on the flange) and base (work object in the robot base
        frame) frames the moves name.
    skipped : list of Skipped
        Moves to targets computed at run time.
    main_axes, external_axes : list of int
        The robot joints (0-based) of the program's main and external axes (:func:`axes_of`).
    """

    language: str
    path: str
    files: dict[str, str]
    targets: list[Target]
    tools: dict[str, np.ndarray]
    bases: dict[str, np.ndarray]
    skipped: list[Skipped] = field(default_factory=list)
    main_axes: list[int] = field(default_factory=list)
    external_axes: list[int] = field(default_factory=list)

    def edited(self, values: dict[int, dict[str, tuple[float, str]]]) -> dict[str, str]:
        """The files' text with the numbers of targets replaced: ``values[k]`` is target ``k``'s
        ``{field: (value, unit)}``; a number whose written value is already within the tolerance of its unit
        is kept as written. Returns path -> new text (every file, changed or not)."""
        edits: dict[str, list[tuple[int, int, str]]] = {f: [] for f in self.files}
        for k, fields in values.items():
            t = self.targets[k]
            for name, (value, unit) in fields.items():
                num = t.numbers[name]
                edits[num.file].append((num.start, num.end, format_like(num.text, value, unit)))
        out = {}
        for f, text in self.files.items():
            for start, end, new in sorted(edits[f], reverse=True):
                text = text[:start] + new + text[end:]
            out[f] = text
        return out


def axes_of(prismatic: tuple[bool, ...], main: int = 6) -> tuple[list[int], list[int]]:
    """The robot joints of a program's main axes (its first ``main`` revolute joints) and external axes (the
    others, in order), 0-based."""
    revolute = [j for j, p in enumerate(prismatic) if not p]
    first = revolute[:main]
    return first, [j for j in range(len(prismatic)) if j not in first]


def reading(value: float, prismatic: bool) -> float:
    """An axis value as a program writes it (deg; mm for a linear axis) -> the robot's reading (rad; m)."""
    return value / 1000.0 if prismatic else math.radians(value)


def axis_fields(q: np.ndarray, prismatic, axes: list[int], names) -> dict[str, tuple[float, str]]:
    """The fields ``names`` of the robot joints ``axes`` at readings ``q`` (SI) as a program writes them:
    ``{name: (value, unit)}``, deg (mm for a linear axis)."""
    return {k: (q[j] * 1000.0, "mm") if prismatic[j] else (math.degrees(q[j]), "deg") for j, k in zip(axes, names)}


# --- numbers ------------------------------------------------------------------------------------------------


def format_like(old: str, value: float, unit: str) -> str:
    """``value`` written as ``old`` is (fixed point, as many decimals or more, a leading ``+`` kept), with the
    decimals needed to be within :data:`TOLERANCE` of its unit; ``old`` itself when it already is."""
    tol = TOLERANCE[unit]
    body = old.replace(" ", "")
    if abs(float(body) - value) <= tol:
        return old
    if unit == "int":
        text = str(int(round(value)))
    else:
        mantissa = re.split(r"[eE]", body)[0]
        decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
        d = decimals
        while d < MAX_DECIMALS and abs(round(value, d) - value) > tol:
            d += 1
        if abs(value) < 0.5 * 10.0 ** -d:
            value = 0.0
        text = f"{value:.{d}f}"
        if d == 0 and "." in mantissa:
            text += "."
    if body.startswith("+") and not text.startswith("-"):
        text = "+" + text
    return text


# --- orientation conventions --------------------------------------------------------------------------------


def _rotation():
    from scipy.spatial.transform import Rotation  # here: scipy's import costs every command's start-up
    return Rotation


def rotvec_matrix(rv) -> np.ndarray:
    """Rotation vector (rad) -> 3x3 (URScript)."""
    return _rotation().from_rotvec(np.asarray(rv, float)).as_matrix()


def matrix_rotvec(R: np.ndarray, near=None) -> np.ndarray:
    """3x3 -> rotation vector (rad); of the two vectors of a rotation (angle t and t - 2 pi about the axis),
    the one nearest ``near``."""
    rv = _rotation().from_matrix(R).as_rotvec()
    if near is None:
        return rv
    angle = np.linalg.norm(rv)
    if angle < 1e-12:
        return rv
    other = rv * (1 - 2 * math.pi / angle)
    return other if np.linalg.norm(other - near) < np.linalg.norm(rv - near) else rv


def abc_matrix(abc_deg) -> np.ndarray:
    """KUKA A, B, C (deg) -> 3x3: ``Rz(A) Ry(B) Rx(C)``."""
    return _rotation().from_euler("ZYX", np.asarray(abc_deg, float), degrees=True).as_matrix()


def matrix_abc(R: np.ndarray, near=None) -> np.ndarray:
    """3x3 -> KUKA A, B, C (deg); of the two triples of a rotation, each angle wrapped to within 180 deg of
    ``near``'s, the one nearest it."""
    a = _rotation().from_matrix(R).as_euler("ZYX", degrees=True)
    if near is None:
        return a
    near = np.asarray(near, float)
    cands = [a, np.array([a[0] + 180.0, 180.0 - a[1], a[2] + 180.0])]
    cands = [near + (c - near + 180.0) % 360.0 - 180.0 for c in cands]
    return min(cands, key=lambda c: float(np.abs(c - near).sum()))


def quaternion_matrix(q) -> np.ndarray:
    """ABB quaternion ``[q1, q2, q3, q4] = [w, x, y, z]`` -> 3x3 (normalised first)."""
    w, x, y, z = np.asarray(q, float)
    return _rotation().from_quat([x, y, z, w]).as_matrix()


def matrix_quaternion(R: np.ndarray, near=None) -> np.ndarray:
    """3x3 -> ABB quaternion ``[w, x, y, z]``, its sign that of ``near`` (the two quaternions of a rotation)."""
    x, y, z, w = _rotation().from_matrix(R).as_quat()
    q = np.array([w, x, y, z])
    return -q if near is not None and float(np.dot(q, near)) < 0 else q


def frame(xyz_m, R) -> np.ndarray:
    """A 4x4 frame from a translation (m) and a rotation."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, xyz_m
    return T


def quadrant(angle_rad):
    """ABB's quadrant of joint angles: ``floor(angle / 90 deg)`` (0 for 0..90 deg, -1 for -90..0); an int for one
    angle, an int array for several."""
    out = np.floor(np.degrees(angle_rad) / 90.0 + 1e-9).astype(int)
    return int(out) if out.ndim == 0 else out
