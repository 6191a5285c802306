"""Second-order sliding-mode (SOSM) current controller, Eq. (27)-(39) of the paper.

Sliding variable s = x_b' + lambda x_b [m/s] and its derivative s' = x_b'' + lambda x_b'
[m/s^2], from the measured base displacement x_b [m], velocity [m/s] and relative
acceleration [m/s^2]. The control is the current rate u = di/dt [A/s], given by the
quasi-continuous law of Eq. (39):

    u1 = clip(-zeta * (s' |s|^-1/2 + theta sign(s)), -rho, rho)    if s != 0
    u2 = -rho sign(s')                                              if s == 0

Sign handling (the paper's Eq. 36 assumes d s''/du = Psi > 0, but Psi of Eq. 34 has the
sign of -(c_E1 x_b' + k_E1 x_b + alpha_1 sinh(beta x_b) + alpha(i) beta_1 x_b cosh(beta x_b)),
which flips with the motion): the applied rate is sign(Psi) * u, evaluated from the
measurements and the controller's model of the isolator (Table 2 by default; the law's
dF/di is ``mre_isolator_core.current_sensitivity``, which travels in the controller's FMU), and 0
where Psi = 0. This makes the reaching condition hold on both sides of x_b = 0.

The current is integrated with forward Euler over each control step and held in
[0, i_max] by clipping (the integrator does not wind up past either bound, which is
Eq. 39's "u = 0 if i > i_M" extended to the lower bound).

Release band (a designer's extension, NOT in the paper): with ``s_release`` > 0 [m/s],
while |s| < s_release the applied rate is -rho, whatever sign(Psi) and u: the current is
released toward 0 A at the largest rate the law allows. Near rest sign(Psi) ~ -sign(c x_b'
+ k x_b) ~ -sign(s) when lambda ~ k/c, so the paper's law applies ~ +min(rho, zeta theta) > 0
whatever the motion's sign and the current ramps up to i_max in any quiet stretch of a
record; the band lets it fall back instead. s_release = 0 (the default) is the paper's law,
bit for bit (the band test is never true).

Gain units: lambda [1/s], rho [A/s], zeta [A s^0.5 m^-0.5], theta [m^0.5 s^-1.5],
s_release [m/s].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

try:  # a package module here, a bare module in an FMU
    from .mre_isolator_core import TABLE2, current_sensitivity
except ImportError:
    from mre_isolator_core import TABLE2, current_sensitivity


@dataclass(frozen=True)
class IsolatorModel:
    """The controller's model of the isolator: the coefficients of Eq. (13)-(16) that Psi
    (Eq. 34) needs, SI units, per device: c0_0 [N*s/(m*A)], k0_0 [N/(m*A)], alpha_0 [N/A],
    alpha_1 [N], beta_0 [1/(m*A)], beta_1 [1/m]. Defaults: Table 2 of the paper
    (``mre_isolator_core.TABLE2``); any object with these attributes (e.g.
    :class:`mre_isolator_core.GeneralizedCoefficients`) can stand in for it.
    """

    c0_0: float = TABLE2.c0_0
    k0_0: float = TABLE2.k0_0
    alpha_0: float = TABLE2.alpha_0
    alpha_1: float = TABLE2.alpha_1
    beta_0: float = TABLE2.beta_0
    beta_1: float = TABLE2.beta_1


GAIN_PARAMETERS = {"lam": "lambda"}  # a gain whose FMU parameter has another name (lambda is a Python keyword)


class ParameterError(ValueError):
    """A gain out of its domain; ``parameter`` is its FMU parameter name (e.g. ``lambda``, ``rho``)."""

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = parameter
        super().__init__(message)


@dataclass(frozen=True)
class SosmGains:
    """Controller gains (README, SOSM gains)."""

    # Defaults: the gains tuned on El Centro by orchestration/case_study/tuning.py
    # (scenarios/sosm_gains.yaml; a test keeps the two equal).
    lam: float = 13.75636215239138  # 1/s
    rho: float = 7.0795685336274365  # A/s
    zeta: float = 18.316074974976253  # A s^0.5 m^-0.5
    theta: float = 1.6969098646453915  # m^0.5 s^-1.5
    i_max: float = 3.0  # A
    s_release: float = 0.0  # m/s: release band (not in the paper); 0 = the paper's law

    def __post_init__(self) -> None:
        for name in ("lam", "rho", "zeta", "theta", "i_max"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ParameterError(GAIN_PARAMETERS.get(name, name),
                                     f"SOSM gain {name} must be positive and finite, got {value}")
        if not (math.isfinite(self.s_release) and self.s_release >= 0):
            raise ParameterError("s_release", f"SOSM release band s_release must be >= 0 m/s and finite, "
                                 f"got {self.s_release}")


# The hand-picked gains used before tuning (and as the tuning's starting point).
HAND_PICKED_GAINS = SosmGains(lam=5.0, rho=20.0, zeta=25.0, theta=1.0)


def sliding_variable(x: float, v: float, a: float, lam: float) -> tuple[float, float]:
    """(s [m/s], s' [m/s^2]) from base displacement x [m], velocity v [m/s], acceleration a [m/s^2]."""
    return v + lam * x, a + lam * v


def quasi_continuous_rate(s: float, sdot: float, gains: SosmGains) -> float:
    """Current rate u [A/s] of Eq. (39) for Psi > 0, before the current bounds."""
    if s != 0.0:
        raw = -gains.zeta * (sdot / math.sqrt(abs(s)) + gains.theta * math.copysign(1.0, s))
        return min(gains.rho, max(-gains.rho, raw))
    if sdot == 0.0:
        return 0.0
    return -gains.rho * math.copysign(1.0, sdot)


def control_direction(x: float, v: float, i: float, coeffs: IsolatorModel | None = None) -> float:
    """sign(Psi) of Eq. (34): +1, -1, or 0 where the current has no first-order effect.

    x [m], v [m/s], i [A]; ``coeffs`` is the isolator model (Table 2 by default).
    """
    bracket = current_sensitivity(x, v, i, coeffs if coeffs is not None else _TABLE2, 1)  # dF/di of one device
    if bracket == 0.0 or math.isnan(bracket):
        return 0.0
    return -math.copysign(1.0, bracket)


_TABLE2 = IsolatorModel()


class SosmController:
    """Discrete SOSM current controller: ``update`` advances the current over one step."""

    def __init__(
        self, gains: SosmGains | None = None, coeffs: IsolatorModel | None = None, i0: float = 0.0
    ) -> None:
        self.gains = gains if gains is not None else SosmGains()
        self.coeffs = coeffs if coeffs is not None else _TABLE2
        self.i = min(max(i0, 0.0), self.gains.i_max)

    def rate(self, x: float, v: float, a: float) -> float:
        """Applied current rate di/dt [A/s] for the measurements and the present current."""
        s, sdot = sliding_variable(x, v, a, self.gains.lam)
        if abs(s) < self.gains.s_release:  # the release band (not in the paper); never true for s_release = 0
            return -self.gains.rho
        return control_direction(x, v, self.i, self.coeffs) * quasi_continuous_rate(s, sdot, self.gains)

    def update(self, x: float, v: float, a: float, h: float) -> float:
        """Integrate the current over h [s] with the measurements held; returns i [A]."""
        self.i = min(max(self.i + h * self.rate(x, v, a), 0.0), self.gains.i_max)
        return self.i


def parameter_problem(values: Mapping[str, Any]) -> tuple[str, str] | None:
    """(parameter, message) for the first gain out of its domain, or None: the check :class:`SosmGains`
    makes when the unit initializes, for the FMU's parameter values by name (before any run)."""
    default = SosmGains()
    try:
        SosmGains(**{f.name: float(values.get(GAIN_PARAMETERS.get(f.name, f.name), getattr(default, f.name)))
                     for f in fields(SosmGains)})
    except ParameterError as exc:
        return exc.parameter, str(exc)
    return None
