"""The SOSM convergence conditions of the paper (Eq. 33-38), evaluated along a run.

The paper's finite-time convergence argument (Levant 2007) needs bounds that hold for all
t > 0 (Eq. 36): |Phi| <= tau and 0 < v_m <= Psi <= v_M, with the gains chosen so that
rho v_m - tau > theta^2 / 2 and zeta theta > rho (after Eq. 39). Here:

* Psi = d s''/du (Eq. 34) is computed from the base motion and the current with the
  controller's isolator model: Psi = -(n / m_b) dF/di, F the force of one device.
* Phi = s'' - Psi u (Eq. 35: s'' with u = 0) is measured from the run: s'' = d/dt(x_b'' +
  lambda x_b') by central differences of the recorded base acceleration, u = di/dt by
  central differences of the recorded current.

Psi changes sign with the motion and vanishes at rest, so v_m (the smallest |Psi|, the
controller applying sign(Psi) u) is 0 and rho v_m - tau > theta^2 / 2 cannot hold: the
convergence argument does not apply globally. :func:`sosm_conditions` also reports the
share of the run where the condition holds pointwise with the global tau
(rho |Psi(t)| - tau > theta^2 / 2) and with the local |Phi(t)| in place of tau.

The release band ``s_release`` of ``sosm_controller_core`` (a designer's extension, not in
the paper: while |s| < s_release the current falls at rate rho) is outside the paper's
argument: inside the band the applied rate is not sign(Psi) u, so the conditions say nothing
there. They are evaluated the same way with or without it (u measured from the recorded current).

Units: x [m], v [m/s], a [m/s^2], i [A], t [s]; s'' and Phi [m/s^3]; Psi [m/(s^2 A)];
tau [m/s^3]; v_m, v_M [m/(s^2 A)]; rho [A/s], zeta [A s^0.5 m^-0.5], theta [m^0.5 s^-1.5].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mre_isolator_core import current_sensitivity


def psi(x: np.ndarray, v: np.ndarray, i: np.ndarray, model, m_b: float, n_isolators: int = 2) -> np.ndarray:
    """Psi of Eq. (34) [m/(s^2 A)]: the sensitivity of s'' to the current rate u.

    ``model`` has the per-device coefficients c0_0, k0_0, alpha_0, alpha_1, beta_0, beta_1
    (slopes per ampere ``*_0``; e.g. ``sosm_controller_core.IsolatorModel`` or
    ``mre_isolator_core.GeneralizedCoefficients``); m_b is the base-floor mass [kg].
    """
    x, v, i = (np.asarray(a, dtype=float) for a in (x, v, i))
    with np.errstate(over="ignore", invalid="ignore"):
        dF_di = current_sensitivity(x, v, i, model, 1, np.sinh, np.cosh)  # one device (the isolator law's dF/di)
    return -(n_isolators / m_b) * dF_di


def phi(t: np.ndarray, v: np.ndarray, a: np.ndarray, i: np.ndarray, psi_values: np.ndarray,
        lam: float) -> np.ndarray:
    """Phi = s'' - Psi u [m/s^3] (Eq. 35) from a run's base velocity, acceleration and current."""
    t, v, a, i = (np.asarray(y, dtype=float) for y in (t, v, a, i))
    sdot = a + lam * v
    return np.gradient(sdot, t) - psi_values * np.gradient(i, t)


@dataclass(frozen=True)
class SosmConditions:
    """The bounds of Eq. (36) over a run and the gain conditions after Eq. (39)."""

    tau: float  # max |Phi| [m/s^3]
    v_m: float  # min |Psi| [m/(s^2 A)]
    v_M: float  # max |Psi| [m/(s^2 A)]
    reaching_margin: float  # rho v_m - tau - theta^2 / 2 [m/s^3]; > 0 is the paper's condition
    reaching_holds: bool
    share_pointwise: float  # share of samples with rho |Psi| - tau > theta^2 / 2
    share_local: float  # share of samples with rho |Psi(t)| - |Phi(t)| > theta^2 / 2 (the local bound)
    zeta_theta_over_rho: float  # zeta theta / rho; > 1 is the paper's second condition
    zeta_theta_holds: bool


def sosm_conditions(  # noqa: PLR0913 - a run's five signals side by side, as Eq. (34)-(36) use them
    t: np.ndarray, x: np.ndarray, v: np.ndarray, a: np.ndarray, i: np.ndarray, gains, model, m_b: float,
    n_isolators: int = 2,
) -> SosmConditions:
    """tau, v_m, v_M along a run and whether the paper's gain conditions hold with them.

    ``gains`` has lam, rho, zeta, theta (``sosm_controller_core.SosmGains``).
    """
    p = psi(x, v, i, model, m_b, n_isolators)
    f = phi(t, v, a, i, p, gains.lam)
    abs_p = np.abs(p[np.isfinite(p)])
    tau = float(np.max(np.abs(f[np.isfinite(f)]))) if np.isfinite(f).any() else float("nan")
    v_m = float(np.min(abs_p)) if len(abs_p) else float("nan")
    v_M = float(np.max(abs_p)) if len(abs_p) else float("nan")
    half_theta2 = 0.5 * gains.theta ** 2
    margin = gains.rho * v_m - tau - half_theta2
    pointwise = gains.rho * np.abs(p) - tau > half_theta2
    local = gains.rho * np.abs(p) - np.abs(f) > half_theta2
    ratio = gains.zeta * gains.theta / gains.rho
    return SosmConditions(tau, v_m, v_M, float(margin), bool(margin > 0), float(np.mean(pointwise)),
                          float(np.mean(local)), float(ratio), bool(ratio > 1))
