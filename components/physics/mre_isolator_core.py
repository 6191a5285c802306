"""Physics of the MRE base isolator: the hyperbolic hysteresis model of the paper.

The paper states its laws in millimetres, mm/s and newtons (Eq. 3-5, 13-17, Tables 1-2).
Everything in this module is SI (m, m/s, N, A); the conversion from the paper's units
happens once, in :meth:`HyperbolicParams.from_paper_units` and
:meth:`GeneralizedCoefficients.from_paper_units`.

Per device (Eq. 3-4 with z = sinh(beta x)):

    F = c0 * v + k0 * x + alpha * sinh(beta * x) + F0

Current-dependent generalized model (Eq. 13-17): every parameter is linear in the
current i, p(i) = p_slope * i + p_intercept (the paper's p^0 and p^1).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields

try:  # a package module here, a bare module in an FMU
    from .dyke_building import BASE_MASS, DYKE_MASSES
except ImportError:
    from dyke_building import BASE_MASS, DYKE_MASSES

MM = 1e-3  # metres per millimetre


@dataclass(frozen=True)
class HyperbolicParams:
    """Parameters of one device at one current, SI units.

    c0 [N*s/m], k0 [N/m], alpha [N], beta [1/m], F0 [N].
    """

    c0: float
    k0: float
    alpha: float
    beta: float
    F0: float = 0.0

    @classmethod
    def from_paper_units(
        cls, c0: float, k0: float, alpha: float, beta: float, F0: float = 0.0
    ) -> HyperbolicParams:
        """From the paper's units: c0 [N*s/mm], k0 [N/mm], alpha [N], beta [1/mm], F0 [N]."""
        return cls(c0=c0 / MM, k0=k0 / MM, alpha=alpha, beta=beta / MM, F0=F0)

    def to_paper_units(self) -> dict[str, float]:
        """The same parameters in the paper's units (Table 1 layout)."""
        return {
            "c0": self.c0 * MM,
            "k0": self.k0 * MM,
            "alpha": self.alpha,
            "beta": self.beta * MM,
            "F0": self.F0,
        }


def safe_sinh(z: float) -> float:
    """sinh(z), or +-inf where it overflows a double (|z| > ~710), instead of raising."""
    try:
        return math.sinh(z)
    except OverflowError:
        return math.copysign(math.inf, z)


def safe_cosh(z: float) -> float:
    """cosh(z), or +inf where it overflows a double."""
    try:
        return math.cosh(z)
    except OverflowError:
        return math.inf


def hyperbolic_force(x: float, v: float, p: HyperbolicParams) -> float:
    """Force of one device [N] at displacement x [m] and velocity v [m/s] (Eq. 3-4)."""
    return p.c0 * v + p.k0 * x + p.alpha * safe_sinh(p.beta * x) + p.F0


