"""FMI 2.0 co-simulation shell of the MRE isolator with the Bouc-Wen model (paper Eq. 1-2).

Swappable with MreIsolator: inputs x [m], v [m/s], i [A]; output F [N], the total
restoring force of ``n_isolators`` devices, F = n * (k x + c v + alpha y + F0).

Current dependence (a choice of this project; the paper gives a generalized model only
for the hyperbolic law): k, c, alpha, beta, gamma are linear in the current,
p(i) = p_0 * i + p_1; delta and n are constant. The default coefficients are SYNTHETIC:
fitted by this project's identification pipeline to synthetic data generated from the
paper's Table 1 (components.physics.bouc_wen_core.SYNTHETIC_DEFAULT), not to measurements.

Local variable F_off [N] (recorded when named; `outputs: all` skips it): the force the same
devices would give at 0 A along the same motion (F - F_off is the force the current controls: the
benchmark's J6). The model has memory, so F_off has its own
hysteretic state y_off, advanced every step with the same displacement increment and scheme as y
but with beta(0), gamma(0); F_off = n * (k(0) x + c(0) v + alpha(0) y_off + F0), plus the same stop.
At 0 A throughout, F_off equals F exactly. y_off is advanced only once F_off has been read (a run
that records it reads it at t = 0), so runs that do not ask for it pay nothing.

State: the dimensionless hysteretic variable y (y = 0 at start). ``do_step(t, h)``
advances y from t to t + h with the inputs held (zero-order hold): the displacement
increment is v * h, integrated in the displacement domain by the exponential midpoint
scheme of bouc_wen_core.bouc_wen_advance, in plain floats (``bouc_wen_advance_scalar``; sub-steps of
at most ``dx_max``, and at most 0.5 / lam_max); the current at the start of the step sets beta(i), gamma(i). F read
after the step uses the state y(t + h) and the inputs set at t + h, so F depends on the
inputs (direct feedthrough through k, c, alpha(i)) and on the state.

Range policy as MreIsolator: |x| beyond the identified range and beyond the device
limit each log one fmi2Warning when entered; a current outside [0, i_max] logs an
fmi2Warning when entered and is clipped. Non-finite inputs fail the step with fmi2Error.
The FMU state (fmi2GetFMUstate / fmi2SetFMUstate) holds y with every other attribute.

Beyond the identified range (String parameter ``beyond_range``, as MreIsolator; docs/structures.md):
'stop' (default: the model's own continuation, which adds no stiffening, plus the Kelvin stop of
mre_isolator_core.stop_contact at +-x_limit with k_stop [N/m], c_stop [N.s/m], once on the base),
'extrapolate' or 'tangent' (the same here: Eq. 1-2 everywhere, no stop). Parameters out of their
domain (bouc_wen_core.device_problem: beta + gamma <= 0, a force that does not rise with x, a stop
softer than the device) are logged when initialization ends and fail the first step.
"""

from __future__ import annotations

import copy
import math

import dyke_building
import fast_exchange
import mre_isolator_core
import shared_copies
from bouc_wen_core import (
    BEYOND_RANGE_DEFAULT,
    COEFFICIENT_DOCS,
    SYNTHETIC_DEFAULT,
    BoucWenCurrentModel,
    bouc_wen_advance_scalar,
    device_problem,
)
from fast_exchange import FastExchange
from mre_isolator_core import (
    BEYOND_RANGE,
    CURRENT_MAX_A,
    DEVICE_LIMIT_M,
    IDENTIFIED_RANGE_M,
    STOP_DAMPING,
    STOP_STIFFNESS,
    stop_contact,
)
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

FMU_CORE_MODULES = ("bouc_wen_core", "mre_isolator_core", "dyke_building", "shared_copies", "fast_exchange")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy",)  # besides Python >= 3.11 (bouc_wen_core uses numpy)
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

_COEFFICIENTS = COEFFICIENT_DOCS


