"""What an engineer reads of a fit: t-values, significance, confidence intervals, AIC and BIC.

Every free parameter is tested against its nominal value (statsmodels'
``t`` and ``P>|t|`` columns, lmfit's relative error):

- the **deviation** ``value - nominal`` is what a calibration estimates (for
  a compliance, a gear error, a drift, ... the nominal is 0 and the deviation
  is the value itself);
- ``t = deviation / std`` and the two-sided p-value of Student's t
  distribution with the fit's degrees of freedom (3 equations per pose less
  the free parameters); a parameter is **significant** when ``p < 1 -
  level`` (``level`` 0.95 by default: ``|t|`` above about 1.97 for a few
  hundred poses), i.e. its deviation from nominal stands out of the noise;
- the **relative standard error** is ``std / |deviation|`` (``1 / |t|``), not
  ``std / |value|``: a geometric parameter's value is mostly its nominal
  (a link of 612 mm known to 0.1 mm would read 0.02 %), while what the data
  determine is its deviation. For the terms whose nominal is 0 both are the
  same (lmfit's ``stderr / |value|``);
- the **confidence interval** ``value +- t_crit std`` (Wald, from the same t
  distribution). It is not clipped at a parameter's bounds: a compliance
  interval reaching below 0 means "down to 0", i.e. infinitely stiff. The
  stiffness ``k = 1/c`` takes its interval from its compliance's:
  ``[1/c_hi, 1/c_lo]``, unbounded above when ``c_lo <= 0``.

These rest on the linearised covariance (:mod:`casadical.stats._uncertainty`); for a
parameter at a bound it does not hold (the calibration notes say so) and the
test only says what the linearisation says.

AIC and BIC (:class:`FitStatistics`) use the Gaussian log-likelihood of the
residuals in mm with the maximum-likelihood noise variance,
``log L = -m/2 (ln(2 pi SSR/m) + 1)``, ``AIC = 2k - 2 log L``, ``BIC = k ln m
- 2 log L``, with ``m`` equations (3 per pose) and ``k`` free parameters (the
base pose included; the noise variance is not counted, as in statsmodels and
lmfit: it would add the same to every model). With the robust loss, ``SSR``
is the weighted sum of squares (``sum w_i |r_i|^2``), so a pose the loss set
aside counts by its weight. Only models fitted to the same poses compare.

No SciPy here: importing ``scipy.special`` would cost every command 0.1 s;
the t distribution is computed from the regularised incomplete beta function
(continued fraction), tested against SciPy.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import lru_cache
from statistics import NormalDist

from .._format import number
from ..errors import SignificanceWarning, listing
from ..parameters import Parameter, Parameters

#: default confidence level of intervals and significance
LEVEL = 0.95


# --- Student's t distribution ------------------------------------------------------------


def _betacf(a: float, b: float, x: float) -> float:
    """Continued fraction of the incomplete beta function (modified Lentz)."""
    tiny, eps = 1e-300, 1e-15
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 100_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < eps:
            break
    return h


def betainc(a: float, b: float, x: float) -> float:
    """Regularised incomplete beta function I_x(a, b) (a, b > 0, 0 <= x <= 1)."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    ln = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(ln) * _betacf(a, b, x) / a
    return 1.0 - math.exp(ln) * _betacf(b, a, 1.0 - x) / b


def t_two_sided_p(t: float, dof: float) -> float:
    """P(|T| >= |t|) for Student's t with ``dof`` degrees of freedom (``inf``: the normal distribution)."""
    if math.isnan(t):
        return math.nan
    if math.isinf(t):
        return 0.0
    if not math.isfinite(dof):
        return math.erfc(abs(t) / math.sqrt(2.0))
    return betainc(dof / 2.0, 0.5, dof / (dof + t * t))


