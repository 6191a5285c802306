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
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

try:  # a package module here, a bare module in an FMU
    from .mre_isolator_core import (
        BEYOND_RANGE,
        CURRENT_MAX_A,
        DEVICE_LIMIT_M,
        IDENTIFIED_RANGE_M,
        STOP_STIFFNESS,
        ParameterError,
        current_grid,
    )
except ImportError:
    from mre_isolator_core import (
        BEYOND_RANGE,
        CURRENT_MAX_A,
        DEVICE_LIMIT_M,
        IDENTIFIED_RANGE_M,
        STOP_STIFFNESS,
        ParameterError,
        current_grid,
    )

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


def bouc_wen_advance(  # noqa: PLR0913 - Bouc-Wen's own parameters, broadcast; the FMU calls it every step
    y, dx, beta, gamma, delta, n, dx_max: float, lam_dx_max: float = 0.5, cap: int = 64
):
    """State y after a displacement increment dx, in :func:`substeps` equal sub-steps.

    All arguments broadcast; the sub-step count is the largest one over the batch.
    """
    m = substeps(dx, envelope_rate(beta, gamma, delta, n), dx_max, lam_dx_max, cap)
    return _advance(y, dx, beta, gamma, delta, n, m, envelope(beta, gamma, delta, n))


def bouc_wen_advance_scalar(  # noqa: PLR0913 - Bouc-Wen's own parameters; the FMU calls it every step
    y: float, dx: float, beta: float, gamma: float, delta: float, n: float, dx_max: float,
    lam_dx_max: float = 0.5, cap: int = 64,
) -> float:
    """:func:`bouc_wen_advance` for one state, in plain floats (the FMU's step: numpy's per-call cost on
    scalars was most of it). The same scheme, sub-step count and clamp, term by term; it agrees with the
    broadcast version to rounding (tests/physics/test_bouc_wen_scalar.py). A float overflow (parameters far
    outside a device's) hands the step to the broadcast version, whose inf/NaN semantics the shell checks."""
    try:
        return _advance_scalar(float(y), float(dx), float(beta), float(gamma), float(delta), float(n), dx_max,
                               lam_dx_max, cap)
    except (OverflowError, ZeroDivisionError):
        with np.errstate(all="ignore"):
            return float(bouc_wen_advance(y, dx, beta, gamma, delta, n, dx_max, lam_dx_max, cap))


def _advance_scalar(  # noqa: PLR0913
    y: float, dx: float, beta: float, gamma: float, delta: float, n: float, dx_max: float, lam_dx_max: float,
    cap: int,
) -> float:
    lam_max = (abs(beta) + abs(gamma)) ** (1.0 / n) * abs(delta) ** ((n - 1.0) / n)
    adx = abs(dx)
    if adx == 0.0:
        m = 1
    else:
        lam_term = adx * lam_max / lam_dx_max if math.isfinite(lam_dx_max) else 0.0
        ratio = max(adx / dx_max, lam_term, 1.0)
        m = cap if ratio >= cap else math.ceil(ratio)
    total = beta + gamma
    bound = abs(delta / total) ** (1.0 / n) if total > 0 else math.inf
    h = dx / m
    sign_h = (h > 0) - (h < 0)
    floor = max(0.5 * abs(delta * h), _TINY)
    half = 0.5 * h
    for _ in range(m):
        lam = (beta * ((y > 0) - (y < 0)) + gamma * sign_h) * max(abs(y), floor) ** (n - 1.0)
        z = min(max(-lam * half, -_ZMAX), _ZMAX) + 1e-300
        y_half = y + half * (delta - lam * y) * (math.expm1(z) / z)
        lam = (beta * ((y_half > 0) - (y_half < 0)) + gamma * sign_h) * max(abs(y_half), floor) ** (n - 1.0)
        z = min(max(-lam * h, -_ZMAX), _ZMAX) + 1e-300
        y = min(max(y + h * (delta - lam * y) * (math.expm1(z) / z), -bound), bound)
    return y


