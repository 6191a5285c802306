"""Physics of the Bouc-Wen isolator model (paper Eq. 1-2), SI units.

    F  = k x + c x' + alpha y + F0                                   (1)
    y' = delta x' - beta x' |y|^n - gamma y |x'| |y|^(n-1)           (2)

Conventions of this project (the paper leaves them open):

* y is dimensionless, so alpha [N], delta, beta, gamma [1/m], n [1], k [N/m], c [N*s/m].
  The model is invariant under y -> s*y, alpha -> alpha/s, delta -> s*delta,
  beta -> s^(1-n) beta, gamma -> s^(1-n) gamma, so delta is redundant; identification
  fixes delta = 1 per millimetre (1000 1/m), which makes |y| of the order of one.
* Eq. (2) is rate independent: dy = dx * (delta - lam(y) * y) with
  lam(y) = (beta*sign(y) + gamma*sign(dx)) * |y|^(n-1). The state is integrated in the
  displacement domain with the exponential midpoint scheme of :func:`bouc_wen_step`
  (lam frozen at a predicted midpoint value, the linear ODE solved exactly over the
  sub-step): second order, unconditionally stable for the stiff relaxation towards the
  hysteresis envelope, exact for n = 1 between reversals and zero crossings of y.
  Sub-steps are chosen so that no sub-step moves x by more than ``dx_max`` nor by more
  than 0.5/lam_max (see :func:`substeps`); after every sub-step y is clamped to the
  envelope |y| <= (delta/(beta+gamma))^(1/n), which the exact solution never leaves (this
  keeps coarse sub-steps of stiff unloading branches from overshooting). Between samples
  x is taken as linear in time (constant velocity).

Functions accept floats or numpy arrays (broadcasting), so the same code serves the
FMU (scalars) and the identification (a whole swarm at once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

MM = 1e-3  # metres per millimetre
DELTA_FIXED = 1.0 / MM  # delta fixed at 1 per millimetre, in 1/m
_TINY = 1e-12  # floor of |y| in |y|^(n-1), avoids 0**negative for n < 1
_ZMAX = 50.0  # cap of the exponent in one sub-step (overflow guard)


@dataclass(frozen=True)
class BoucWenParams:
    """Bouc-Wen parameters of one device at one current, SI units.

    k [N/m], c [N*s/m], alpha [N], beta [1/m], gamma [1/m], delta [1/m], n [1], F0 [N].
    """

    k: float
    c: float
    alpha: float
    beta: float
    gamma: float
    delta: float = DELTA_FIXED
    n: float = 1.0
    F0: float = 0.0

    @classmethod
    def from_paper_units(
        cls,
        k: float,
        c: float,
        alpha: float,
        beta: float,
        gamma: float,
        delta: float = 1.0,
        n: float = 1.0,
        F0: float = 0.0,
    ) -> BoucWenParams:
        """From mm-based units: k [N/mm], c [N*s/mm], alpha [N], beta, gamma, delta [1/mm]."""
        return cls(
            k=k / MM, c=c / MM, alpha=alpha, beta=beta / MM, gamma=gamma / MM, delta=delta / MM, n=n, F0=F0
        )

    def to_paper_units(self) -> dict[str, float]:
        """The same parameters in mm-based units."""
        return {
            "k": self.k * MM,
            "c": self.c * MM,
            "alpha": self.alpha,
            "beta": self.beta * MM,
            "gamma": self.gamma * MM,
            "delta": self.delta * MM,
            "n": self.n,
            "F0": self.F0,
        }


def _lam(y, s, beta, gamma, n, floor):
    """lam(y) of dy/dx = delta - lam*y for a sub-step moving in direction s = sign(dx).

    |y| is floored at ``floor`` (half the sub-step's explicit increment |delta*dx|/2): for
    n < 1, lam is infinite at y = 0, and a frozen infinite lam would pin y at 0.
    """
    return (beta * np.sign(y) + gamma * s) * np.maximum(np.abs(y), floor) ** (n - 1.0)


def _exp_step(y, h, delta, lam):
    """Exact solution of dy/dx = delta - lam*y over dx = h with lam frozen."""
    z = np.clip(-lam * h, -_ZMAX, _ZMAX) + 1e-300  # phi(z) = expm1(z)/z, phi(0) = 1
    return y + h * (delta - lam * y) * (np.expm1(z) / z)


def bouc_wen_step(y, dx, beta, gamma, delta, n):
    """One exponential-midpoint sub-step of Eq. (2): y after the displacement moves by dx.

    Units must be consistent (SI: dx [m], beta, gamma, delta [1/m]); y is dimensionless.
    """
    s = np.sign(dx)
    floor = np.maximum(0.5 * np.abs(delta * dx), _TINY)
    y_half = _exp_step(y, 0.5 * dx, delta, _lam(y, s, beta, gamma, n, floor))
    return _exp_step(y, dx, delta, _lam(y_half, s, beta, gamma, n, floor))


def envelope_rate(beta, gamma, delta, n) -> float:
    """Lam = max over the batch of (|beta|+|gamma|)^(1/n) |delta|^((n-1)/n).

    Lam bounds |lam(y)| on the hysteresis envelope |y| <= (delta/(beta+gamma))^(1/n).
    """
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        lam = (np.abs(beta) + np.abs(gamma)) ** (1.0 / n) * np.abs(delta) ** ((n - 1.0) / n)
    value = float(np.max(lam))
    return value if math.isfinite(value) else math.inf


def substeps(dx, lam_max: float, dx_max: float, lam_dx_max: float = 0.5, cap: int = 64) -> int:
    """Number of equal sub-steps for an increment dx (largest over a batch).

    Two limits: |dx|/m <= dx_max and |dx|/m * lam_max <= lam_dx_max (lam_max from
    :func:`envelope_rate`); never more than ``cap`` sub-steps.
    """
    adx = float(np.max(np.abs(dx)))
    if adx == 0.0:
        return 1
    lam_term = adx * lam_max / lam_dx_max if math.isfinite(lam_dx_max) else 0.0
    m = max(adx / dx_max, lam_term, 1.0)
    return cap if m >= cap else math.ceil(m)


def envelope(beta, gamma, delta, n):
    """Bound of |y|: (delta/(beta+gamma))^(1/n) where beta + gamma > 0, else infinity.

    Starting inside it, the exact solution of Eq. (2) never leaves it (loading relaxes
    towards it, unloading shrinks |y|); the integrator clamps to it after every sub-step.
    """
    s = np.asarray(beta + gamma, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.where(s > 0, np.abs(delta / np.where(s > 0, s, 1.0)) ** (1.0 / n), np.inf)


def _advance(y, dx, beta, gamma, delta, n, m: int, bound):
    h = np.asarray(dx, dtype=float) / m
    for _ in range(m):
        y = np.clip(bouc_wen_step(y, h, beta, gamma, delta, n), -bound, bound)
    return y


def bouc_wen_advance(y, dx, beta, gamma, delta, n, dx_max: float, lam_dx_max: float = 0.5, cap: int = 64):
    """State y after a displacement increment dx, in :func:`substeps` equal sub-steps.

    All arguments broadcast; the sub-step count is the largest one over the batch.
    """
    m = substeps(dx, envelope_rate(beta, gamma, delta, n), dx_max, lam_dx_max, cap)
    return _advance(y, dx, beta, gamma, delta, n, m, envelope(beta, gamma, delta, n))


def bouc_wen_states(
    x, beta, gamma, delta, n, dx_max: float, y0=0.0, lam_dx_max: float = 0.5, cap: int = 64
) -> np.ndarray:
    """Hysteretic state y at every sample of the displacement history x (last axis = time).

    Parameters broadcast against ``x[..., 0]`` (e.g. x of shape (R, N) with parameters of
    shape (P, 1) gives y of shape (P, R, N)). x and dx_max in consistent length units.
    ``lam_dx_max`` and ``cap`` trade accuracy for speed (see :func:`substeps`).
    """
    x = np.asarray(x, dtype=float)
    y = np.broadcast_to(np.asarray(y0, dtype=float), np.broadcast(x[..., 0], beta, gamma, delta, n).shape)
    out = np.empty((*y.shape, x.shape[-1]))
    out[..., 0] = y
    dxs = np.diff(x, axis=-1)
    lam_max = envelope_rate(beta, gamma, delta, n)
    bound = envelope(beta, gamma, delta, n)
    for k in range(dxs.shape[-1]):
        dx = dxs[..., k]
        y = _advance(y, dx, beta, gamma, delta, n, substeps(dx, lam_max, dx_max, lam_dx_max, cap), bound)
        out[..., k + 1] = y
    return out


def bouc_wen_force(x, v, y, p: BoucWenParams):
    """Force of one device [N], Eq. (1): x [m], v [m/s], y [1]."""
    return p.k * x + p.c * v + p.alpha * y + p.F0


@dataclass(frozen=True)
class BoucWenCurrentModel:
    """Current-dependent Bouc-Wen model used by the BoucWenIsolator FMU, SI units.

    Rule (a choice of this project, not of the paper): k, c, alpha, beta and gamma are
    linear in the current, p(i) = p_0 * i + p_1 (slope, value at 0 A, as in Table 2);
    delta and n do not depend on the current.
    """

    k_0: float
    k_1: float
    c_0: float
    c_1: float
    alpha_0: float
    alpha_1: float
    beta_0: float
    beta_1: float
    gamma_0: float
    gamma_1: float
    delta: float = DELTA_FIXED
    n: float = 1.0

    def at_current(self, i: float, F0: float = 0.0) -> BoucWenParams:
        """Device parameters at current i [A]."""
        return BoucWenParams(
            k=self.k_0 * i + self.k_1,
            c=self.c_0 * i + self.c_1,
            alpha=self.alpha_0 * i + self.alpha_1,
            beta=self.beta_0 * i + self.beta_1,
            gamma=self.gamma_0 * i + self.gamma_1,
            delta=self.delta,
            n=self.n,
            F0=F0,
        )

    def as_dict(self) -> dict[str, float]:
        """Coefficient name -> SI value."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_paper_units(cls, **paper: float) -> BoucWenCurrentModel:
        """From mm-based units (k, c per mm; beta, gamma, delta in 1/mm; alpha, n as is)."""
        per_mm = {"k_0", "k_1", "c_0", "c_1", "beta_0", "beta_1", "gamma_0", "gamma_1", "delta"}
        return cls(**{k: (v / MM if k in per_mm else v) for k, v in paper.items()})


# Default coefficients of the BoucWenIsolator FMU. SYNTHETIC: produced by this project's
# identification pipeline (Bouc-Wen by FFOA per condition, per-current averages and lines,
# then the joint least-squares refinement of components/identification/bouc_wen_joint.py)
# on the default synthetic data set, which is generated from the paper's Table 1
# hyperbolic parameters. They are a Bouc-Wen approximation of the paper's identified model,
# not a fit to measurements. Command: python orchestration/identify.py
# scenarios/identification.yaml (file generalized_bouc_wen-joint.yaml), values rounded to
# 5 digits. mm-based units: k [N/mm], c [N*s/mm], alpha [N], beta, gamma, delta [1/mm];
# suffix _0 = slope per ampere, _1 = value at 0 A. n and beta_1 ended on their bounds
# (0.5 and ~1e-4) of the joint fit.
SYNTHETIC_DEFAULT_PAPER_UNITS: dict[str, float] = {
    "k_0": 7.7755,
    "k_1": 4.3217,
    "c_0": 0.037427,
    "c_1": 0.12002,
    "alpha_0": 32.506,
    "alpha_1": 3.7123,
    "beta_0": 0.059059,
    "beta_1": 0.0001,
    "gamma_0": 0.023686,
    "gamma_1": 0.84835,
    "delta": 1.0,
    "n": 0.5,
}

SYNTHETIC_DEFAULT = BoucWenCurrentModel.from_paper_units(**SYNTHETIC_DEFAULT_PAPER_UNITS)
