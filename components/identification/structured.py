"""Structured identifier of the hyperbolic model (beyond the paper): variable projection.

For a fixed beta, Eq. (3)-(4) is linear in (c0, k0, alpha, F0):
F = [v, x, sinh(beta x), 1] @ (c0, k0, alpha, F0). These four are solved by bounded
linear least squares (``scipy.optimize.lsq_linear``, c0, k0, alpha >= 0 as Eq. 6 asks;
F0 free), which leaves a one-dimensional problem in beta: the RMS residual profile
r(beta). It is scanned on a log grid over [beta_min, beta_max] and the best grid cell is
refined with bounded Brent search (``scipy.optimize.minimize_scalar``) in log(beta).
beta_max is also capped so that beta * max|x| <= 20 (sinh stays well conditioned).
The fit is declared not converged when the optimum lies on a bound of the beta range
(beta then is not identifiable from the data: the sinh term is indistinguishable from
the linear spring, or the refinement failed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear, minimize_scalar

_LOWER = np.array([0.0, 0.0, 0.0, -np.inf])
_UPPER = np.full(4, np.inf)


@dataclass(frozen=True)
class StructuredFit:
    """params: c0, k0, alpha, beta, F0 (paper units); rms [N]; ok/reason: convergence."""

    params: dict[str, float]
    rms: float
    ok: bool
    reason: str
    evaluations: int
    beta_grid: np.ndarray
    rms_profile: np.ndarray


def linear_part(x: np.ndarray, v: np.ndarray, F: np.ndarray, beta: float) -> tuple[np.ndarray, float]:
    """(c0, k0, alpha, F0) minimising the RMS residual at fixed beta, and that RMS [N]."""
    A = np.column_stack([v, x, np.sinh(beta * x), np.ones_like(x)])
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    As = A / norms
    theta, *_ = np.linalg.lstsq(As, F, rcond=None)
    if np.any(theta[:3] < 0):
        theta = lsq_linear(As, F, bounds=(_LOWER, _UPPER), method="bvls").x
    theta = theta / norms
    r = F - A @ theta
    return theta, float(np.sqrt(np.mean(r**2)))


def structured_fit(
    x: np.ndarray,
    v: np.ndarray,
    F: np.ndarray,
    beta_bounds: tuple[float, float] = (1e-3, 5.0),
    n_grid: int = 48,
    xatol: float = 1e-7,
) -> StructuredFit:
    """Identify (c0, k0, alpha, beta, F0) of Eq. (3)-(4) from x [mm], v [mm/s], F [N]."""
    lo, hi = beta_bounds
    hi = min(hi, 20.0 / max(float(np.max(np.abs(x))), 1e-12))
    if not 0 < lo < hi:
        raise ValueError(f"bad beta range [{lo}, {hi}]")
    grid = np.geomspace(lo, hi, n_grid)
    profile = np.array([linear_part(x, v, F, b)[1] for b in grid])
    k = int(np.argmin(profile))
    a, b = np.log(grid[max(k - 1, 0)]), np.log(grid[min(k + 1, n_grid - 1)])
    res = minimize_scalar(
        lambda lb: linear_part(x, v, F, float(np.exp(lb)))[1],
        bounds=(a, b),
        method="bounded",
        options={"xatol": xatol},
    )
    beta = float(np.exp(res.x))
    if res.fun > profile[k]:
        beta = float(grid[k])
    theta, err = linear_part(x, v, F, beta)
    ok, reason = bool(res.success), "" if res.success else f"beta refinement failed: {res.message}"
    span = np.log(hi / lo)
    if ok and (np.log(beta / lo) < 1e-3 * span or np.log(hi / beta) < 1e-3 * span):
        ok, reason = (
            False,
            (
                f"beta = {beta:.4g} 1/mm lies on the search bound [{lo:g}, {hi:.4g}]: "
                "the sinh term is not identifiable from these data"
            ),
        )
    params = {
        "c0": float(theta[0]),
        "k0": float(theta[1]),
        "alpha": float(theta[2]),
        "beta": beta,
        "F0": float(theta[3]),
    }
    return StructuredFit(params, err, ok, reason, n_grid + int(res.nfev) + 1, grid, profile)
