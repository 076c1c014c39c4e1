"""Stage ``screen_structure``: what the model of the named causes leaves, and where it lives.

The catalogue never holds every cause a robot has. After the named causes, what the model leaves on the
calibration poses is tested against what an error can vary with (the **covariates**: every joint's reading
``qK``, every joint's gravity torque ``tauK``, the pose's ``time`` or order, and where the point stands for the
instrument: ``azimuth``, ``elevation``, ``distance``), in each way an error can show (the **effects**: a
joint's ``angle``; the point moving in the robot's base frame, ``point_base``; the point moving in the
measurement frame, ``point_measurement``). Each pair is a flexible smooth term: Legendre polynomials of degree
1 to :data:`DEGREE` of the covariate scaled to [-1, 1], times the effect's directions (a joint's angle: the
point's derivative w.r.t. its reading; a frame: its three axes). The model's own parameters are refitted
beside it (linearised at the final fit, robust weights), so structure the model can already take counts for
nothing.

A pair is structure when both hold on the calibration poses:

- an F-test of its columns at the diagnosis' level divided among every pair tried (Bonferroni), and
- held-out gain: on random folds of the calibration poses, the model with the term predicts the left-out
  poses better than the model without it, for most of the poses (a paired sign test at the same level).

The strongest pair is kept, its columns join the model, and the rest are tested again (up to
:data:`MAX_STRUCTURES`). Each becomes an ``unexplained`` finding (not in the model) that says where it lives
in words, with its ``covariate``, ``effect``, ``p_value``, its size on the validation poses (``size_mm``:
the mean norm of the term fitted on the calibration poses, judge only) and what the flexible term would gain
there (``potential_gain_mm``). The validation poses never decide.

Reads ``current`` (the model of the named causes), the folds and the level; adds the findings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import legendre

from ..data import Measurements
from ..result import CalibrationResult
from .candidates import Candidate
from .report import Finding
from .state import DiagnosisRun
from .statistics import nested_test
from .validation import Linearized

#: highest degree of the Legendre basis of a covariate
DEGREE = 4
#: at most this many structures are reported
MAX_STRUCTURES = 3
#: random folds of the held-out check
FOLDS = 5


@dataclass
class Structure:
    """One structure the model leaves: what it varies with, how it shows, its test and sizes."""

    covariate: str
    effect: str
    joint: int | None            # the joint whose angle it moves (effect ``angle``)
    log10_p: float
    test_text: str
    size_mm: float               # mean norm of the fitted term on the validation poses
    potential_gain_mm: float     # validation mean without it minus with it
    held_out_share: float        # share of left-out calibration poses it predicts better
    misses: np.ndarray = field(default_factory=lambda: np.zeros(0, int))   # set-aside poses it accounts for

    def words(self) -> str:
        """Where it lives, in words an engineer reads."""
        return describe_pair(self.covariate, self.effect, self.joint)

    def to_dict(self) -> dict:
        return {"covariate": self.covariate, "effect": self.effect, "p_value": 10 ** self.log10_p,
                "size_mm": self.size_mm, "potential_gain_mm": self.potential_gain_mm}


def describe_pair(covariate: str, effect: str, joint: int | None) -> str:
    """A pair of covariate and effect in words an engineer reads."""
    cov = _covariate_words(covariate)
    if effect == "angle":
        own = covariate == f"q{joint}"
        return (f"joint {joint}'s angle error varies with "
                + ("its own reading (not as any catalogue cause of that joint)" if own else cov))
    if effect == "point_base":
        return f"the point moves in the robot's base frame with {cov}"
    text = f"the point moves in the measurement frame with {cov}"
    if covariate in ("azimuth", "elevation", "distance"):
        text += ": the instrument's own error or the robot's, only another session (the instrument placed " \
                "elsewhere) can tell"
    return text


def _covariate_words(cov: str) -> str:
    if cov.startswith("q"):
        return f"joint {cov[1:]}'s reading"
    if cov.startswith("tau"):
        return f"joint {cov[3:]}'s gravity torque"
    if cov == "time":
        return "the time of the pose (its order in the measurements)"
    return f"the point's {cov} as the instrument sees it"


def _basis(x: np.ndarray, ref: tuple[float, float]) -> np.ndarray:
    """Legendre polynomials of degree 1..DEGREE of ``x`` scaled by ``ref`` (lo, hi) to [-1, 1]: (N, DEGREE)."""
    lo, hi = ref
    t = np.clip(2 * (x - lo) / (hi - lo) - 1, -1.5, 1.5) if hi > lo else np.zeros_like(x)
    return legendre.legvander(t, DEGREE)[:, 1:]


def covariates(res: CalibrationResult, data: Measurements, torques: np.ndarray) -> dict[str, np.ndarray]:
    """Every covariate of the screen at ``data``'s poses (rad, N m, s, m)."""
    out = {f"q{j + 1}": data.q[:, j] for j in range(data.q.shape[1])}
    out.update({f"tau{j + 1}": torques[:, j] for j in range(torques.shape[1])})
    t = data.get("time_s")
    out["time"] = np.asarray(t, float) if t is not None else np.arange(len(data), dtype=float)
    x, y, z = data.xyz.T
    out["azimuth"] = np.arctan2(y, x)
    out["elevation"] = np.arctan2(z, np.hypot(x, y))
    out["distance"] = np.linalg.norm(data.xyz, axis=1)
    return out