@lru_cache(maxsize=4096)
def t_critical(level: float = LEVEL, dof: float = math.inf) -> float:
    """The two-sided critical value: P(|T| <= t) = ``level`` (``dof`` ``inf``: the normal's).

    Newton's method on the p-value from the Cornish-Fisher expansion (a few
    steps: a calibration inside a diagnosis asks it hundreds of times), with
    bisection as the fallback.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"confidence level must lie in (0, 1), got {level}")
    z = NormalDist().inv_cdf(0.5 + level / 2.0)
    if not math.isfinite(dof):
        return z
    if not dof > 0:
        return math.nan
    alpha, v = 1.0 - level, float(dof)
    t = (z + (z ** 3 + z) / (4 * v) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * v ** 2)
         + (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / (384 * v ** 3))
    log_c = math.lgamma((v + 1) / 2) - math.lgamma(v / 2) - 0.5 * math.log(v * math.pi)
    for _ in range(20):
        if not (t > 0 and math.isfinite(t)):
            break
        density = math.exp(log_c - (v + 1) / 2 * math.log1p(t * t / v))
        new = t + (t_two_sided_p(t, v) - alpha) / (2.0 * density)
        if abs(new - t) <= 1e-14 * t:
            return new
        t = new
    lo, hi = 0.0, max(z, 1.0)                   # bisection: p falls monotonically with t
    while t_two_sided_p(hi, v) > alpha:
        lo, hi = hi, 2.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if t_two_sided_p(mid, v) > alpha:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-14 * hi:
            break
    return 0.5 * (lo + hi)


# --- one parameter ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ParameterTest:
    """The test of one free parameter against its nominal value (SI units).

    Attributes
    ----------
    name : str
    deviation : float
        ``value - nominal``.
    std : float
    t : float
        ``deviation / std``.
    p : float
        Two-sided p-value of ``t``.
    significant : bool
        ``p < 1 - level``.
    ci : (float, float)
        Confidence interval of the value, ``value +- t_crit std``.
    relative_std : float
        ``std / |deviation|`` (``inf`` for a deviation of exactly 0).
    level : float
    """

    name: str
    deviation: float
    std: float
    t: float
    p: float
    significant: bool
    ci: tuple[float, float]
    relative_std: float
    level: float = LEVEL


def parameter_test(p: Parameter, dof: float = math.inf, level: float = LEVEL,
                   t_crit: float | None = None) -> ParameterTest | None:
    """The test of a free parameter with a usable standard error; None for a fixed one or without."""
    if p.fixed or not (math.isfinite(p.std) and p.std > 0):
        return None
    crit = t_critical(level, dof) if t_crit is None else t_crit
    dev = p.value - p.nominal
    t = dev / p.std
    pv = t_two_sided_p(t, dof)
    return ParameterTest(p.name, dev, p.std, t, pv, bool(pv < 1.0 - level),
                         (p.value - crit * p.std, p.value + crit * p.std),
                         p.std / abs(dev) if dev != 0 else math.inf, level)




def parameter_tests(params: Parameters, dof: float = math.inf, level: float = LEVEL) -> dict[str, ParameterTest]:
    """Tests of every free parameter with a usable standard error, by name (model order)."""
    crit = t_critical(level, dof)
    out = {}
    for p in params:
        t = parameter_test(p, dof, level, crit)
        if t is not None:
            out[p.name] = t
    return out




def stiffness_interval(c_interval: tuple[float, float]) -> tuple[float, float] | None:
    """The interval of ``k = 1/c`` from the compliance's: ``(1/c_hi, 1/c_lo)``; ``inf`` above when ``c_lo <= 0``.

    None when the whole compliance interval is at or below 0 (no positive stiffness).
    """
    lo, hi = c_interval
    if not hi > 0:
        return None
    return 1.0 / hi, (1.0 / lo if lo > 0 else math.inf)


# --- the whole fit -----------------------------------------------------------------------------


@dataclass(frozen=True)
class FitStatistics:
    """Size, noise and information criteria of a least-squares fit (module docstring: the formulas).

    Attributes
    ----------
    n_equations : int
        3 per pose.
    n_parameters : int
        Free parameters, the base pose's included.
    ssr : float
        Weighted sum of squared residuals (m^2).
    """

    n_equations: int
    n_parameters: int
    ssr: float

    @property
    def dof(self) -> int:
        return self.n_equations - self.n_parameters

    @property
    def sigma(self) -> float:
        """Residual standard deviation per axis (m), ``sqrt(SSR / dof)``."""
        return math.sqrt(self.ssr / self.dof) if self.dof > 0 else math.nan

    @property
    def log_likelihood(self) -> float:
        """Gaussian log-likelihood of the residuals in mm, maximum-likelihood variance ``SSR/m``."""
        m = self.n_equations
        s2 = self.ssr * 1e6 / m
        return -0.5 * m * (math.log(2.0 * math.pi * s2) + 1.0) if s2 > 0 else math.inf

    @property
    def aic(self) -> float:
        return 2.0 * self.n_parameters - 2.0 * self.log_likelihood

    @property
    def bic(self) -> float:
        return self.n_parameters * math.log(self.n_equations) - 2.0 * self.log_likelihood

    @classmethod
    def of(cls, unc) -> "FitStatistics | None":
        """From an :class:`~casadical.stats._uncertainty.Uncertainty` (its sigma, dof and free parameters)."""
        if unc is None or not unc.dof > 0 or not math.isfinite(unc.sigma):
            return None
        p = len(unc.names)
        return cls(unc.dof + p, p, unc.sigma ** 2 * unc.dof)

    def to_dict(self, level: float = LEVEL) -> dict:
        """The calibration JSON's ``statistics``."""
        return {"n_equations": self.n_equations, "n_parameters": self.n_parameters, "dof": self.dof,
                "sigma_mm": self.sigma * 1000, "log_likelihood": self.log_likelihood, "aic": self.aic,
                "bic": self.bic, "level": level, "t_critical": t_critical(level, self.dof)}

    @classmethod
    def from_dict(cls, d: dict) -> "FitStatistics":
        dof = int(d["n_equations"]) - int(d["n_parameters"])
        sigma = float(d["sigma_mm"]) / 1000
        return cls(int(d["n_equations"]), int(d["n_parameters"]), sigma * sigma * dof)

    def line(self) -> str:
        return (f"fit: {self.n_equations} equations, {self.n_parameters} free parameters, {self.dof} degrees of "
                f"freedom; log-likelihood {self.log_likelihood:.2f} (residuals in mm), AIC {self.aic:.2f}, "
                f"BIC {self.bic:.2f} (compare only models fitted to the same poses)")