@dataclass(frozen=True)
class GeneralizedCoefficients:
    """Coefficients of the current-dependent model, Eq. (13)-(16), SI units.

    ``*_0`` is the slope per ampere (the paper's superscript 0), ``*_1`` the value at
    0 A (superscript 1): k0(i) = k0_0 * i + k0_1 and so on.
    k0_0 [N/(m*A)], k0_1 [N/m], c0_0 [N*s/(m*A)], c0_1 [N*s/m], alpha_0 [N/A],
    alpha_1 [N], beta_0 [1/(m*A)], beta_1 [1/m].
    """

    k0_0: float
    k0_1: float
    c0_0: float
    c0_1: float
    alpha_0: float
    alpha_1: float
    beta_0: float
    beta_1: float

    @classmethod
    def from_paper_units(cls, **paper: float) -> GeneralizedCoefficients:
        """From Table 2 units: k0 in N/mm, c0 in N*s/mm, alpha in N, beta in 1/mm."""
        per_mm = {"k0_0", "k0_1", "c0_0", "c0_1", "beta_0", "beta_1"}
        return cls(**{k: (v / MM if k in per_mm else v) for k, v in paper.items()})

    def at_current(self, i: float, F0: float = 0.0) -> HyperbolicParams:
        """Device parameters at current i [A] (Eq. 13-16)."""
        return HyperbolicParams(
            c0=self.c0_0 * i + self.c0_1,
            k0=self.k0_0 * i + self.k0_1,
            alpha=self.alpha_0 * i + self.alpha_1,
            beta=self.beta_0 * i + self.beta_1,
            F0=F0,
        )

    def as_dict(self) -> dict[str, float]:
        """Coefficient name -> SI value."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


# Table 2 of the paper, in its units (N/mm, N*s/mm, N, 1/mm).
TABLE2_PAPER_UNITS: dict[str, float] = {
    "k0_0": 5.8161,
    "k0_1": 3.3431,
    "c0_0": 0.5767,
    "c0_1": 0.3396,
    "alpha_0": 4.9810,
    "alpha_1": 8.1100,
    "beta_0": 0.1322,
    "beta_1": 0.3463,
}

TABLE2 = GeneralizedCoefficients.from_paper_units(**TABLE2_PAPER_UNITS)

# Description and SI unit of each coefficient (FMU variables of every isolator implementation).
COEFFICIENT_DOCS: dict[str, tuple[str, str]] = {
    "k0_0": ("N/(m.A)", "stiffness k0 slope per ampere (Table 2 k0^0)"),
    "k0_1": ("N/m", "stiffness k0 at 0 A (Table 2 k0^1)"),
    "c0_0": ("N.s/(m.A)", "damping c0 slope per ampere (Table 2 c0^0)"),
    "c0_1": ("N.s/m", "damping c0 at 0 A (Table 2 c0^1)"),
    "alpha_0": ("N/A", "sinh-spring scale alpha slope per ampere (Table 2 alpha^0)"),
    "alpha_1": ("N", "sinh-spring scale alpha at 0 A (Table 2 alpha^1)"),
    "beta_0": ("1/(m.A)", "sinh-spring shape beta slope per ampere (Table 2 beta^0)"),
    "beta_1": ("1/m", "sinh-spring shape beta at 0 A (Table 2 beta^1)"),
}

# Device limits stated in the paper (section 2): identified on +-8 mm, 15 mm maximum.
IDENTIFIED_RANGE_M = 8.0 * MM
DEVICE_LIMIT_M = 15.0 * MM
CURRENT_MAX_A = 3.0


def isolator_force(
    x: float,
    v: float,
    i: float,
    coeffs: GeneralizedCoefficients = TABLE2,
    F0: float = 0.0,
    n_isolators: int = 2,
) -> float:
    """Total force [N] of ``n_isolators`` identical devices, Eq. (17).

    x [m] and v [m/s] are the isolator displacement and velocity, i [A] the current.
    The force is the restoring force: positive in the direction of x.
    """
    c0 = coeffs.c0_0 * i + coeffs.c0_1
    k0 = coeffs.k0_0 * i + coeffs.k0_1
    alpha = coeffs.alpha_0 * i + coeffs.alpha_1
    beta = coeffs.beta_0 * i + coeffs.beta_1
    return n_isolators * (c0 * v + k0 * x + alpha * safe_sinh(beta * x) + F0)


def isolator_stiffness(
    x: float, i: float, coeffs: GeneralizedCoefficients = TABLE2, n_isolators: int = 2
) -> float:
    """Tangent stiffness dF/dx [N/m] of ``n_isolators`` devices at x [m], i [A]."""
    alpha = coeffs.alpha_0 * i + coeffs.alpha_1
    beta = coeffs.beta_0 * i + coeffs.beta_1
    k0 = coeffs.k0_0 * i + coeffs.k0_1
    return n_isolators * (k0 + alpha * beta * safe_cosh(beta * x))


def force_law(
    coeffs: GeneralizedCoefficients = TABLE2, F0: float = 0.0, n_isolators: int = 2
) -> Callable[[float, float, float], float]:
    """:func:`isolator_force` with the coefficients bound: ``law(x, v, i)`` -> F [N].

    The scalar fast path for a unit that evaluates the force every step: the same
    operations in the same order (so the same numbers, bit for bit), without the
    attribute look-ups and argument passing of the general function.
    """
    c0_0, c0_1, k0_0, k0_1 = coeffs.c0_0, coeffs.c0_1, coeffs.k0_0, coeffs.k0_1
    alpha_0, alpha_1, beta_0, beta_1 = coeffs.alpha_0, coeffs.alpha_1, coeffs.beta_0, coeffs.beta_1
    sinh, copysign, inf = math.sinh, math.copysign, math.inf

    def law(x: float, v: float, i: float) -> float:
        c0 = c0_0 * i + c0_1
        k0 = k0_0 * i + k0_1
        alpha = alpha_0 * i + alpha_1
        z = (beta_0 * i + beta_1) * x
        try:
            s = sinh(z)
        except OverflowError:
            s = copysign(inf, z)
        return n_isolators * (c0 * v + k0 * x + alpha * s + F0)

    return law


# What the law does beyond the identified range (docs/structures.md).
BEYOND_RANGE = ("extrapolate", "tangent", "stop")
# The stop at +-x_limit (a moat wall or the device's own end stop), Kelvin-Voigt contact:
# F_stop = k_stop * penetration + c_stop * penetration rate, never pulling (clipped at 0).
# k_stop: about 100 times the two devices' tangent stiffness at 8 mm and 0 A (~52 kN/m), 13 times the
# Bouc-Wen plant's largest tangent (0.39 MN/m at 3 A) and about 10 times the first storey's 516 kN/m.
# A stop must be stiffer than the device it stops: :func:`device_problem` refuses a k_stop not above the
# device's stiffness beyond x_identified (Table 2's tangent at 8 mm and 3 A is 6.57 MN/m, so the paper's
# law with a stop needs a k_stop set above it). Not stiffer by default because of the coupling: with a
# 1 ms communication step, 50 MN/m made the coupling energy error of a stop contact on El Centro x 0.5
# 1.46 % of the input energy (invalid, tolerance 1 %), 5 MN/m 0.45 %.
# c_stop: the Kelvin pounding model's damping for a coefficient of restitution e = 0.65
# (Anagnostopoulos 1988, Earthq. Eng. Struct. Dyn. 16:443-456), zeta = -ln e / sqrt(pi^2 + ln^2 e)
# = 0.136, on the whole isolated mass (the Dyke building's, 4 x 98.3 kg) against k_stop: c = 2 zeta sqrt(k_stop m).
STOP_STIFFNESS = 5.0e6  # N/m
STOP_RESTITUTION = 0.65
STOP_MASS = sum(DYKE_MASSES, BASE_MASS)  # kg (dyke_building)
_zeta_stop = -math.log(STOP_RESTITUTION) / math.sqrt(math.pi**2 + math.log(STOP_RESTITUTION) ** 2)
STOP_DAMPING = 2.0 * _zeta_stop * math.sqrt(STOP_STIFFNESS * STOP_MASS)  # N*s/m (~1.2e4)


class ParameterError(ValueError):
    """An isolator parameter out of its domain; ``parameter`` is its FMU name (e.g. ``k_stop``)."""

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = parameter
        super().__init__(message)


def bounded_force_law(
    coeffs: GeneralizedCoefficients = TABLE2,
    F0: float = 0.0,
    n_isolators: int = 2,
    beyond_range: str = "extrapolate",
    x_identified: float = IDENTIFIED_RANGE_M,
    x_limit: float = DEVICE_LIMIT_M,
    k_stop: float = STOP_STIFFNESS,
    c_stop: float = STOP_DAMPING,
) -> Callable[[float, float, float], float]:
    """``law(x, v, i)`` -> F [N] with a policy beyond the identified range +-x_identified [m].

    * ``extrapolate``: Eq. (17) everywhere, :func:`force_law` itself (bit for bit).
    * ``tangent``: beyond +-x_identified the spring part continues along its tangent at the
      boundary, F_s(x) = F_s(+-x_id) + K_t(+-x_id) (x -+ x_id), K_t = n (k0 + alpha beta cosh(beta x_id)):
      force continuous and C1 at the boundary; the viscous term n c0 v is unchanged.
    * ``stop``: ``tangent`` plus a stop at +-x_limit [m]: k_stop [N/m] times the penetration plus
      c_stop [N*s/m] times its rate, never pulling (Kelvin contact model of pounding,
      Anagnostopoulos 1988).
    """
    if beyond_range not in BEYOND_RANGE:
        raise ParameterError("beyond_range", f"beyond_range = {beyond_range!r} is not one of "
                             f"{', '.join(map(repr, BEYOND_RANGE))}")
    inner = force_law(coeffs, F0, n_isolators)
    if beyond_range == "extrapolate":
        return inner
    if not (x_identified > 0.0):
        raise ParameterError("x_identified", f"x_identified = {x_identified!r} m must be > 0")
    stop = beyond_range == "stop"
    if stop and not (x_limit > x_identified):
        raise ParameterError("x_limit", f"x_limit = {x_limit!r} m must exceed x_identified = {x_identified!r} m")
    for name, value, unit in (("k_stop", k_stop, "N/m"), ("c_stop", c_stop, "N.s/m")):
        if stop and not (value >= 0.0):
            raise ParameterError(name, f"{name} = {value!r} {unit} must not be negative")
    c0_0, c0_1, k0_0, k0_1 = coeffs.c0_0, coeffs.c0_1, coeffs.k0_0, coeffs.k0_1
    alpha_0, alpha_1, beta_0, beta_1 = coeffs.alpha_0, coeffs.alpha_1, coeffs.beta_0, coeffs.beta_1
    xb = x_identified

    def law(x: float, v: float, i: float) -> float:
        ax = abs(x)
        if ax <= xb:
            return inner(x, v, i)
        c0 = c0_0 * i + c0_1
        k0 = k0_0 * i + k0_1
        alpha = alpha_0 * i + alpha_1
        beta = beta_0 * i + beta_1
        sign = 1.0 if x > 0.0 else -1.0
        edge = sign * xb
        spring = k0 * edge + alpha * safe_sinh(beta * edge) + (k0 + alpha * beta * safe_cosh(beta * xb)) * (x - edge)
        force = n_isolators * (c0 * v + spring + F0)
        if stop and ax > x_limit:
            force += stop_contact(x, v, x_limit, k_stop, c_stop)
        return force

    return law


def stop_contact(x: float, v: float, x_limit: float, k_stop: float, c_stop: float) -> float:
    """Force [N] of the Kelvin stop at +-x_limit [m] (Anagnostopoulos 1988): k_stop [N/m] times the
    penetration plus c_stop [N*s/m] times its rate, in the direction of x, never pulling; 0 inside the limit.
    Every isolator unit's ``stop`` uses it (MreIsolator, BoucWenIsolator)."""
    ax = abs(x)
    if ax <= x_limit:
        return 0.0
    sign = 1.0 if x > 0.0 else -1.0
    contact = k_stop * (ax - x_limit) + c_stop * sign * v
    return sign * contact if contact > 0.0 else 0.0


