"""FMI 2.0 co-simulation shell of the MRE isolator with the Bouc-Wen model (paper Eq. 1-2).

Swappable with MreIsolator: inputs x [m], v [m/s], i [A]; output F [N], the total
restoring force of ``n_isolators`` devices, F = n * (k x + c v + alpha y + F0).

Current dependence (a choice of this project; the paper gives a generalized model only
for the hyperbolic law): k, c, alpha, beta, gamma are linear in the current,
p(i) = p_0 * i + p_1; delta and n are constant. The default coefficients are SYNTHETIC:
fitted by this project's identification pipeline to synthetic data generated from the
paper's Table 1 (components.physics.bouc_wen_core.SYNTHETIC_DEFAULT), not to measurements.

State: the dimensionless hysteretic variable y (y = 0 at start). ``do_step(t, h)``
advances y from t to t + h with the inputs held (zero-order hold): the displacement
increment is v * h, integrated in the displacement domain by the exponential midpoint
scheme of bouc_wen_core.bouc_wen_advance (sub-steps of at most ``dx_max``, and at most
0.5 / lam_max); the current at the start of the step sets beta(i), gamma(i). F read
after the step uses the state y(t + h) and the inputs set at t + h, so F depends on the
inputs (direct feedthrough through k, c, alpha(i)) and on the state.

Range policy as MreIsolator: |x| beyond the identified range and beyond the device
limit each log one fmi2Warning when entered; a current outside [0, i_max] logs an
fmi2Warning when entered and is clipped. Non-finite inputs fail the step with fmi2Error.
The FMU state (fmi2GetFMUstate / fmi2SetFMUstate) holds y with every other attribute.
"""

from __future__ import annotations

import copy
import math

from bouc_wen_core import SYNTHETIC_DEFAULT, bouc_wen_advance
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

FMU_CORE_MODULES = ("bouc_wen_core",)
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy",)  # besides Python >= 3.11 (bouc_wen_core uses numpy)
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

CURRENT_MAX_A = 3.0
IDENTIFIED_RANGE_M = 8e-3
DEVICE_LIMIT_M = 15e-3

_COEFFICIENTS = {
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


class BoucWenIsolator(Fmi2Slave):
    """MRE base isolator, current-dependent Bouc-Wen model (SI units), with state y."""

    description = "MRE base isolator, Bouc-Wen: F = n*(k(i) x + c(i) v + alpha(i) y + F0), y from Eq. (2)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self.x = 0.0
        self.v = 0.0
        self.i = 0.0
        self.F0 = 0.0
        self.n_isolators = 2
        self.i_max = CURRENT_MAX_A
        self.x_identified = IDENTIFIED_RANGE_M
        self.x_limit = DEVICE_LIMIT_M
        self.dx_max = 2e-5
        self.y = 0.0
        for name, value in SYNTHETIC_DEFAULT.as_dict().items():
            setattr(self, name, value)
        self._outside = {"identified": False, "limit": False, "current": False}

        self.fmi_units = {name: unit for name, (unit, _) in _COEFFICIENTS.items()}
        self.fmi_units.update(
            x="m", v="m/s", i="A", F="N", F0="N", i_max="A", x_identified="m", x_limit="m", dx_max="m", y="1"
        )
        self.fmi_dependencies = {"F": ("x", "v", "i")}

        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        self.register_variable(Real("x", description="isolator displacement", **inp))
        self.register_variable(Real("v", description="isolator velocity", **inp))
        self.register_variable(Real("i", description="commanded current", **inp))
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        for name, (_, text) in _COEFFICIENTS.items():
            self.register_variable(Real(name, description=text, **par))
        self.register_variable(Real("F0", description="force offset per device", **par))
        self.register_variable(
            Integer("n_isolators", description="number of identical devices in parallel", **par)
        )
        self.register_variable(Real("i_max", description="largest admissible current", **par))
        self.register_variable(
            Real("x_identified", description="displacement range the model was identified on", **par)
        )
        self.register_variable(Real("x_limit", description="device displacement limit", **par))
        self.register_variable(
            Real("dx_max", description="largest displacement sub-step of the y integrator", **par)
        )
        self.register_variable(
            Real(
                "y",
                description="hysteretic state (dimensionless)",
                causality=Fmi2Causality.local,
                variability=Fmi2Variability.continuous,
            )
        )
        self.register_variable(
            Real(
                "F",
                description="total isolator restoring force (acts on the base against x)",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous,
                getter=self._force,
            )
        )

    def _current(self) -> float:
        return min(max(self.i, 0.0), self.i_max)

    def _force(self) -> float:
        i = self._current()
        k = self.k_0 * i + self.k_1
        c = self.c_0 * i + self.c_1
        alpha = self.alpha_0 * i + self.alpha_1
        return self.n_isolators * (k * self.x + c * self.v + alpha * self.y + self.F0)

    def _warn_on_entry(self, key: str, outside: bool, message: str) -> None:
        if outside and not self._outside[key]:
            self.log(message, Fmi2Status.warning)
        self._outside[key] = outside

    def do_step(self, current_time: float, step_size: float) -> bool:
        for name in ("x", "v", "i"):
            value = getattr(self, name)
            if not math.isfinite(value):
                self.log(
                    f"input {name} = {value} is not finite at t = {current_time:.6g} s", Fmi2Status.error
                )
                return False
        t = current_time
        ax = abs(self.x)
        self._warn_on_entry(
            "identified",
            ax > self.x_identified,
            f"|x| = {ax * 1e3:.3g} mm left the identified range "
            f"{self.x_identified * 1e3:.3g} mm at t = {t:.6g} s: the model is extrapolated",
        )
        self._warn_on_entry(
            "limit",
            ax > self.x_limit,
            f"|x| = {ax * 1e3:.3g} mm passed the device limit {self.x_limit * 1e3:.3g} mm at t = {t:.6g} s",
        )
        self._warn_on_entry(
            "current",
            not 0.0 <= self.i <= self.i_max,
            f"current i = {self.i:.4g} A left [0, {self.i_max:.4g}] A at t = {t:.6g} s: clipped",
        )
        i = self._current()
        beta = self.beta_0 * i + self.beta_1
        gamma = self.gamma_0 * i + self.gamma_1
        dx = self.v * step_size
        if dx != 0.0:
            y = float(bouc_wen_advance(self.y, dx, beta, gamma, self.delta, self.n, self.dx_max))
            if not math.isfinite(y):
                self.log(f"hysteretic state became {y} at t = {t:.6g} s", Fmi2Status.error)
                return False
            self.y = y
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added
    # (the state y, inputs, parameters, warning flags), deep-copied; pythonfmu's own
    # bookkeeping is left alone. Same pattern as MreIsolator.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
