"""Lyapunov current control of the MRE isolators (after Jansen and Dyke 2000).

Source: L. M. Jansen and S. J. Dyke (2000), "Semiactive control strategies for MR
dampers: comparative study", J. Eng. Mech. 126(8), 795-803 (the Lyapunov controller,
after Leitmann 1994): V = 1/2 z'Pz with A'P + PA = -Q for the passive-off system, and the
command that makes dV/dt smallest.

Here A is the isolated building with the isolators linearised at 0 A (secant stiffness
at x_lin, exact damping; :mod:`lqg_plant_core`), Q = the weighted squares of base
displacement and velocity, drifts and absolute accelerations (:class:`Weights`, the same
responses the clipped-optimal design weights; P by scipy.linalg.solve_continuous_lyapunov).
Along the plant, with f(i) the force the isolators apply to the base (f = -F, F the
restoring force of Eq. 17) and B = e_{v0}/m_0 its influence vector,

    dV/dt = 1/2 z'(A'P + PA) z + z'PB (f(i) - f_lin,0(z)) + z'P e ag

and only z'PB f(i) depends on the current. Between i = 0 and i = i_max the smaller dV/dt
is i_max exactly when z'PB (f(i_max) - f(0)) < 0, i.e. z'PB * df/di < 0 with df/di the
mean slope over [0, i_max] at the measured x, v (the secant, so the choice is exact even
where df/di changes sign inside the range). z is the Kalman estimate
(:class:`lqg_plant_core.StateEstimator`).

The MRE sign question: for an MR damper more current means more |f| along f, so
sign(df/di) = sign(f) and the rule becomes Jansen and Dyke's i = i_max H(-z'PB f). For
the MRE isolator df/di = -dF/di = -n (c0_0 v + k0_0 x + alpha_0 sinh(beta x)
+ alpha beta_0 x cosh(beta x)): a controllable stiffness and damping whose sign follows
c0_0 v + x g(x) (g > 0), not the sign of f. In the wedge of the phase plane where the base
returns (x v < 0) with |v/x| between c-over-k ratios of F and of dF/di, the two differ and
H(-z'PB f) picks the current that makes dV/dt larger; the argument must be z'PB df/di.

Units: x [m], v [m/s], F [N], i [A].
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


@dataclass(frozen=True)
class LyapunovDesign:
    """i_max [A]; x_lin [m] the secant amplitude of the passive-off linearisation (0: tangent at 0)."""

    i_max: float = 3.0
    x_lin: float = 0.005

    def __post_init__(self) -> None:
        if not (math.isfinite(self.i_max) and self.i_max > 0):
            raise ParameterError("i_max", f"i_max must be positive and finite, got {self.i_max}")
        if not (math.isfinite(self.x_lin) and self.x_lin >= 0):
            raise ParameterError("x_lin", f"x_lin must be >= 0 m and finite, got {self.x_lin}")


def lyapunov_weights() -> Weights:
    """Default Q of the Lyapunov equation: the responses' weights without a control weight."""
    return Weights(r=0.0)


class LyapunovController(plant_core.EstimatedStateController):
    """Bang-bang current in {0, i_max} that makes dV/dt smaller, V = 1/2 z'Pz.

    Arguments (all optional, defaults where None): design :class:`LyapunovDesign`, weights :class:`Weights`
    (Q; default :func:`lyapunov_weights`), noise :class:`NoiseIntensities`, building :class:`BuildingModel`,
    isolator :class:`IsolatorLaw`; :meth:`update` steps it (:class:`lqg_plant_core.EstimatedStateController`).
    """

    design_class = LyapunovDesign

    @staticmethod
    def default_weights() -> Weights:
        return lyapunov_weights()

    def _design(self) -> None:
        plant = plant_core.linearised_plant(self.building, self.isolator, 0.0, self.design.x_lin)
        Q, _, _ = plant_core.regulated_cost(plant, self.weights)
        self.P = plant_core.lyapunov_matrix(plant.A, Q)
        self.B = plant.b.copy()  # influence of a base force on z'
        self.PB = self.P @ self.B
        self.switch = 0.0  # z'PB (f(i_max) - f(0)) [N * state units] at the last decision

    def switching_function(self, z: np.ndarray, x: float, v: float) -> float:
        """z'PB (f(i_max) - f(0)) for the state z and the measured x [m], v [m/s]; < 0 selects i_max."""
        d_f = -(self.isolator.force(x, v, self.design.i_max) - self.isolator.force(x, v, 0.0))
        return float(self.PB @ z) * d_f

    def current(self, z: np.ndarray, x: float, v: float) -> float:
        """i_max if z'PB df/di < 0 at the measured x, v, else 0 [A]."""
        self.switch = self.switching_function(z, x, v)
        return self.design.i_max if self.switch < 0.0 else 0.0

    def decide(self, x: float, v: float, F: float) -> float:
        """:meth:`current` for the estimate at this communication point (F is not used)."""
        return self.current(self.estimator.z, x, v)


def controller_parts(values: Mapping[str, Any], n_levels: int = 4) -> tuple[
        LyapunovDesign, Weights, NoiseIntensities, BuildingModel, IsolatorLaw]:
    """The controller's design objects from its FMU parameter values by name (the arguments of
    :class:`LyapunovController`; Q's weights without a control weight, r = 0); :class:`ParameterError`
    names the first one out of its domain."""
    return plant_core.estimator_parts(LyapunovDesign, values, n_levels, r=0.0)


def parameter_problem(values: Mapping[str, Any], n_levels: int = 4) -> tuple[str, str] | None:
    """(parameter, message) for the first FMU parameter out of its domain, or a design that cannot be made from
    them (zero control weight, zero process noise, not stabilizing), or None (a check before any run)."""
    return plant_core.design_problem(LyapunovController, controller_parts, values, n_levels)