def directions(res: CalibrationResult, data: Measurements) -> dict[tuple[str, int | None], np.ndarray]:
    """Each effect's directions at ``data``'s poses, (N, 3, k) in the measurement frame: a joint's angle (the
    point's derivative w.r.t. its reading), the robot's base frame's axes, the measurement frame's axes."""
    m, p = res.model, res.parameters
    _, Jq = m.predict_q_jacobian(data.q, p.values, m.covariates(data), res.base0)
    out: dict[tuple[str, int | None], np.ndarray] = {("angle", j + 1): Jq[:, :, j:j + 1] for j in range(Jq.shape[2])}
    if data.sessions is None:
        R = np.broadcast_to(res.base_matrix()[:3, :3], (len(data), 3, 3))
    else:
        R = np.empty((len(data), 3, 3))
        for s in data.session_names:
            R[data.sessions == s] = res.base_matrix(s)[:3, :3]
    out[("point_base", None)] = np.ascontiguousarray(R)
    out[("point_measurement", None)] = np.broadcast_to(np.eye(3), (len(data), 3, 3)).copy()
    return out


def pairs(n_joints: int) -> list[tuple[str, str, int | None]]:
    """Every (covariate, effect, joint) the screen tries."""
    robot_cov = [f"q{j}" for j in range(1, n_joints + 1)] + [f"tau{j}" for j in range(1, n_joints + 1)] + ["time"]
    out = [(c, "angle", j) for j in range(1, n_joints + 1) for c in robot_cov if c != f"tau{j}"]
    out += [(c, "point_base", None) for c in robot_cov]
    out += [(c, "point_measurement", None) for c in ("azimuth", "elevation", "distance", "time")]
    return out


def _columns(cov: np.ndarray, ref: tuple[float, float], dirs: np.ndarray) -> np.ndarray:
    """(N, 3, DEGREE * k): each basis function times each direction."""
    B = _basis(cov, ref)
    return (dirs[:, :, :, None] * B[:, None, None, :]).reshape(len(cov), 3, -1)


def _weighted(X: np.ndarray, sw: np.ndarray) -> np.ndarray:
    return X.reshape(-1, X.shape[2]) * sw[:, None]