def bouc_wen_states(  # noqa: PLR0913 - Bouc-Wen's own parameters, broadcast over parameter sets (hot kernel)
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


# Description and SI unit of each coefficient (the BoucWenIsolator FMU's variables).
COEFFICIENT_DOCS: dict[str, tuple[str, str]] = {
    "k_0": ("N/(m.A)", "stiffness k slope per ampere"),
    "k_1": ("N/m", "stiffness k at 0 A"),
    "c_0": ("N.s/(m.A)", "damping c slope per ampere"),
    "c_1": ("N.s/m", "damping c at 0 A"),
    "alpha_0": ("N/A", "hysteretic force scale alpha slope per ampere"),
    "alpha_1": ("N", "hysteretic force scale alpha at 0 A"),
    "beta_0": ("1/(m.A)", "Bouc-Wen beta slope per ampere"),
    "beta_1": ("1/m", "Bouc-Wen beta at 0 A"),
    "gamma_0": ("1/(m.A)", "Bouc-Wen gamma slope per ampere"),
    "gamma_1": ("1/m", "Bouc-Wen gamma at 0 A"),
    "delta": ("1/m", "Bouc-Wen delta (fixed at 1/mm in identification)"),
    "n": ("1", "Bouc-Wen exponent n"),
}

BEYOND_RANGE_DEFAULT = "stop"
"""The BoucWenIsolator's default beyond +-x_identified: its own continuation plus the stop at x_limit.

Past the tested 8 mm the model needs no separate continuation: its elastic part k(i) x is linear and y
is bounded by its envelope, so the force goes on along the post-yield slope k(i) (+ alpha dy/dx, which
tends to 0 on the envelope), with no invented stiffening ('tangent' is therefore the same as
'extrapolate' here). The data's trend supports that slope: Table 1's peak forces grow affinely with the
amplitude (docs/identification.md, "Past the tested stroke"). 'stop' adds the Kelvin stop of
mre_isolator_core.stop_contact at +-x_limit."""


def _blame(prefix: str, model, i: float) -> str:
    return f"{prefix}_1" if i == 0.0 or getattr(model, f"{prefix}_1") < 0.0 else f"{prefix}_0"


def tangent_bounds(k, alpha, beta, gamma, delta) -> tuple[float, float]:
    """Smallest and largest tangent stiffness dF/dx [N/m] of one device (Eq. 1-2) over every state inside the
    envelope and both directions of motion, for n > 0 and beta + gamma > 0.

    dF/dx = k + alpha dy/dx, dy/dx = delta - lam y: delta at y = 0, 0 when loading on the envelope and
    2 delta gamma / (beta + gamma) when unloading from it, monotone in |y|^n in between.
    """
    rates = (delta, 0.0, 2.0 * delta * gamma / (beta + gamma))
    values = [k + alpha * r for r in rates]
    return min(values), max(values)


def device_problem(model: BoucWenCurrentModel, i_max: float = CURRENT_MAX_A, n_isolators: int = 2,
                   beyond_range: str = BEYOND_RANGE_DEFAULT, x_identified: float = IDENTIFIED_RANGE_M,
                   x_limit: float = DEVICE_LIMIT_M, k_stop: float = STOP_STIFFNESS, c_stop: float = 0.0) -> None:
    """ParameterError (naming the coefficient, with its unit) unless the law is a device on [0, i_max] A.

    delta > 0 and n > 0 finite; beta + gamma > 0 at every current of ``current_grid`` (else there is no
    hysteresis envelope); the force rises with displacement in every state (:func:`tangent_bounds` >= 0);
    ``beyond_range`` one of BEYOND_RANGE; with ``stop``, x_limit > x_identified > 0, c_stop >= 0 and
    k_stop above the device's largest tangent stiffness (a stop must be stiffer than what it stops).
    """
    if beyond_range not in BEYOND_RANGE:
        raise ParameterError("beyond_range", f"beyond_range = {beyond_range!r} is not one of "
                             f"{', '.join(map(repr, BEYOND_RANGE))}")
    if not (math.isfinite(i_max) and i_max >= 0.0):
        raise ParameterError("i_max", f"i_max = {i_max!r} A must be finite and >= 0")
    for name in ("delta", "n"):
        value = getattr(model, name)
        if not (math.isfinite(value) and value > 0.0):
            raise ParameterError(name, f"{name} = {value!r} {COEFFICIENT_DOCS[name][0]} must be finite and > 0")
    stiffest = 0.0
    for i in current_grid(i_max):
        p = model.at_current(i)
        if not p.beta + p.gamma > 0.0:
            name = _blame("gamma" if p.gamma < 0.0 else "beta", model, i)
            raise ParameterError(name, f"{name} = {getattr(model, name)!r} {COEFFICIENT_DOCS[name][0]}: "
                                 f"beta + gamma = {p.beta + p.gamma:.4g} 1/m <= 0 at i = {i:.4g} A "
                                 "(no hysteresis envelope)")
        low, high = tangent_bounds(p.k, p.alpha, p.beta, p.gamma, p.delta)
        if not low >= 0.0:
            prefix = "k" if p.k < 0.0 else "alpha" if p.alpha < 0.0 else "gamma"
            name = _blame(prefix, model, i)
            raise ParameterError(name, f"{name} = {getattr(model, name)!r} {COEFFICIENT_DOCS[name][0]}: the force "
                                 f"does not rise with displacement (tangent stiffness down to {n_isolators * low:.4g}"
                                 f" N/m < 0 at i = {i:.4g} A)")
        stiffest = max(stiffest, n_isolators * high)
    if beyond_range == "stop":
        if not x_identified > 0.0:
            raise ParameterError("x_identified", f"x_identified = {x_identified!r} m must be > 0")
        if not x_limit > x_identified:
            raise ParameterError("x_limit", f"x_limit = {x_limit!r} m must exceed x_identified = {x_identified!r} m")
        if not c_stop >= 0.0:
            raise ParameterError("c_stop", f"c_stop = {c_stop!r} N.s/m must not be negative")
        if not k_stop > stiffest:
            raise ParameterError("k_stop", f"k_stop = {k_stop!r} N/m is not stiffer than the device "
                                 f"({stiffest:.4g} N/m on [0, {i_max:g}] A): a stop must be stiffer than what it stops")


def parameter_problem(values: Mapping[str, float | int | str]) -> tuple[str, str] | None:
    """(parameter, message) for the first BoucWenIsolator parameter out of its domain, or None.

    ``values``: the FMU's parameters by name (absent names take the FMU's defaults); the check the unit
    makes when it initializes (:func:`device_problem`), before anything runs.
    """
    from_values = {name: values.get(name, getattr(SYNTHETIC_DEFAULT, name)) for name in COEFFICIENT_DOCS}
    try:
        model = BoucWenCurrentModel(**{name: float(v) for name, v in from_values.items()})
        device_problem(model, float(values.get("i_max", CURRENT_MAX_A)), int(values.get("n_isolators", 2)),
                       str(values.get("beyond_range", BEYOND_RANGE_DEFAULT)),
                       float(values.get("x_identified", IDENTIFIED_RANGE_M)),
                       float(values.get("x_limit", DEVICE_LIMIT_M)), float(values.get("k_stop", STOP_STIFFNESS)),
                       float(values.get("c_stop", 0.0)))
    except ParameterError as exc:
        return exc.parameter, str(exc)
    return None
