"""Clipped-optimal current control of the MRE isolators (Dyke, Spencer, Sain and Carlson 1996).

Source: S. J. Dyke, B. F. Spencer Jr., M. K. Sain and J. D. Carlson (1996), "Modeling and
control of magnetorheological dampers for seismic response reduction", Smart Mater.
Struct. 5, 565-575 (an H2/LQG design on a three-storey building, the one of the paper's
Table 3, and the clipping law for the damper voltage).

Design (at initialization, with scipy): the isolated building with the isolators
linearised at the nominal current i_nom (secant stiffness at the amplitude x_lin, exact
damping; :mod:`lqg_plant_core`) and a control force u on the base. The LQR gain K_u
minimises J = integral of the weighted squares of base displacement and velocity,
inter-storey drifts, absolute floor accelerations and u (weights :class:`Weights`,
scipy.linalg.solve_continuous_are with the cross term of the accelerations). The isolators
deliver the linearised force F_lin(i_nom) minus the control force, so the desired
isolator force (restoring, positive along x_0, the convention of the measured F) is

    f_c = k_lin(i_nom) x^_0 + c(i_nom) x^'_0 + K_u z^  =  -K z^

from the Kalman estimate z^ (:class:`lqg_plant_core.StateEstimator`, absolute floor
accelerations and base displacement, the measured F as input).

Two laws turn f_c into a current in [0, i_max]:

* ``clipped`` (Dyke et al. 1996): i = i_max H((f_c - F) F), F the measured isolator force,
  H the Heaviside step (H(0) = 0). It assumes, as for an MR damper, that more current
  means more |F| along F. For the MRE isolator dF/di (the paper's Eq. 34 bracket) has the
  sign of c0_0 v + x g(x, i) with g > 0, while F has the sign of c0(i) v + x h(x, i):
  the two disagree in a wedge of the phase plane where the base returns towards its
  centre (x v < 0) and |v/x| lies between the two ratios (about 15 and 18 1/s with Table 2
  at 0 A). There raising the current moves F away from f_c, and lowering it never takes
  F below |F(0 A)| (the elastomer keeps its stiffness): the clipping is a heuristic here.
* ``inverse``: the current whose Eq. 17 force at the measured x, v is closest to f_c.
  A bounded scalar search, fine grid + refine: Eq. 17 on a grid of ``n_grid`` currents
  over [0, i_max]; where F - f_c changes sign between two grid points the lowest such
  bracket is solved by regula falsi (Illinois) to 1e-6 A (F meets f_c; the lowest current
  that does), else
  the grid's best point is refined by golden-section search of |F - f_c| between its
  neighbours. This uses the true shape of F(i), hence the true sign of dF/di. (Plain
  Python rather than scipy.optimize: it runs every step, where scipy's per-call overhead
  would cost more than the search.)

Units: x [m], v [m/s], F and f_c [N], i [A], accelerations [m/s^2].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

try:
    from . import lqg_plant_core as plant_core
    from .lqg_plant_core import BuildingModel, IsolatorLaw, NoiseIntensities, ParameterError, Weights
except ImportError:  # inside an FMU the cores are top-level modules
    import lqg_plant_core as plant_core
    from lqg_plant_core import BuildingModel, IsolatorLaw, NoiseIntensities, ParameterError, Weights

LAWS = ("clipped", "inverse")
MAX_GRID = 100_001  # currents of the inverse law's grid: a sanity bound (it is evaluated every step)


def clipped_current(f_c: float, F: float, i_max: float) -> float:
    """Dyke's clipping: i_max if (f_c - F) F > 0, else 0 [A]."""
    return i_max if (f_c - F) * F > 0.0 else 0.0


def inverse_current(f_c: float, x: float, v: float, law: IsolatorLaw, i_max: float, n_grid: int = 31,
                    tol: float = 1e-6) -> float:
    """The current in [0, i_max] [A] whose Eq. 17 force at x [m], v [m/s] is closest to f_c [N].

    Eq. 17 on a grid of n_grid currents; where F - f_c changes sign between two grid points
    the lowest such bracket is solved by regula falsi (Illinois) to ``tol`` [A] or a force error
    below 1e-9 of |f_c|, else the grid's best point is refined
    by golden-section search of |F - f_c| between its neighbours (to ``tol``); the grid point
    is kept if the refinement finds nothing closer.
    """
    grid = np.linspace(0.0, i_max, n_grid)
    g = law.forces(x, v, grid) - f_c
    if not np.all(np.isfinite(g)):
        return 0.0
    if g[0] == 0.0:
        return 0.0
    change = np.flatnonzero(np.signbit(g[:-1]) != np.signbit(g[1:]))
    if change.size:  # a root: the force can be met exactly
        k = int(change[0])
        lo, hi, g_lo, g_hi = float(grid[k]), float(grid[k + 1]), float(g[k]), float(g[k + 1])
        side = 0
        while hi - lo > tol:  # regula falsi, Illinois variant: a bracket that shrinks from both ends
            mid = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
            if not lo < mid < hi:
                mid = 0.5 * (lo + hi)
            g_mid = law.force(x, v, mid) - f_c
            if g_mid == 0.0:
                return mid
            if (g_mid < 0.0) == (g_lo < 0.0):
                lo, g_lo = mid, g_mid
                if side == -1:
                    g_hi *= 0.5
                side = -1
            else:
                hi, g_hi = mid, g_mid
                if side == 1:
                    g_lo *= 0.5
                side = 1
            if abs(g_mid) <= 1e-9 * (abs(f_c) + 1.0):
                return mid
        return lo if abs(g_lo) <= abs(g_hi) else hi
    k = int(np.argmin(np.abs(g)))
    lo, hi = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, n_grid - 1)])
    best, best_err = float(grid[k]), abs(float(g[k]))
    ratio = 0.5 * (math.sqrt(5.0) - 1.0)
    a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    fa, fb = abs(law.force(x, v, a) - f_c), abs(law.force(x, v, b) - f_c)
    while hi - lo > tol:
        if fa <= fb:
            hi, b, fb = b, a, fa
            a = hi - ratio * (hi - lo)
            fa = abs(law.force(x, v, a) - f_c)
        else:
            lo, a, fa = a, b, fb
            b = lo + ratio * (hi - lo)
            fb = abs(law.force(x, v, b) - f_c)
    for i, err in ((a, fa), (b, fb)):
        if err < best_err:
            best, best_err = i, err
    return best