def _held_out_share(J: np.ndarray, X: np.ndarray, r: np.ndarray, w: np.ndarray, folds: list[np.ndarray]
                    ) -> tuple[float, int, int]:
    """Left-out poses predicted better with the term than without: (share, wins, counted)."""
    wins = counted = 0
    for test in folds:
        train = np.setdiff1d(np.arange(len(r)), test)
        sw = np.sqrt(np.repeat(w[train], 3))
        rt = r[train].ravel() * sw
        A0 = _weighted(J[train], sw)
        A1 = np.hstack([A0, _weighted(X[train], sw)])
        x0 = np.linalg.lstsq(A0, rt, rcond=None)[0]
        x1 = np.linalg.lstsq(A1, rt, rcond=None)[0]
        e0 = np.linalg.norm(r[test] - J[test] @ x0, axis=1)
        e1 = np.linalg.norm(r[test] - np.concatenate([J[test], X[test]], axis=2) @ x1, axis=1)
        keep = w[test] >= 0.5
        wins += int(np.sum((e1 < e0) & keep))
        counted += int(np.sum(keep))
    return (wins / counted if counted else 0.0), wins, counted


def _sign_log10_p(wins: int, n: int) -> float:
    """log10 of the one-sided sign test's p-value of ``wins`` of ``n`` (normal approximation)."""
    if n == 0:
        return 0.0
    z = (wins - 0.5 * n) / math.sqrt(0.25 * n)
    return math.log10(max(0.5 * math.erfc(z / math.sqrt(2)), 1e-300))


@dataclass
class Found:
    """The strongest structure of a residual: its pair, its columns on the calibration poses, its test."""

    covariate: str
    effect: str
    joint: int | None
    X: np.ndarray
    log10_p: float
    test_text: str
    held_out_share: float


class StructureScreen:
    """The structure screen of one fit on the calibration poses: its covariates, effects' directions, folds."""

    def __init__(self, res: CalibrationResult, cal: Measurements, torques: np.ndarray, alpha: float,
                 seed: int = 0):
        self.res, self.cal = res, cal
        self.cov = covariates(res, cal, torques)
        self.dirs = directions(res, cal)
        self.refs = {k: (float(np.min(v)), float(np.max(v))) for k, v in self.cov.items()}
        self.tried = pairs(cal.q.shape[1])
        self.level = math.log10(alpha / len(self.tried))
        self.folds = np.array_split(np.random.default_rng(seed).permutation(len(cal)), FOLDS)

    def columns(self, cov: str, effect: str, joint: int | None) -> np.ndarray:
        return _columns(self.cov[cov], self.refs[cov], self.dirs[(effect, joint)])

    def strongest(self, base: np.ndarray, r: np.ndarray, w: np.ndarray, skip=(), only=None) -> Found | None:
        """The pair that explains most of ``r`` beside the columns ``base`` (N, 3, p) at weights ``w``, if it is
        significant at the level and predicts left-out poses better (see the module); ``skip``: pairs not to
        try; ``only``: the pairs to try (default: every pair)."""
        sw = np.sqrt(np.repeat(w, 3))
        Q, _ = np.linalg.qr(_weighted(base, sw))
        rw = r.ravel() * sw
        r0 = rw - Q @ (Q.T @ rw)
        ssr0 = float(r0 @ r0)
        scored = []
        for pair in self.tried if only is None else only:
            if pair in skip:
                continue
            X = self.columns(*pair)
            Xw = _weighted(X, sw)
            Xw = Xw - Q @ (Q.T @ Xw)
            k = int(np.linalg.matrix_rank(Xw, tol=1e-10 * max(np.abs(Xw).max(), 1e-300)))
            if k == 0:
                continue
            coef, *_ = np.linalg.lstsq(Xw, r0, rcond=None)
            ssr1 = float(np.sum((r0 - Xw @ coef) ** 2))
            test = nested_test(ssr0, base.shape[2], ssr1, base.shape[2] + k, len(rw))
            scored.append((test.log10_p, pair, X, test))
        scored.sort(key=lambda t: t[0])
        for log10_p, (cov, effect, joint), X, test in scored:
            if log10_p >= self.level or test.delta_bic >= 0:
                return None
            share, wins, counted = _held_out_share(base, X, r, w, self.folds)
            if share > 0.5 and _sign_log10_p(wins, counted) < self.level:
                return Found(cov, effect, joint, X, log10_p, test.text(), share)
        return None