def parameter_problem(values: Mapping[str, float | int | str]) -> tuple[str, str] | None:
    """(parameter, message) for the first isolator parameter out of its domain, or None.

    ``values`` holds the FMU's parameters by name (the model description's start values overridden
    by a scenario's): the checks :func:`bounded_force_law` and :func:`device_problem` make when the unit
    initializes, before anything runs. Absent names take this module's defaults.
    """
    return _problem(values, device=True)


def value_problem(values: Mapping[str, float | int | str]) -> tuple[str, str] | None:
    """:func:`parameter_problem` without :func:`device_problem`: each value in its own domain only."""
    return _problem(values, device=False)


def _problem(values: Mapping[str, float | int | str], device: bool) -> tuple[str, str] | None:
    try:
        coeffs = GeneralizedCoefficients(**{name: float(values.get(name, getattr(TABLE2, name)))
                                            for name in COEFFICIENT_DOCS})
        bounded_force_law(coeffs, float(values.get("F0", 0.0)), int(values.get("n_isolators", 2)),
                          str(values.get("beyond_range", "extrapolate")),
                          float(values.get("x_identified", IDENTIFIED_RANGE_M)),
                          float(values.get("x_limit", DEVICE_LIMIT_M)), float(values.get("k_stop", STOP_STIFFNESS)),
                          float(values.get("c_stop", STOP_DAMPING)))
        if device:
            device_problem(coeffs, float(values.get("i_max", CURRENT_MAX_A)), int(values.get("n_isolators", 2)),
                           str(values.get("beyond_range", "extrapolate")),
                           float(values.get("x_identified", IDENTIFIED_RANGE_M)),
                           float(values.get("x_limit", DEVICE_LIMIT_M)), float(values.get("k_stop", STOP_STIFFNESS)))
    except ParameterError as exc:
        return exc.parameter, str(exc)
    return None


