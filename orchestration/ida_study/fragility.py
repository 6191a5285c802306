"""Fragility curves from multiple-stripe data: lognormal, fitted by maximum likelihood.

At intensity level x_j (the stripes of an IDA), k_j of n_j runs exceed a limit state.
The fragility is ``P(exceed | IM = x) = Phi((ln x - mu) / beta)``, median ``theta = e^mu``
and dispersion ``beta``. The parameters maximize the binomial likelihood (Baker 2015,
Earthquake Spectra 31(1), Eq. 11)::

    L(mu, beta) = prod_j C(n_j, k_j) p_j^k_j (1 - p_j)^(n_j - k_j),   p_j = Phi((ln x_j - mu) / beta)

(``scipy.stats.norm`` log-CDFs, ``scipy.optimize``). The confidence band is pointwise:
with z(x) = (ln x - mu) / beta and the expected Fisher information of (mu, beta)::

    I = sum_j n_j phi(z_j)^2 / (p_j (1 - p_j)) g_j g_j',   g_j = dz_j/d(mu, beta) = (-1, -z_j) / beta

the band is ``Phi(z(x) -+ q sqrt(g(x)' I^-1 g(x)))`` (delta method on the probit scale),
q the normal quantile of the confidence level. Data that never exceed, always exceed, or
are perfectly separated by one level give no finite fit; they are reported as such.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats


@dataclass(frozen=True)
class Stripe:
    """One intensity level: runs counted and runs that exceeded."""

    level: float
    n: int
    k: int


@dataclass
class Fit:
    """A fitted fragility (``kind`` 'fit'), or why there is none: 'none-exceed', 'all-exceed', 'separated', 'no-fit'."""

    kind: str
    theta: float = math.nan  # median [unit of IM]
    beta: float = math.nan  # lognormal dispersion
    cov: np.ndarray | None = None  # covariance of (mu, beta) (inverse expected information)
    confidence: float = 0.95
    bounds: tuple[float, float] = (math.nan, math.nan)  # 'separated': theta lies between these levels
    stripes: list[Stripe] = field(default_factory=list)
    note: str = ""

    @property
    def ok(self) -> bool:
        return self.kind == "fit"

    def probability(self, x: np.ndarray | float) -> np.ndarray:
        """P(exceed | IM = x)."""
        z = (np.log(np.asarray(x, dtype=float)) - math.log(self.theta)) / self.beta
        return stats.norm.cdf(z)

    def band(self, x: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Pointwise lower and upper confidence bounds of P(exceed | IM = x)."""
        x = np.asarray(x, dtype=float)
        z = (np.log(x) - math.log(self.theta)) / self.beta
        g = np.stack([-np.ones_like(z), -z]) / self.beta
        var = np.einsum("in,ij,jn->n", g.reshape(2, -1), self.cov, g.reshape(2, -1)).reshape(z.shape)
        q = stats.norm.ppf(0.5 + self.confidence / 2)
        sd = np.sqrt(np.maximum(var, 0.0))
        return stats.norm.cdf(z - q * sd), stats.norm.cdf(z + q * sd)

    def theta_interval(self) -> tuple[float, float]:
        """Confidence interval of the median theta."""
        if self.cov is None:
            return math.nan, math.nan
        q = stats.norm.ppf(0.5 + self.confidence / 2)
        spread = min(q * math.sqrt(max(self.cov[0, 0], 0.0)), 700.0)  # on the log scale
        return self.theta * math.exp(-spread), self.theta * math.exp(spread)


def expected_information(levels: np.ndarray, n: np.ndarray, mu: float, beta: float) -> np.ndarray:
    """Expected Fisher information of (mu, beta) for binomial stripes (module docstring)."""
    z = (np.log(levels) - mu) / beta
    p = np.clip(stats.norm.cdf(z), 1e-300, 1 - 1e-16)
    w = n * stats.norm.pdf(z) ** 2 / (p * (1 - p))
    g = np.stack([-np.ones_like(z), -z]) / beta
    return (g * w) @ g.T


def negative_log_likelihood(mu: float, beta: float, levels: np.ndarray, n: np.ndarray, k: np.ndarray) -> float:
    """-ln L(mu, beta), without the constant binomial coefficients."""
    z = (np.log(levels) - mu) / beta
    return -float(np.sum(k * stats.norm.logcdf(z) + (n - k) * stats.norm.logsf(z)))


