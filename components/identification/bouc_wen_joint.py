"""Current-dependent Bouc-Wen model fitted jointly to all conditions (beyond the paper).

The paper's route (identify per condition, average per current, fit lines) does not carry
over to Bouc-Wen: its parameters trade off against each other (alpha, beta, gamma, n), so
per-condition FFOA estimates scatter and their per-current averages can give lines that
turn beta + gamma negative inside [0, 3] A (no hysteresis envelope). This module refines
such a start by nonlinear least squares over all conditions at once
(``scipy.optimize.least_squares``, trust-region reflective, bounds):

* unknowns: k, c, alpha, beta, gamma at 0 A and at ``i_ref`` (the largest current of the
  data), and n; the linear rule p(i) = p_0 i + p_1 of BoucWenCurrentModel follows, and
  the bounds p(0), p(i_ref) >= 0 keep every parameter non-negative on [0, i_ref];
* residual: per condition, (predicted - measured force) / (force RMS * sqrt(samples)),
  so that every condition weighs the same whatever its force level;
* delta fixed at 1/mm; F0 per condition = mean force (as in Eq. 5 usage);
* the Bouc-Wen state uses sub-steps of at most ``dx_max`` only (no parameter-dependent
  sub-step count), so residuals are smooth in the unknowns for finite differences; the
  Jacobian is by forward differences evaluated as one batch.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from components.identification.models import BW_DELTA_MM, FitData, bouc_wen_window_states
from components.identification.paper_tables import Condition

LINEAR = ("k", "c", "alpha", "beta", "gamma")
_FLOOR = {"k": 1e-3, "c": 1e-4, "alpha": 1e-3, "beta": 1e-4, "gamma": 0.0}
JOINT_DX_MAX_MM = 0.1


@dataclass(frozen=True)
class JointFit:
    """coefficients: paper units, BoucWenCurrentModel names; rms_per_condition [N]."""

    coefficients: dict[str, float]
    rms_per_condition: dict[Condition, float]
    cost_start: float
    cost: float
    seconds: float
    success: bool
    message: str


def _coefficients(theta: np.ndarray, i_ref: float) -> dict[str, np.ndarray]:
    out = {}
    for j, p in enumerate(LINEAR):
        at0, atref = theta[..., j], theta[..., j + len(LINEAR)]
        out[f"{p}_1"], out[f"{p}_0"] = at0, (atref - at0) / i_ref
    out["n"] = theta[..., 2 * len(LINEAR)]
    return out


def _residuals(theta: np.ndarray, data: list[FitData], i_ref: float) -> np.ndarray:
    """Residuals for a batch theta (P, 11) -> (P, M)."""
    co = _coefficients(theta, i_ref)
    parts = []
    for d in data:
        i = d.condition[2]
        p = {name: co[f"{name}_0"] * i + co[f"{name}_1"] for name in LINEAR}
        y = bouc_wen_window_states(
            d, p["beta"], p["gamma"], co["n"], dx_max=JOINT_DX_MAX_MM, lam_dx_max=np.inf
        )
        pred = p["k"][:, None] * d.x + p["c"][:, None] * d.v + p["alpha"][:, None] * y + d.F0
        parts.append((pred - d.F) / (d.force_rms * np.sqrt(d.F.size)))
    return np.concatenate(parts, axis=1)


def fit_bouc_wen_joint(
    data: Mapping[Condition, FitData], start: Mapping[str, float], max_nfev: int = 40
) -> JointFit:
    """Refine generalized Bouc-Wen coefficients (paper units, ``start``) on all conditions."""
    items = list(data.values())
    i_ref = max(d.condition[2] for d in items)
    if i_ref <= 0 or len({d.condition[2] for d in items}) < 2:
        raise ValueError("the joint Bouc-Wen fit needs data at two or more currents")
    lower = np.array([_FLOOR[p] for p in LINEAR] * 2 + [0.5])
    upper = np.full(lower.size, np.inf)
    upper[-1] = 4.0
    x0 = np.array(
        [start[f"{p}_1"] for p in LINEAR]
        + [start[f"{p}_0"] * i_ref + start[f"{p}_1"] for p in LINEAR]
        + [start["n"]]
    )
    x0 = np.clip(x0, lower + 1e-3 * np.maximum(np.abs(x0), 1e-2), upper)

    def fun(th: np.ndarray) -> np.ndarray:
        return _residuals(th[None, :], items, i_ref)[0]

    def jac(th: np.ndarray) -> np.ndarray:
        h = 1e-6 * np.maximum(np.abs(th), 1e-2)
        batch = np.vstack([th, th + np.diag(h)])
        r = _residuals(batch, items, i_ref)
        return ((r[1:] - r[0]) / h[:, None]).T

    t0 = time.perf_counter()
    cost_start = 0.5 * float(np.sum(fun(x0) ** 2))
    res = least_squares(
        fun, x0, jac=jac, bounds=(lower, upper), method="trf", max_nfev=max_nfev, x_scale="jac"
    )
    seconds = time.perf_counter() - t0
    co = {k: float(v) for k, v in _coefficients(res.x, i_ref).items()}
    co["delta"] = BW_DELTA_MM
    r = _residuals(res.x[None, :], items, i_ref)[0]
    per, k = {}, 0
    for d in items:
        seg = r[k : k + d.F.size] * d.force_rms * np.sqrt(d.F.size)
        per[d.condition] = float(np.sqrt(np.mean(seg**2)))
        k += d.F.size
    return JointFit(co, per, cost_start, float(res.cost), seconds, bool(res.success), str(res.message))