CURRENT_GRID = 61
"""Currents at which the device checks evaluate a law on [0, i_max] (both ends included)."""


def current_grid(i_max: float) -> list[float]:
    """[0, i_max] A in CURRENT_GRID equal steps (the currents the device checks look at)."""
    return [i_max * k / (CURRENT_GRID - 1) for k in range(CURRENT_GRID)]


def _line_name(prefix: str, coeffs, i: float) -> str:
    """The coefficient of a line p(i) = p_0 i + p_1 to blame for a bad value at i: the value at 0 A if it is
    itself negative (or i = 0), else the slope."""
    return f"{prefix}_1" if i == 0.0 or getattr(coeffs, f"{prefix}_1") < 0.0 else f"{prefix}_0"


def device_problem(coeffs, i_max: float = CURRENT_MAX_A, n_isolators: int = 2, beyond_range: str = "extrapolate",
                   x_identified: float = IDENTIFIED_RANGE_M, x_limit: float = DEVICE_LIMIT_M,
                   k_stop: float = STOP_STIFFNESS) -> None:
    """ParameterError unless the law is a device on [0, i_max] A up to the device limit.

    * The force must rise with displacement: the tangent stiffness n (k0 + alpha beta cosh(beta x)) >= 0 for
      every current of :func:`current_grid` and 0 <= x <= x_limit (with ``tangent``/``stop`` the law beyond
      x_identified has the boundary's tangent, so x <= x_identified). It is monotone in |x|, so x = 0 and the
      largest x decide. The coefficient named is the one that makes it negative.
    * ``stop``: k_stop [N/m] must exceed the device's stiffness beyond x_identified (a stop softer than what it
      stops is no stop).
    """
    if not (math.isfinite(i_max) and i_max >= 0.0):
        raise ParameterError("i_max", f"i_max = {i_max!r} A must be finite and >= 0")
    x_top = x_limit if beyond_range == "extrapolate" else min(x_identified, x_limit)
    stiffest = 0.0
    for i in current_grid(i_max):
        k0 = coeffs.k0_0 * i + coeffs.k0_1
        alpha = coeffs.alpha_0 * i + coeffs.alpha_1
        beta = coeffs.beta_0 * i + coeffs.beta_1
        for x in (0.0, x_top):
            kt = n_isolators * (k0 + alpha * beta * safe_cosh(beta * x))
            if not kt >= 0.0:
                name = (_line_name("k0", coeffs, i) if k0 < 0.0 else
                        _line_name("alpha", coeffs, i) if alpha < 0.0 else _line_name("beta", coeffs, i))
                unit = COEFFICIENT_DOCS[name][0]
                raise ParameterError(name, f"{name} = {getattr(coeffs, name)!r} {unit}: the force does not rise with "
                                     f"displacement (tangent stiffness {kt:.4g} N/m < 0 at x = {x * 1e3:.4g} mm, "
                                     f"i = {i:.4g} A, inside [0, i_max] and the device limit)")
        stiffest = max(stiffest, n_isolators * (k0 + alpha * beta * safe_cosh(beta * x_identified)))
    if beyond_range == "stop" and not k_stop > stiffest:
        raise ParameterError("k_stop", f"k_stop = {k_stop!r} N/m is not stiffer than the device beyond "
                             f"x_identified ({stiffest:.4g} N/m on [0, {i_max:g}] A): a stop must be stiffer "
                             "than what it stops")


