"""FMI 2.0 co-simulation shell of the on-off (switching-stiffness) current law.

Inputs x [m], v [m/s] and a [m/s^2] (a is unused; it is there so that the unit drops in
for the SOSM controller with the same connections). Output i [A], a state of the unit:
set in each step from the inputs at the step's start, so no direct feedthrough.
"""

from __future__ import annotations

import copy
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status
from switching_controller_core import SwitchingLaw

FMU_CORE_MODULES = ("switching_controller_core",)
FMU_REQUIREMENTS: tuple[str, ...] = ()  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error


class SwitchingCurrentController(Fmi2Slave):
    """On-off current: i_high while the base moves away from its centre, i_low otherwise."""

    description = "Lyapunov-based on-off (switching-stiffness) current law of the MRE isolator"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self.x = 0.0
        self.v = 0.0
        self.a = 0.0
        self.i_high = 3.0
        self.i_low = 0.0
        self.i_max = 3.0
        self._law: SwitchingLaw | None = None
        self._failed = ""
        self._i = 0.0
        self.fmi_units = {"x": "m", "v": "m/s", "a": "m/s2", "i": "A", "i_high": "A", "i_low": "A", "i_max": "A"}
        self.fmi_dependencies = {}
        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register_variable(Real("x", description="base displacement relative to the ground", **inp))
        self.register_variable(Real("v", description="base velocity relative to the ground", **inp))
        self.register_variable(Real("a", description="base relative acceleration (unused)", **inp))
        self.register_variable(Real("i_high", description="current while the base moves away from 0", **par))
        self.register_variable(Real("i_low", description="current while the base returns", **par))
        self.register_variable(Real("i_max", description="largest current", **par))
        self.register_variable(Real("i", description="command current", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.discrete, getter=lambda: self._i))

    def exit_initialization_mode(self):
        # A problem is logged and fails the first step: an exception here would be fmi2Fatal.
        try:
            self._law = SwitchingLaw(self.i_high, self.i_low, self.i_max)
            self._i = self._law.current(self.x, self.v)
        except ValueError as exc:
            self._failed = f"invalid parameters: {exc}"
            self._i = math.nan
            self.log(self._failed, Fmi2Status.error)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        if not (math.isfinite(self.x) and math.isfinite(self.v)):
            self.log(f"input x = {self.x} or v = {self.v} is not finite at t = {current_time:.6g} s", Fmi2Status.error)
            return False
        self._i = self._law.current(self.x, self.v)
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