# --- notes and the text table ------------------------------------------------------------------


def _groups(term, params: list[Parameter]) -> dict:
    """A term's parameters by what is dropped together: a joint, a joint's harmonic, or the whole term
    (:meth:`~casadical.terms._base.ErrorTerm.group_key`)."""
    out: dict = {}
    for p in params:
        out.setdefault(term.group_key(p), []).append(p)
    return out


def significance_notes(model, params: Parameters, tests: dict[str, ParameterTest]) -> list[str]:
    """A note per error term (not the geometry) with parameters that are not significant.

    A joint (a joint's harmonic, a term without joints) is named when none
    of its tested parameters is significant. The note says what is not
    determined and what to do: drop it from the model (the specification
    without it is given) or measure poses that show it.
    """
    notes = []
    for term in model.terms:
        if not term.noted:
            continue
        own = [params[q.name] for q in term.parameters(model.robot) if q.name in tests]   # the term's own
        weak, strong, weak_keys = [], [], []
        for key, group in _groups(term, own).items():
            significant = any(tests[p.name].significant for p in group)
            (strong if significant else weak).append(group)
            weak_keys += [] if significant else [key]
        if not weak:
            continue
        names = [p for g in weak for p in g]
        level = next(iter(tests.values())).level
        said = [f"{p.name} (t = {tests[p.name].t:.2f})" for p in names]
        said = said[0] if len(said) == 1 else listing(said[:-1], 5) + " and " + said[-1] if len(said) <= 6 \
            else listing(said, 6)
        verb = "is" if len(names) == 1 else "are"
        js = sorted({p.joint for p in names if p.joint is not None})
        words = term.weak_words(weak_keys, js)
        what, do, drop = words or (f"the {term.name} effect is", "measure poses that show it", "drop the term")
        keep = _reduced_spec(model, term, [p for g in strong for p in g], weak_keys)
        notes.append(f"{term.name}: {said} {verb} not significant ({100 * level:g} % level): {what} not "
                     f"determined by these poses; {drop}{f' ({keep})' if keep else ''} or {do}")
    return notes


def warn_not_significant(model, params: Parameters, dof: float, level: float = LEVEL) -> list[str]:
    """:func:`significance_notes` of a fit, each also issued as a :class:`SignificanceWarning`."""
    notes = significance_notes(model, params, parameter_tests(params, dof if dof > 0 else math.inf, level))
    for n in notes:
        warnings.warn(n, SignificanceWarning, stacklevel=3)
    return notes


def _reduced_spec(model, term, kept: list[Parameter], dropped: list) -> str:
    """The model specification without what of ``term`` has no significant parameter ('' if not expressible)."""
    if hasattr(term, "inner"):      # a term of one session: said without a specification
        return ""
    part = term.without(kept, dropped)
    if part is None:
        return ""
    return model.spec.replace(term.spec(), part).replace("++", "+").strip("+")


def parameter_table_text(params: Parameters, tests: dict[str, ParameterTest]) -> str:
    """Plain-text table: name, nominal, value, deviation, std, relative std, t, interval, unit, status.

    Angles in degrees, lengths in mm; the interval's ends are headed as in
    statsmodels (``[0.025`` and ``0.975]`` at 95 %). A free parameter that is
    not significant says so in its status.
    """
    level = next(iter(tests.values())).level if tests else LEVEL
    lo, hi = f"[{(1 - level) / 2:g}", f"{1 - (1 - level) / 2:g}]"
    w = max([14] + [len(p.name) + 2 for p in params])     # a session's own parameters have long names (base_x@B)
    head = (f"{'name':<{w}}{'nominal':>12}{'value':>12}{'deviation':>12}{'std':>11}{'rel.std':>8}{'t':>8}"
            f"{lo:>12}{hi:>12}  {'unit':<10}status")
    lines = [head, "-" * len(head)]
    for p in params:
        f = p.to_display
        std = f(p.std) if math.isfinite(p.std) else math.nan
        t = tests.get(p.name)
        status = "fixed" if p.fixed else "free"
        if t is not None and not t.significant:
            status += ", not significant"
        if p.reason:
            status += f" ({p.reason})"
        rel = "-" if t is None else (f"{100 * t.relative_std:.0f}%" if t.relative_std < 10 else ">999%")
        tv = "-" if t is None else f"{t.t:.2f}"
        ci = ("-", "-") if t is None else (number(f(t.ci[0])), number(f(t.ci[1])))
        lines.append(f"{p.name:<{w}}{number(f(p.nominal)):>12}{number(f(p.value)):>12}"
                     f"{number(f(p.value - p.nominal)):>12}{number(std, 4):>11}{rel:>8}{tv:>8}{ci[0]:>12}{ci[1]:>12}"
                     f"  {p.display_unit:<10}{status}")
    return "\n".join(lines)
