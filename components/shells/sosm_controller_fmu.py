"""FMI 2.0 co-simulation shell of the SOSM current controller (and its passive mode).

Inputs: base displacement x [m], velocity v [m/s] and relative acceleration a [m/s^2].
Output: command current i [A], a state of the unit (integrated over each step), so it
has no direct feedthrough. ``mode = "passive"`` holds i = clip(i_passive, 0, i_max).
"""

from __future__ import annotations

import copy
import math

import dyke_building
import fast_exchange
import mre_isolator_core
import shared_copies
from fast_exchange import FastExchange
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status
from sosm_controller_core import IsolatorModel, SosmController, SosmGains

FMU_CORE_MODULES = ("sosm_controller_core", "mre_isolator_core", "dyke_building", "shared_copies", "fast_exchange")
FMU_REQUIREMENTS: tuple[str, ...] = ()  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

_GAINS = {
    "lambda": ("lam", "1/s", "sliding-surface slope lambda"),
    "rho": ("rho", "A/s", "largest current rate rho"),
    "zeta": ("zeta", "A.s0.5/m0.5", "quasi-continuous gain zeta"),
    "theta": ("theta", "m0.5/s1.5", "parabola gain theta (the paper's vartheta)"),
    "i_max": ("i_max", "A", "largest current i_M"),
    # not in the paper: while |s| < s_release the current is released toward 0 at rate rho (0: the paper's law)
    "s_release": ("s_release", "m/s", "release band on |s| (designer's extension, not in the paper; 0 = off)"),
}
# The controller's model of the isolator, used for the sign of Psi (Eq. 34).
_MODEL = {
    "c0_0": "N.s/(m.A)",
    "k0_0": "N/(m.A)",
    "alpha_0": "N/A",
    "alpha_1": "N",
    "beta_0": "1/(m.A)",
    "beta_1": "1/m",
}
MODES = ("sosm", "passive")


class SosmCurrentController(FastExchange, Fmi2Slave):
    """SOSM controller commanding the isolator current; passive mode holds a constant current."""

    description = "Second-order sliding-mode controller of the MRE isolator current (Eq. 27-39)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        defaults = SosmGains()
        self.x = 0.0
        self.v = 0.0
        self.a = 0.0
        self.mode = "sosm"
        self.i_passive = 0.0
        self.i_start = 0.0
        for fmi_name, (attr, _, _) in _GAINS.items():
            setattr(self, fmi_name, getattr(defaults, attr))
        for name in _MODEL:
            setattr(self, name, getattr(IsolatorModel(), name))
        self._controller: SosmController | None = None
        self._failed = ""

        self.fmi_units = {"x": "m", "v": "m/s", "a": "m/s2", "i": "A", "i_passive": "A", "i_start": "A"}
        self.fmi_dependencies = {}
        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register_variable(Real("x", description="base displacement relative to the ground", **inp))
        self.register_variable(Real("v", description="base velocity relative to the ground", **inp))
        self.register_variable(Real("a", description="base acceleration relative to the ground", **inp))
        for fmi_name, (_, unit, text) in _GAINS.items():
            self.register_variable(Real(fmi_name, description=text, **par))
            self.fmi_units[fmi_name] = unit
        for name, unit in _MODEL.items():
            self.register_variable(Real(name, description=f"isolator model coefficient {name}", **par))
            self.fmi_units[name] = unit
        self.register_variable(String("mode", description="'sosm' or 'passive' (constant current)", **par))
        self.register_variable(Real("i_passive", description="current held in passive mode", **par))
        self.register_variable(Real("i_start", description="current at the start (sosm mode)", **par))
        self.register_variable(
            Real(
                "i",
                description="command current",
                causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous,
                getter=self._current,
            )
        )
        # The master exchanges the same value references every step: fast paths for them (fast_exchange).
        self.exchange_fast(inputs=("x", "v", "a"), outputs=("i",))

    def _make_controller(self) -> SosmController:
        gains = SosmGains(**{attr: getattr(self, fmi_name) for fmi_name, (attr, _, _) in _GAINS.items()})
        model = IsolatorModel(**{name: getattr(self, name) for name in _MODEL})
        return SosmController(gains, model, i0=self.i_start)

    def _current(self) -> float:
        if self._failed:
            return math.nan
        if self.mode == "passive":
            return min(max(self.i_passive, 0.0), self.i_max)
        if self._controller is None:
            return min(max(self.i_start, 0.0), self.i_max)
        return self._controller.i

    _exchanged_value = _current  # the fast output (fast_exchange)

    def exit_initialization_mode(self):
        # Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        self._failed = shared_copies.copy_problem((mre_isolator_core, dyke_building, fast_exchange), self.resources)
        if not self._failed and self.mode not in MODES:
            self._failed = f"parameter mode = {self.mode!r} is not one of {MODES}"
        elif not self._failed:
            try:
                self._controller = self._make_controller()
            except ValueError as exc:
                self._failed = f"invalid controller parameters: {exc}"
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
        elif self.mode == "passive" and not 0.0 <= self.i_passive <= self.i_max:
            self.log(f"i_passive = {self.i_passive:g} A is outside [0, i_max = {self.i_max:g} A]: the current is held "
                     f"at {self._current():g} A", Fmi2Status.warning)


    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        x, v, a = self.x, self.v, self.a
        if not (math.isfinite(x) and math.isfinite(v) and math.isfinite(a)):
            self.log(
                f"input x = {x}, v = {v} or a = {a} is not finite at t = {current_time:.6g} s",
                Fmi2Status.error,
            )
            return False
        if self.mode == "sosm":
            self._controller.update(x, v, a, step_size)
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added,
    # registered or not, deep-copied; pythonfmu's own bookkeeping is left alone.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
