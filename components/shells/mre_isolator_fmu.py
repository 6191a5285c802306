"""FMI 2.0 co-simulation shell of the MRE isolator (generalized hyperbolic model, Eq. 17).

Inputs x [m], v [m/s], i [A]; output F [N], the total restoring force of
``n_isolators`` devices. F is direct feedthrough: it is evaluated from the inputs set
at the current communication point whenever it is read. The unit has no state. Local variable
F_off [N] (recorded when a scenario names it; not an output, so `outputs: all` skips it): the
force the same devices give at 0 A at the same x and v (F - F_off is the force the current
controls: the benchmark's J6).

Range policy: |x| beyond the identified +-8 mm range and beyond the device's 15 mm
limit each log one fmi2Warning when entered; a current outside [0, i_max] logs an
fmi2Warning when entered and is clipped to [0, i_max] before it enters the law.
Non-finite inputs make ``fmi2DoStep`` fail with fmi2Error and a logged message.

Beyond the identified range (String parameter ``beyond_range``, docs/structures.md):
'extrapolate' (default, Eq. 17 everywhere, as before), 'tangent' (the spring continues along
its tangent at +-x_identified, C1) or 'stop' ('tangent' plus a Kelvin stop at +-x_limit with
k_stop [N/m] and c_stop [N.s/m], acting once on the base, not per device).
"""

from __future__ import annotations

import copy
import math

import dyke_building
import fast_exchange
import mre_isolator_core
import shared_copies
from fast_exchange import FastExchange
from mre_isolator_core import (
    BEYOND_RANGE,
    COEFFICIENT_DOCS,
    CURRENT_MAX_A,
    DEVICE_LIMIT_M,
    IDENTIFIED_RANGE_M,
    STOP_DAMPING,
    STOP_STIFFNESS,
    TABLE2,
    GeneralizedCoefficients,
    bounded_force_law,
    device_problem,
)
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

FMU_CORE_MODULES = ("mre_isolator_core", "dyke_building", "shared_copies", "fast_exchange")
FMU_REQUIREMENTS: tuple[str, ...] = ()  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

_COEFFICIENTS = COEFFICIENT_DOCS


class MreIsolator(FastExchange, Fmi2Slave):
    """MRE base isolator, generalized current-dependent hyperbolic model (SI units)."""

    description = "MRE base isolator: F = n*(c0(i) v + k0(i) x + alpha(i) sinh(beta(i) x) + F0)"

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
        self.beyond_range = "extrapolate"
        self.k_stop = STOP_STIFFNESS
        self.c_stop = STOP_DAMPING
        self._failed = ""
        for name, value in TABLE2.as_dict().items():
            setattr(self, name, value)
        self._outside = {"identified": False, "limit": False, "current": False}
        self._coeffs: GeneralizedCoefficients | None = None
        self._initialized = False
        self._law = None  # force_law(...) once the parameters are fixed (after initialization)

        self.fmi_units = {name: unit for name, (unit, _) in _COEFFICIENTS.items()}
        self.fmi_units.update(
            x="m", v="m/s", i="A", F="N", F0="N", i_max="A", x_identified="m", x_limit="m", k_stop="N/m",
            c_stop="N.s/m", F_off="N",
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
        self.register_variable(String("beyond_range", description=f"{choices}: the law beyond x_identified", **par))
        self.register_variable(Real("k_stop", description="stiffness of the stop at x_limit ('stop')", **par))
        self.register_variable(Real("c_stop", description="damping of the stop at x_limit ('stop')", **par))
        self.register_variable(Real("F_off", description="the same force at 0 A (F - F_off: the controllable force)",
                                    causality=Fmi2Causality.local, variability=Fmi2Variability.continuous,
                                    getter=self._force_off))
        # The master exchanges the same value references every step: fast paths for them (fast_exchange).
        self.exchange_fast(inputs=("x", "v", "i"), outputs=("F",))

    def _current(self) -> float:
        return min(max(self.i, 0.0), self.i_max)

    def _coefficients(self) -> GeneralizedCoefficients:
        # Parameters may change until initialization ends; afterwards they are fixed.
        if self._coeffs is None or not self._initialized:
            self._coeffs = GeneralizedCoefficients(**{name: getattr(self, name) for name in _COEFFICIENTS})
        return self._coeffs

    def _make_law(self):
        return bounded_force_law(self._coefficients(), self.F0, self.n_isolators, self.beyond_range,
                                 self.x_identified, self.x_limit, self.k_stop, self.c_stop)

    def _force(self) -> float:
        if self._law is not None:
            return self._law(self.x, self.v, min(max(self.i, 0.0), self.i_max))
        return self._force_at(self._current())

    def _force_at(self, i: float) -> float:
        if self._law is not None:
            return self._law(self.x, self.v, i)
        if self._failed:
            return math.nan
        try:
            return self._make_law()(self.x, self.v, i)
        except ValueError:
            return math.nan  # reported when initialization ends

    def _force_off(self) -> float:
        return self._force_at(0.0)

    _exchanged_value = _force  # the fast output (fast_exchange)

    def exit_initialization_mode(self):
        # Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        self._initialized = False
        self._law = None
        self._failed = shared_copies.copy_problem((mre_isolator_core, dyke_building, fast_exchange), self.resources)
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return
        try:
            law = self._make_law()
            device_problem(self._coefficients(), self.i_max, self.n_isolators, self.beyond_range, self.x_identified,
                           self.x_limit, self.k_stop)
        except ValueError as exc:
            self._failed = f"invalid isolator parameters: {exc}"
            self.log(self._failed, Fmi2Status.error)
            return
        self._initialized = True
        self._law = law


    def _beyond_text(self) -> str:
        if self.beyond_range == "extrapolate":
            return "the model is extrapolated"
        return "the law continues along its tangent at the boundary"

    def _entered(self, key: str, outside: bool) -> bool:
        """True when a range is left now (it was inside at the previous step)."""
        entered = outside and not self._outside[key]
        self._outside[key] = outside
        return entered

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        x, v, i = self.x, self.v, self.i
        if not (math.isfinite(x) and math.isfinite(v) and math.isfinite(i)):
            name, value = next((n, val) for n, val in (("x", x), ("v", v), ("i", i)) if not math.isfinite(val))
            self.log(f"input {name} = {value} is not finite at t = {current_time:.6g} s", Fmi2Status.error)
            return False
        t = current_time
        ax = abs(x)
        outside = self._outside
        identified, limit, current = ax > self.x_identified, ax > self.x_limit, not 0.0 <= i <= self.i_max
        if identified == outside["identified"] and limit == outside["limit"] and current == outside["current"]:
            return True  # no range entered or left: nothing to say (the usual step)
        if self._entered("identified", identified):
            self.log(f"|x| = {ax * 1e3:.3g} mm left the identified range {self.x_identified * 1e3:.3g} mm "
                     f"at t = {t:.6g} s: {self._beyond_text()}", Fmi2Status.warning)
        if self._entered("limit", limit):
            self.log(f"|x| = {ax * 1e3:.3g} mm passed the device limit {self.x_limit * 1e3:.3g} mm at t = {t:.6g} s",
                     Fmi2Status.warning)
        if self._entered("current", current):
            self.log(f"current i = {i:.4g} A left [0, {self.i_max:.4g}] A at t = {t:.6g} s: clipped",
                     Fmi2Status.warning)
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added,
    # registered or not, deep-copied; pythonfmu's own bookkeeping is left alone.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
