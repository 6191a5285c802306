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
# k_stop: about 100 times the two devices' tangent stiffness at 8 mm and 0 A (~52 kN/m) and
# about 10 times the first storey's 516 kN/m: a wall far stiffer than the isolation.
# c_stop: the Kelvin pounding model's damping for a coefficient of restitution e = 0.65
# (Anagnostopoulos 1988, Earthq. Eng. Struct. Dyn. 16:443-456), zeta = -ln e / sqrt(pi^2 + ln^2 e)
# = 0.136, on the whole isolated mass (4 x 98.3 kg) against k_stop: c = 2 zeta sqrt(k_stop m).
STOP_STIFFNESS = 5.0e6  # N/m
STOP_RESTITUTION = 0.65
STOP_MASS = 4 * 98.3  # kg
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
            contact = k_stop * (ax - x_limit) + c_stop * sign * v
            if contact > 0.0:
                force += sign * contact
        return force

    return law


def parameter_problem(values: Mapping[str, float | int | str]) -> tuple[str, str] | None:
    """(parameter, message) for the first isolator parameter out of its domain, or None.

    ``values`` holds the FMU's parameters by name (the model description's start values overridden
    by a scenario's): the check :func:`bounded_force_law` makes when the unit initializes, before
    anything runs. Absent names take this module's defaults.
    """
    try:
        coeffs = GeneralizedCoefficients(**{name: float(values.get(name, getattr(TABLE2, name)))
                                            for name in COEFFICIENT_DOCS})
        bounded_force_law(coeffs, float(values.get("F0", 0.0)), int(values.get("n_isolators", 2)),
                          str(values.get("beyond_range", "extrapolate")),
                          float(values.get("x_identified", IDENTIFIED_RANGE_M)),
                          float(values.get("x_limit", DEVICE_LIMIT_M)), float(values.get("k_stop", STOP_STIFFNESS)),
                          float(values.get("c_stop", STOP_DAMPING)))
    except ParameterError as exc:
        return exc.parameter, str(exc)
    return None