# -- the law's other forms, for the controllers' models (lqg_plant_core, sosm_controller_core, sosm_conditions) --
# ``coeffs`` is any object with the coefficients' attributes (GeneralizedCoefficients, or a controller's model of
# the isolator with its own values); ``sinh``/``cosh`` default to the scalar ones above, numpy's serve arrays.


def force_with(x, v, i, coeffs=TABLE2, n_isolators: int = 2, sinh: Callable = safe_sinh):
    """Eq. (17) without offset, ``n_isolators`` devices [N] at x [m], v [m/s], i [A], with the given ``sinh``
    (numpy's, for an array of currents): the same operations in the same order as :func:`isolator_force`."""
    c0 = coeffs.c0_0 * i + coeffs.c0_1
    k0 = coeffs.k0_0 * i + coeffs.k0_1
    alpha = coeffs.alpha_0 * i + coeffs.alpha_1
    beta = coeffs.beta_0 * i + coeffs.beta_1
    return n_isolators * (c0 * v + k0 * x + alpha * sinh(beta * x))


def current_sensitivity(x, v, i, coeffs=TABLE2, n_isolators: int = 2, sinh: Callable = safe_sinh,
                        cosh: Callable = safe_cosh):
    """dF/di [N/A] of ``n_isolators`` devices at x [m], v [m/s], i [A]: the derivative of Eq. (17) in the
    current, the bracket of the paper's Eq. (34) (c0^0 v + k0^0 x + alpha^0 sinh(beta x)
    + alpha(i) beta^0 x cosh(beta x)) times ``n_isolators``."""
    alpha = coeffs.alpha_0 * i + coeffs.alpha_1
    bx = (coeffs.beta_0 * i + coeffs.beta_1) * x
    return n_isolators * (coeffs.c0_0 * v + coeffs.k0_0 * x + coeffs.alpha_0 * sinh(bx)
                          + alpha * coeffs.beta_0 * x * cosh(bx))