class BoucWenIsolator(FastExchange, Fmi2Slave):
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
        self.beyond_range = BEYOND_RANGE_DEFAULT
        self.k_stop = STOP_STIFFNESS
        self.c_stop = STOP_DAMPING
        self._failed = ""
        self.y = 0.0
        self.y_off = 0.0  # y along the same path at 0 A (F_off)
        self._track_off = False  # F_off has been read: advance y_off
        for name, value in SYNTHETIC_DEFAULT.as_dict().items():
            setattr(self, name, value)
        self._outside = {"identified": False, "limit": False, "current": False}

        self.fmi_units = {name: unit for name, (unit, _) in _COEFFICIENTS.items()}
        self.fmi_units.update(
            x="m", v="m/s", i="A", F="N", F0="N", i_max="A", x_identified="m", x_limit="m", dx_max="m", y="1",
            k_stop="N/m", c_stop="N.s/m", F_off="N",
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
        # Added after F, so that the value references of the original variables stay as they were.
        choices = " or ".join(f"'{b}'" for b in BEYOND_RANGE)
        self.register_variable(String("beyond_range", description=f"{choices}: the law beyond x_identified "
                                      "('stop': with the stop at x_limit)", **par))
        self.register_variable(Real("k_stop", description="stiffness of the stop at x_limit ('stop')", **par))
        self.register_variable(Real("c_stop", description="damping of the stop at x_limit ('stop')", **par))
        self.register_variable(Real("F_off", description="the same force at 0 A along the same motion (F - F_off: "
                                    "the controllable force)", causality=Fmi2Causality.local,
                                    variability=Fmi2Variability.continuous, getter=self._force_off))
        # The master exchanges the same value references every step: fast paths for them (fast_exchange).
        self.exchange_fast(inputs=("x", "v", "i"), outputs=("F",))


    def _current(self) -> float:
        return min(max(self.i, 0.0), self.i_max)

    def _force(self) -> float:
        return self._force_at(self._current(), self.y)

    def _force_off(self) -> float:
        self._track_off = True
        return self._force_at(0.0, self.y_off)

    def _force_at(self, i: float, y: float) -> float:
        k = self.k_0 * i + self.k_1
        c = self.c_0 * i + self.c_1
        alpha = self.alpha_0 * i + self.alpha_1
        force = self.n_isolators * (k * self.x + c * self.v + alpha * y + self.F0)
        if self.beyond_range == "stop" and abs(self.x) > self.x_limit:
            force += stop_contact(self.x, self.v, self.x_limit, self.k_stop, self.c_stop)
        return force

    _exchanged_value = _force  # the fast output (fast_exchange)

    def exit_initialization_mode(self):
        # Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        # another FMU's copy of a shared module (the law, the fast paths) with other code: refused (shared_copies)
        self._failed = shared_copies.copy_problem((mre_isolator_core, dyke_building, fast_exchange), self.resources)
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return
        try:
            model = BoucWenCurrentModel(**{name: float(getattr(self, name)) for name in _COEFFICIENTS})
            device_problem(model, self.i_max, self.n_isolators, self.beyond_range, self.x_identified,
                           self.x_limit, self.k_stop, self.c_stop)
        except (ValueError, TypeError) as exc:
            self._failed = f"invalid isolator parameters: {exc}"
            self.log(self._failed, Fmi2Status.error)

    def _warn_on_entry(self, key: str, outside: bool, message: str) -> None:
        if outside and not self._outside[key]:
            self.log(message, Fmi2Status.warning)
        self._outside[key] = outside

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
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
            f"{self.x_identified * 1e3:.3g} mm at t = {t:.6g} s: the model goes on (no stiffening)",
        )
        self._warn_on_entry(
            "limit",
            ax > self.x_limit,
            f"|x| = {ax * 1e3:.3g} mm passed the device limit {self.x_limit * 1e3:.3g} mm at t = {t:.6g} s"
            + (": the stop acts" if self.beyond_range == "stop" else ": no stop (beyond_range is not 'stop')"),
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
            y = bouc_wen_advance_scalar(self.y, dx, beta, gamma, self.delta, self.n, self.dx_max)
            if not math.isfinite(y):
                self.log(f"hysteretic state became {y} at t = {t:.6g} s", Fmi2Status.error)
                return False
            same = i == 0.0 and self.y_off == self.y  # at 0 A on the same state: the same step, not computed twice
            self.y = y
            if not self._track_off:
                return True
            y_off = y if same else bouc_wen_advance_scalar(self.y_off, dx, self.beta_1, self.gamma_1, self.delta,
                                                           self.n, self.dx_max)
            if not math.isfinite(y_off):
                self.log(f"hysteretic state at 0 A (F_off) became {y_off} at t = {t:.6g} s", Fmi2Status.error)
                return False
            self.y_off = y_off
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added
    # (the state y, inputs, parameters, warning flags), deep-copied; pythonfmu's own
    # bookkeeping is left alone. Same pattern as MreIsolator.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
