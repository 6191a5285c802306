"""Elastic response spectra of ground-motion records: the piecewise-exact SDOF solution.

A single-degree-of-freedom oscillator of period T [s] and damping ratio zeta, at rest at
t = 0, under the ground acceleration ag(t) [any unit]::

    u'' + 2 zeta w u' + w^2 u = -ag(t),   w = 2 pi / T

is solved exactly for an ag that is linear between samples (Nigam & Jennings 1969;
Chopra, *Dynamics of Structures*, section 5.2) -- the same signal the ground-motion FMU
plays, which interpolates its record linearly. The recurrence over one step dt,
``[u, u']_{k+1} = M [u, u']_k + N0 p_k + N1 p_{k+1}`` with p = -ag, is run as the
equivalent second-order filter (``scipy.signal.lfilter``) seeded with the exact first
step. The pseudo-spectral acceleration is ``PSa = w^2 max |u|`` (in the unit of ag).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter, lfiltic


def _coefficients(omega: float, zeta: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M (2x2), N0, N1 (2,) of the exact recurrence for unit mass (Chopra Table 5.2.1)."""
    if not 0.0 <= zeta < 1.0:
        raise ValueError(f"damping ratio must be in [0, 1), got {zeta}")
    k = omega * omega
    root = math.sqrt(1.0 - zeta * zeta)
    wd = omega * root
    e = math.exp(-zeta * omega * dt)
    s, c = math.sin(wd * dt), math.cos(wd * dt)
    zr = zeta / root
    a = e * (zr * s + c)
    b = e * s / wd
    cc = (2 * zeta / (omega * dt) + e * (((1 - 2 * zeta**2) / (wd * dt) - zr) * s
                                         - (1 + 2 * zeta / (omega * dt)) * c)) / k
    d = (1 - 2 * zeta / (omega * dt) + e * ((2 * zeta**2 - 1) / (wd * dt) * s + 2 * zeta / (omega * dt) * c)) / k
    a1 = -e * omega / root * s
    b1 = e * (c - zr * s)
    c1 = (-1 / dt + e * ((omega / root + zeta / (dt * root)) * s + c / dt)) / k
    d1 = (1 - e * (zr * s + c)) / (k * dt)
    return np.array([[a, b], [a1, b1]]), np.array([cc, c1]), np.array([d, d1])


def sdof_displacement(ag: np.ndarray, dt: float, period: float, zeta: float = 0.05) -> np.ndarray:
    """Relative displacement u_k of the oscillator at t_k = k dt (unit of ag times s^2), u_0 = u'_0 = 0."""
    if not (period > 0 and dt > 0):
        raise ValueError(f"period and dt must be positive, got {period}, {dt}")
    p = -np.asarray(ag, dtype=float)
    n = len(p)
    u = np.zeros(n)
    if n < 2:
        return u
    m, n0, n1 = _coefficients(2 * math.pi / period, zeta, dt)
    u[1] = n0[0] * p[0] + n1[0] * p[1]
    if n == 2:
        return u
    # U(z)/P(z) = e1' (zI - M)^-1 (N0 + z N1): a second-order filter, exact for n >= 2.
    b = np.array([n1[0], n0[0] - m[1, 1] * n1[0] + m[0, 1] * n1[1], m[0, 1] * n0[1] - m[1, 1] * n0[0]])
    a = np.array([1.0, -(m[0, 0] + m[1, 1]), m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]])
    zi = lfiltic(b, a, y=[u[1], u[0]], x=[p[1], p[0]])
    u[2:], _ = lfilter(b, a, p[2:], zi=zi)
    return u


def pseudo_acceleration(ag: np.ndarray, dt: float, periods: float | np.ndarray, zeta: float = 0.05) -> np.ndarray:
    """PSa(T) = (2 pi / T)^2 max_t |u(t)| for each period T [s], in the unit of ag (same shape as ``periods``)."""
    ts = np.atleast_1d(np.asarray(periods, dtype=float))
    out = np.array([(2 * math.pi / t) ** 2 * float(np.max(np.abs(sdof_displacement(ag, dt, t, zeta))))
                    for t in ts])
    return out.reshape(np.shape(periods))


def resample_uniform(time: np.ndarray, values: np.ndarray, dt: float | None = None) -> tuple[np.ndarray, float]:
    """Values on a uniform grid from t_0 (step ``dt``, default the median sample spacing), linearly interpolated."""
    t = np.asarray(time, dtype=float)
    v = np.asarray(values, dtype=float)
    steps = np.diff(t)
    if dt is None:
        dt = float(np.median(steps)) if len(steps) else 1.0
    if len(steps) and np.allclose(steps, dt, rtol=1e-9, atol=0.0):
        return v, dt
    n = math.floor((t[-1] - t[0]) / dt + 1e-9) + 1
    return np.interp(t[0] + dt * np.arange(n), t, v), dt