def isolator_damping(i: float, coeffs=TABLE2, n_isolators: int = 2) -> float:
    """Viscous coefficient n c0(i) [N*s/m] of ``n_isolators`` devices at current i [A] (Eq. 14)."""
    return n_isolators * (coeffs.c0_0 * i + coeffs.c0_1)


def secant_stiffness(x_lin: float, i: float, coeffs=TABLE2, n_isolators: int = 2) -> float:
    """Spring part of Eq. (17) linearised at i [A]: its secant through the origin at the amplitude x_lin [m]
    [N/m], n (k0(i) + alpha(i) sinh(beta(i) x_lin) / x_lin); x_lin = 0 is the tangent at 0, n (k0 + alpha beta)."""
    alpha = coeffs.alpha_0 * i + coeffs.alpha_1
    beta = coeffs.beta_0 * i + coeffs.beta_1
    spring = alpha * beta if x_lin == 0.0 else alpha * safe_sinh(beta * x_lin) / x_lin
    return n_isolators * (coeffs.k0_0 * i + coeffs.k0_1 + spring)


def device_force(x, v, p: HyperbolicParams, sinh: Callable = safe_sinh):
    """:func:`hyperbolic_force` (one device, Eq. 3-4) [N] with the given ``sinh`` (numpy's, along a motion)."""
    return p.c0 * v + p.k0 * x + p.alpha * sinh(p.beta * x) + p.F0


# This module's source as loaded: several FMUs carry it and share one interpreter (the copy loaded first serves
# them all), and the FMU folder it came from may be gone when another FMU compares it with its own copy.
with open(__file__, "rb") as _source:
    LOADED_SOURCE = _source.read()