@dataclass(frozen=True)
class ClippedOptimalDesign:
    """Design parameters: law, current range, nominal current, linearisation amplitude, grid."""

    law: str = "clipped"
    i_max: float = 3.0  # A
    i_nom: float = 1.5  # A: the isolators' current in the linearised plant
    x_lin: float = 0.005  # m: secant amplitude of the sinh spring (0: tangent at 0)
    n_grid: int = 31  # currents of the inverse law's grid

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise ParameterError("law", f"law must be one of {LAWS}, got {self.law!r}")
        if not (math.isfinite(self.i_max) and self.i_max > 0):
            raise ParameterError("i_max", f"i_max must be positive and finite, got {self.i_max}")
        if not (math.isfinite(self.i_nom) and 0 <= self.i_nom <= self.i_max):
            raise ParameterError("i_nom", f"i_nom must lie in [0, i_max = {self.i_max}], got {self.i_nom}")
        if not (math.isfinite(self.x_lin) and self.x_lin >= 0):
            raise ParameterError("x_lin", f"x_lin must be >= 0 m and finite, got {self.x_lin}")
        if not 2 <= self.n_grid <= MAX_GRID:
            raise ParameterError("n_grid", f"n_grid must lie in [2, {MAX_GRID}], got {self.n_grid}")


class ClippedOptimalController(plant_core.EstimatedStateController):
    """LQG desired force and its clipped (or inverse-model) current; gains computed at construction.

    Arguments (all optional, defaults where None): design :class:`ClippedOptimalDesign`, weights
    :class:`Weights`, noise :class:`NoiseIntensities`, building :class:`BuildingModel`, isolator
    :class:`IsolatorLaw`; :meth:`update` steps it (:class:`lqg_plant_core.EstimatedStateController`).
    """

    design_class = ClippedOptimalDesign

    def _design(self) -> None:
        d = self.design
        plant = plant_core.linearised_plant(self.building, self.isolator, d.i_nom, d.x_lin)
        Q, N, R = plant_core.regulated_cost(plant, self.weights)
        self.K_u = plant_core.lqr_gain(plant.A, plant.b, Q, R, N)
        n = self.building.n_levels
        self.K = -self.K_u.copy()  # f_c = -K z
        self.K[0] -= self.isolator.stiffness(d.i_nom, d.x_lin)
        self.K[n] -= self.isolator.damping(d.i_nom)
        if not np.all(np.isfinite(self.K)):
            raise ValueError("the desired-force gain is not finite (a model parameter too large)")
        self.f_c = 0.0

    def desired_force(self, z: np.ndarray) -> float:
        """f_c = -K z [N], the desired isolator restoring force for the state z."""
        return float(-self.K @ z)

    def current(self, f_c: float, x: float, v: float, F: float) -> float:
        """The law's current [A] for the desired force f_c [N] and the measured x [m], v [m/s], F [N]."""
        d = self.design
        if d.law == "clipped":
            return clipped_current(f_c, F, d.i_max)
        return inverse_current(f_c, x, v, self.isolator, d.i_max, d.n_grid)

    def decide(self, x: float, v: float, F: float) -> float:
        """The desired force f_c from the estimate, then the law's current [A] (sets ``f_c``)."""
        self.f_c = self.desired_force(self.estimator.z)
        return self.current(self.f_c, x, v, F)


def controller_parts(values: Mapping[str, Any], n_levels: int = 4) -> tuple[
        ClippedOptimalDesign, Weights, NoiseIntensities, BuildingModel, IsolatorLaw]:
    """The controller's design objects from its FMU parameter values by name (the arguments of
    :class:`ClippedOptimalController`); :class:`ParameterError` names the first one out of its domain."""
    return plant_core.estimator_parts(ClippedOptimalDesign, values, n_levels)


def parameter_problem(values: Mapping[str, Any], n_levels: int = 4) -> tuple[str, str] | None:
    """(parameter, message) for the first FMU parameter out of its domain, or a design that cannot be made from
    them (zero control weight, zero process noise, not stabilizing), or None (a check before any run)."""
    return plant_core.design_problem(ClippedOptimalController, controller_parts, values, n_levels)