def screen(res: CalibrationResult, cal: Measurements, val: Measurements, cal_torques: np.ndarray,
           val_torques: np.ndarray, alpha: float, seed: int = 0) -> list[Structure]:
    """The structures ``res`` leaves on ``cal`` (see the module), strongest first."""
    lin = Linearized.of(res, cal)
    scr = StructureScreen(res, cal, cal_torques, alpha, seed)
    r, w = lin.r, lin.weights
    sw = np.sqrt(np.repeat(w, 3))
    cov_v = covariates(res, val, val_torques)
    lin_v = dir_v = base_v = None
    found: list[Structure] = []
    base = lin.J
    while len(found) < MAX_STRUCTURES:
        s = scr.strongest(base, r, w, skip={(f.covariate, f.effect, f.joint) for f in found})
        if s is None:
            break
        # the term fitted with the model's parameters on the calibration poses, taken to the validation poses
        # (the parameters refitted beside it: the term alone is not what it changes where it is confounded)
        base = np.concatenate([base, s.X], axis=2)
        x1 = np.linalg.lstsq(_weighted(base, sw), r.ravel() * sw, rcond=None)[0]
        if lin_v is None:
            lin_v, dir_v = Linearized.of(res, val), directions(res, val)
            base_v = lin_v.J
        Xv = _columns(cov_v[s.covariate], scr.refs[s.covariate], dir_v[(s.effect, s.joint)])
        base_v = np.concatenate([base_v, Xv], axis=2)
        change = base_v @ x1
        before = np.linalg.norm(lin_v.r, axis=1)
        after = np.linalg.norm(lin_v.r - change, axis=1)
        # the poses the robust loss set aside that this structure (with those before it) brings back within its
        # limit: the largest misses of the structure, not bad measurements
        left = r - base @ x1
        back = np.flatnonzero((w < 0.5) & (res.loss.weight(np.einsum("ij,ij->i", left, left)) >= 0.5))
        back = np.setdiff1d(back, np.concatenate([f.misses for f in found] + [np.zeros(0, int)]))
        found.append(Structure(s.covariate, s.effect, s.joint, s.log10_p, s.test_text,
                               float(np.mean(np.linalg.norm(change, axis=1)) * 1000),
                               float((before.mean() - after.mean()) * 1000), s.held_out_share, back))
    return found


def screen_structure(run: DiagnosisRun) -> None:
    """Stage: screen what the model of the named causes (``current``) leaves; each structure found is an
    ``unexplained`` finding, not in the model."""
    if not run.s.structure:
        return
    res = run.current
    run.say("structure screen: what the named causes leave, against every joint's reading and torque, time, "
            "and the instrument's view")
    val_torques = res.model.torques(run.val.q, res.parameters.values, res.model.covariates(run.val))
    found = screen(res, run.cal, run.val, run.torques(res), val_torques, run.s.alpha, run.s.seed)
    if not found:
        run.say("  nothing the named causes leave is structure")
    for s in found:
        run.say(f"  {s.words()} (p = {10 ** s.log10_p:.2g}; {s.size_mm:.4f} mm on the validation poses)")
        finding = Finding(
            Candidate("unexplained", s.joint), 0.0,
            f"structure no cause of the catalogue explains: {s.words()}; {s.test_text} on the calibration poses "
            f"(a flexible term of degree {DEGREE} in the covariate, the model's parameters refitted beside it); it "
            f"predicts {s.held_out_share:.0%} of the left-out calibration poses better; judged on the validation "
            f"poses it is {s.size_mm:.4f} mm on average, and a flexible term would lower their mean error by "
            f"{s.potential_gain_mm:.4f} mm",
            in_model=False, where=s.words(), potential_gain_mm=s.potential_gain_mm,
            structure=s.to_dict())
        run.findings.append(finding)
        run.structures.append((s, finding))
