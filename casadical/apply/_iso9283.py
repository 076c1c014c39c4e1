"""ISO 9283 pose and distance characteristics: accuracy and repeatability, before and after compensation.

For each commanded pose ``j`` (a ``pose`` of a ``cube``), attained ``n`` times (its ``cycle`` s) at ``x_i, y_i,
z_i`` and angles ``a_i, b_i, c_i`` (about x, y, z), commanded at ``x_c, y_c, z_c`` and ``a_c, b_c, c_c``:

- pose accuracy: ``AP_x = x_bar - x_c`` (likewise y, z), ``AP_p = sqrt(AP_x^2 + AP_y^2 + AP_z^2)``, and
  ``AP_a = a_bar - a_c``, ``AP_b``, ``AP_c`` (the bars are means over the cycles);
- pose repeatability: ``l_i = |(x_i, y_i, z_i) - (x_bar, y_bar, z_bar)|``, ``RP_l = l_bar + 3 S_l`` with
  ``S_l = sqrt(sum (l_i - l_bar)^2 / (n - 1))``; ``RP_a = +-3 S_a`` with ``S_a = sqrt(sum (a_i - a_bar)^2 /
  (n - 1))``, likewise b and c; it needs two cycles or more (None with one);
- distance accuracy between poses ``A`` and ``B`` (cycle by cycle): ``D_c = |P_cA - P_cB|``, ``D_i = |P_Ai -
  P_Bi|``, ``AD_p = D_bar - D_c``; distance repeatability ``RD_p = +-3 sqrt(sum (D_i - D_bar)^2 / (n - 1))``;
  in orientation ``D_ai = a_Ai - a_Bi``, ``D_ca = a_cA - a_cB``, ``AD_a = D_a_bar - D_ca`` and ``RD_a = +-3
  sqrt(sum (D_ai - D_a_bar)^2 / (n - 1))``, likewise b and c.

Angles are the measurement files' ``R = Rx(a) Ry(b) Rz(c)`` (intrinsic x-y-z, ``rx_deg, ry_deg, rz_deg``), their
differences wrapped to +-180 deg. Positions in mm, angles in deg. A cube's summary is the largest of its poses'
(and pairs') figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Poses:
    """Rows of a measured file: which pose, which cycle, commanded and attained (robot base frame).

    ``commanded``, ``attained``: (N, 3) mm; ``commanded_angles``, ``attained_angles``: (N, 3) deg or None.
    """

    cycle: np.ndarray
    pose: np.ndarray
    cube: np.ndarray
    commanded: np.ndarray
    attained: np.ndarray
    commanded_angles: np.ndarray | None = None
    attained_angles: np.ndarray | None = None

    def subset(self, rows: np.ndarray) -> "Poses":
        pick = (lambda a: None if a is None else a[rows])
        return Poses(self.cycle[rows], self.pose[rows], self.cube[rows], self.commanded[rows], self.attained[rows],
                     pick(self.commanded_angles), pick(self.attained_angles))

    def groups(self) -> list[tuple[object, str, np.ndarray]]:
        """(cube, pose, rows) in the order of first appearance."""
        out, seen = [], {}
        for i, key in enumerate(zip(self.cube.tolist(), self.pose.tolist())):
            if key not in seen:
                seen[key] = len(out)
                out.append((key[0], key[1], []))
            out[seen[key]][2].append(i)
        return [(c, p, np.array(r)) for c, p, r in out]


def wrap(deg: np.ndarray) -> np.ndarray:
    """Angle differences to (-180, 180] deg."""
    return -((-np.asarray(deg, float) + 180.0) % 360.0 - 180.0)


def _std(v: np.ndarray) -> float:
    return float(np.std(v, ddof=1))


def pose_characteristics(p: Poses) -> list[dict]:
    """AP and RP of each pose (the module's formulas): a dict per pose with ``cube``, ``pose``, ``n``, ``AP_p``,
    ``AP_x``, ``AP_y``, ``AP_z``, ``RP_l`` and, with angles, ``AP_a/b/c``, ``RP_a/b/c`` (None where undefined)."""
    out = []
    for cube, pose, rows in p.groups():
        x, xc = p.attained[rows], p.commanded[rows].mean(axis=0)
        n = len(rows)
        mean = x.mean(axis=0)
        ap = mean - xc
        d = {"cube": cube, "pose": pose, "n": n, "AP_p": float(np.linalg.norm(ap)),
             "AP_x": float(ap[0]), "AP_y": float(ap[1]), "AP_z": float(ap[2]), "RP_l": None}
        if n >= 2:
            l = np.linalg.norm(x - mean, axis=1)
            d["RP_l"] = float(l.mean() + 3 * _std(l))
        if p.attained_angles is not None and p.commanded_angles is not None:
            dev = wrap(p.attained_angles[rows] - p.commanded_angles[rows])      # a_i - a_c
            for k, name in enumerate("abc"):
                d[f"AP_{name}"] = float(dev[:, k].mean())
                d[f"RP_{name}"] = 3 * _std(dev[:, k]) if n >= 2 else None
        out.append(d)
    return out


def distance_characteristics(p: Poses, pairs: list[tuple[str, str]]) -> list[dict]:
    """AD and RD of each pair of poses of each cube (cycles matched): ``cube``, ``pair``, ``n``, ``D_c``,
    ``AD_p``, ``RD_p`` and, with angles, ``AD_a/b/c``, ``RD_a/b/c`` (RD None with one cycle)."""
    out = []
    for cube in dict.fromkeys(p.cube.tolist()):
        for a, b in pairs:
            ra = {c: i for i, c in enumerate(p.cycle.tolist()) if p.cube[i] == cube and p.pose[i] == a}
            rb = {c: i for i, c in enumerate(p.cycle.tolist()) if p.cube[i] == cube and p.pose[i] == b}
            cycles = [c for c in ra if c in rb]
            if not cycles:
                continue
            ia, ib = np.array([ra[c] for c in cycles]), np.array([rb[c] for c in cycles])
            dc = float(np.linalg.norm(p.commanded[ia[0]] - p.commanded[ib[0]]))
            D = np.linalg.norm(p.attained[ia] - p.attained[ib], axis=1)
            d = {"cube": cube, "pair": f"{a}-{b}", "n": len(cycles), "D_c": dc, "AD_p": float(D.mean() - dc),
                 "RD_p": 3 * _std(D) if len(D) >= 2 else None}
            if p.attained_angles is not None and p.commanded_angles is not None:
                Da = wrap(p.attained_angles[ia] - p.attained_angles[ib])           # D_ai = a_Ai - a_Bi
                Dca = wrap(p.commanded_angles[ia[0]] - p.commanded_angles[ib[0]])
                for k, name in enumerate("abc"):
                    d[f"AD_{name}"] = float(wrap(Da[:, k].mean() - Dca[k]))
                    d[f"RD_{name}"] = 3 * _std(Da[:, k]) if len(D) >= 2 else None
            out.append(d)
    return out


def cube_summary(poses: list[dict], distances: list[dict]) -> list[dict]:
    """Per cube: the largest AP_p, RP_l, |AD_p|, RD_p of its poses and pairs (None where none is defined)."""
    out = []
    for cube in dict.fromkeys(d["cube"] for d in poses):
        mine = [d for d in poses if d["cube"] == cube]
        pairs = [d for d in distances if d["cube"] == cube]
        top = (lambda v: max(v) if v else None)
        out.append({"cube": cube, "poses": len(mine), "AP_p": top([d["AP_p"] for d in mine]),
                    "RP_l": top([d["RP_l"] for d in mine if d["RP_l"] is not None]),
                    "AD_p": top([abs(d["AD_p"]) for d in pairs]),
                    "RD_p": top([d["RD_p"] for d in pairs if d["RD_p"] is not None])})
    return out


def rigid_fit(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t with ``R source + t`` nearest ``target`` in least squares (Kabsch)."""
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    U, _, Vt = np.linalg.svd((source - cs).T @ (target - ct))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, ct - R @ cs


@dataclass
class Iso9283:
    """The report: for each state (``before``; ``after (predicted)`` by a calibration; ``after (measured)``
    where the file has rows measured after compensation) the poses', pairs' and cubes' figures."""

    states: dict[str, dict] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    source: str = ""

    def add(self, name: str, p: Poses, pairs: list[tuple[str, str]]) -> None:
        poses = pose_characteristics(p)
        distances = distance_characteristics(p, pairs)
        self.states[name] = {"poses": poses, "distances": distances, "cubes": cube_summary(poses, distances),
                             "cycles": int(max(d["n"] for d in poses)) if poses else 0}

    @property
    def repeated(self) -> bool:
        return any(s["cycles"] >= 2 for s in self.states.values())

    def to_dict(self) -> dict:
        return {"measured": self.source, "states": list(self.states), **self.states, "notes": self.notes}

    def _side_by_side(self, key: str, field_name: str) -> tuple[list[str], list[list]]:
        names = list(self.states)
        first = self.states[names[0]][key]
        header = ["cube", "pose" if key == "poses" else "pair" if key == "distances" else "poses"]
        rows = []
        for i, d in enumerate(first):
            label = d.get("pose", d.get("pair", d.get("poses")))
            row = [str(d["cube"]), str(label)]
            for n in names:
                other = self.states[n][key]
                match = next((o for o in other if o["cube"] == d["cube"]
                              and o.get("pose", o.get("pair")) == d.get("pose", d.get("pair"))), None)
                row.append(_fmt(None if match is None else match.get(field_name)))
            rows.append(row)
        return header + [f"{field_name} {n}" for n in names], rows

    def text(self, max_rows: int = 40) -> str:
        """The terminal report: per cube, and per pose (the first ``max_rows``), each state side by side."""
        lines = [f"ISO 9283 pose characteristics of {self.source}: states {', '.join(self.states)}"]
        for key, fields in (("cubes", ("AP_p", "RP_l", "AD_p")), ("poses", ("AP_p", "RP_l"))):
            for f in fields:
                header, rows = self._side_by_side(key, f)
                if all(all(c == "-" for c in r[2:]) for r in rows):
                    continue
                lines.append(f"{'per cube, largest' if key == 'cubes' else 'per pose'} {f} (mm):")
                lines.append("  " + "  ".join(f"{h:>22s}" if k >= 2 else f"{h:>6s}" for k, h in enumerate(header)))
                for r in rows[:max_rows]:
                    lines.append("  " + "  ".join(f"{c:>22s}" if k >= 2 else f"{c:>6s}" for k, c in enumerate(r)))
                if len(rows) > max_rows:
                    lines.append(f"  ... {len(rows) - max_rows} more (the JSON and HTML reports list all)")
        lines += ["note: " + n for n in self.notes]
        return "\n".join(lines)

    def html(self) -> str:
        from ..html._page import Page

        page = Page(f"ISO 9283: {self.source}")
        page.heading(f"ISO 9283 pose characteristics: {self.source}", 1)
        page.para("Pose accuracy AP and repeatability RP, distance accuracy AD and repeatability RD, with the "
                  "formulas of ISO 9283 (docs/guide.md, ISO 9283): "
                  + ", ".join(f"<b>{s}</b>" for s in self.states) + " side by side.")
        page.items(self.notes)
        for key, title, fields in (("cubes", "Per cube (the largest of its poses and pairs)", ("AP_p", "RP_l",
                                                                                             "AD_p", "RD_p")),
                                   ("poses", "Per pose", ("AP_p", "AP_x", "AP_y", "AP_z", "RP_l", "AP_a", "AP_b",
                                                          "AP_c", "RP_a", "RP_b", "RP_c")),
                                   ("distances", "Per pair of poses", ("AD_p", "RD_p", "AD_a", "AD_b", "AD_c",
                                                                        "RD_a", "RD_b", "RD_c"))):
            first = self.states[next(iter(self.states))][key]
            if not first:
                continue
            page.heading(title, 2)
            header = ["cube", "pose" if key != "distances" else "pair"] if key != "cubes" else ["cube"]
            cols = [(f, s) for f in fields for s in self.states
                    if any(d.get(f) is not None for d in self.states[s][key])]
            rows = []
            for d in first:
                ident = [str(d["cube"])] + ([str(d.get("pose", d.get("pair")))] if key != "cubes" else [])
                row = list(ident)
                for f, s in cols:
                    match = next((o for o in self.states[s][key] if o["cube"] == d["cube"]
                                  and o.get("pose", o.get("pair")) == d.get("pose", d.get("pair"))), None)
                    row.append(_fmt(None if match is None else match.get(f)))
                rows.append(row)
            page.table(header + [f"{f} {s} ({'deg' if f[-1] in 'abc' else 'mm'})" for f, s in cols], rows,
                       text_columns=tuple(range(len(header))))
        return page.html()


def _fmt(v) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.4f}"