def fit_fragility(stripes: list[Stripe], confidence: float = 0.95) -> Fit:
    """Maximum-likelihood lognormal fragility of stripes (levels > 0, ascending not required)."""
    used = [s for s in stripes if s.n > 0]
    if not used:
        return Fit("none-exceed", stripes=stripes, confidence=confidence, note="no run to count")
    x = np.array([s.level for s in used], dtype=float)
    n = np.array([s.n for s in used], dtype=float)
    k = np.array([s.k for s in used], dtype=float)
    order = np.argsort(x)
    x, n, k = x[order], n[order], k[order]
    if k.sum() == 0:
        return Fit("none-exceed", stripes=stripes, confidence=confidence,
                   note=f"no run exceeded it up to {x[-1]:.4g}")
    if k.sum() == n.sum():
        return Fit("all-exceed", stripes=stripes, confidence=confidence,
                   note=f"every run exceeded it, from {x[0]:.4g} on")
    for j in range(1, len(x)):
        if k[:j].sum() == 0 and np.all(k[j:] == n[j:]):
            return Fit("separated", stripes=stripes, confidence=confidence, bounds=(float(x[j - 1]), float(x[j])),
                       note=f"no run exceeded it at {x[j - 1]:.4g}, every run at {x[j]:.4g} and above: "
                            "the dispersion is not identifiable")
    for j in range(len(x)):  # quasi-separated: one mixed level between none and all (the MLE has beta -> 0)
        if k[:j].sum() == 0 and np.all(k[j + 1:] == n[j + 1:]) and 0 < k[j] < n[j]:
            return Fit("separated", stripes=stripes, confidence=confidence,
                       bounds=(float(x[max(j - 1, 0)]), float(x[min(j + 1, len(x) - 1)])),
                       note=f"exceeded at {x[j]:.4g} by {int(k[j])} of {int(n[j])} runs, by none below and all "
                            "above: the median is near it, the dispersion is not identifiable")
    # start: least squares of probit(fraction) on ln x (slope 1/beta); then L-BFGS on (mu, ln beta)
    frac = np.clip(k / n, 0.5 / n, 1 - 0.5 / n)
    slope, intercept = np.polyfit(np.log(x), stats.norm.ppf(frac), 1, w=np.sqrt(n)) if len(x) > 1 else (2.5, 0.0)
    slope = slope if slope > 0.1 else 2.5
    start = np.array([-intercept / slope, -math.log(slope)])

    def objective(q: np.ndarray) -> tuple[float, np.ndarray]:
        beta = math.exp(q[1])
        z = (np.log(x) - q[0]) / beta
        lc, ls, lp = stats.norm.logcdf(z), stats.norm.logsf(z), stats.norm.logpdf(z)
        dz = -(k * np.exp(lp - lc) - (n - k) * np.exp(lp - ls))  # d(-ln L)/dz_j
        return -float(np.sum(k * lc + (n - k) * ls)), np.array([np.sum(dz * -1.0 / beta), np.sum(dz * -z)])

    best = optimize.minimize(objective, start, jac=True, method="BFGS", options={"gtol": 1e-9, "maxiter": 500})
    mu, beta = float(best.x[0]), math.exp(min(float(best.x[1]), 50.0))
    if not (math.isfinite(mu) and math.isfinite(beta) and beta > 0):
        return Fit("no-fit", stripes=stripes, confidence=confidence, note=f"the optimizer failed: {best.message}")
    info = expected_information(x, n, mu, beta)
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        cov = None
    note = ""
    if not x[0] <= math.exp(mu) <= x[-1]:
        note = f"median {math.exp(mu):.3g} outside the ladder {x[0]:.3g}-{x[-1]:.3g}: extrapolated"
    return Fit("fit", math.exp(mu), beta, cov, confidence, stripes=stripes, note=note)


STROKE_QUANTITY = "isolator_displacement"


def stroke_limit_state(limit_states: dict[str, tuple[str, float]]) -> str | None:
    """The limit state of the device's stroke: of those on the isolator displacement (name -> (quantity,
    threshold [m])), the one with the largest threshold (the device limit); None if there is none."""
    on_stroke = [(threshold, name) for name, (quantity, threshold) in limit_states.items()
                 if quantity == STROKE_QUANTITY]
    return max(on_stroke)[1] if on_stroke else None


@dataclass(frozen=True)
class StrokeCapacity:
    """The intensity up to which the device stays within its stroke: the median of the stroke fragility [IM unit].

    ``kind`` as :class:`Fit`. 'fit': ``median`` with its confidence interval [``low``, ``high``] (the lognormal
    fit's, :meth:`Fit.theta_interval`). 'separated': no median, the interval is the two levels it lies between.
    'none-exceed': never left the stroke: the median is above the ladder (``low`` its top, ``high`` infinite).
    'all-exceed': left it at every level: the median is below the ladder (``low`` 0, ``high`` its bottom).
    """

    kind: str
    median: float
    low: float
    high: float

    def text(self, unit: str = "g", confidence: float = 0.95) -> str:
        """In words, e.g. ``0.128 g (95 % interval 0.10-0.16 g)``."""
        if self.kind == "fit":
            return f"{self.median:.3g} {unit} ({100 * confidence:g} % interval {self.low:.3g}-{self.high:.3g} {unit})"
        if self.kind == "separated":
            return f"between {self.low:g} and {self.high:g} {unit}"
        if self.kind == "none-exceed":
            return f"within its stroke up to {self.low:g} {unit} (the whole ladder)"
        if self.kind == "all-exceed":
            return f"beyond its stroke from the lowest level ({self.high:g} {unit}) on"
        return "no fit"


def stroke_capacity(fit: Fit) -> StrokeCapacity:
    """The stroke capacity of a fitted stroke fragility (see :class:`StrokeCapacity`)."""
    levels = sorted(s.level for s in fit.stripes if s.n > 0)
    if fit.ok:
        lo, hi = fit.theta_interval()
        return StrokeCapacity("fit", fit.theta, lo, hi)
    if fit.kind == "separated":
        return StrokeCapacity("separated", math.nan, *fit.bounds)
    if fit.kind == "none-exceed" and levels:
        return StrokeCapacity("none-exceed", math.nan, levels[-1], math.inf)
    if fit.kind == "all-exceed" and levels:
        return StrokeCapacity("all-exceed", math.nan, 0.0, levels[0])
    return StrokeCapacity(fit.kind, math.nan, math.nan, math.nan)
