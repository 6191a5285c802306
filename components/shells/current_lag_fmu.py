"""FMI 2.0 co-simulation shell of the coil-current lag (current_lag_core): commanded -> device current.

Input i_cmd [A] (the controller's command), output i [A] (the current in the isolators' coils),
parameter tau [s] (0: no lag; < 0 refused). The output is the unit's state: updated in each step
with the command held over it (exact discretisation), so no direct feedthrough.
"""

from __future__ import annotations

import copy
import math

from current_lag_core import CurrentLag as LagCore
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status

FMU_CORE_MODULES = ("current_lag_core",)
FMU_REQUIREMENTS: tuple[str, ...] = ()  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

UNIT = "CurrentLag"


class CurrentLag(Fmi2Slave):
    """First-order lag tau di/dt = i_cmd - i between the commanded and the device current."""

    description = "First-order lag between the commanded and the device current of the isolators' coils"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self.i_cmd = 0.0
        self.tau = 0.0
        self._lag = None
        self._failed = ""
        self._i = 0.0
        self.fmi_units = {"i_cmd": "A", "i": "A", "tau": "s"}
        self.fmi_dependencies = {}
        self.register_variable(Real("i_cmd", description="commanded current", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("tau", description="time constant of the coil current (0: no lag)",
                                    causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("i", description="device (coil) current", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous, getter=lambda: self._i))

    def exit_initialization_mode(self):
        # Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        try:
            self._lag = LagCore(self.tau, self.i_cmd)  # starts settled at the initial command
            self._i = self._lag.i
        except ValueError as exc:
            self._failed = f"{UNIT}: invalid parameter: {exc}"
            self._i = math.nan
            self.log(self._failed, Fmi2Status.error)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        if not math.isfinite(self.i_cmd):
            self.log(f"{UNIT}: input i_cmd = {self.i_cmd} is not finite at t = {current_time:.6g} s",
                     Fmi2Status.error)
            return False
        self._i = self._lag.step(self.i_cmd, step_size)
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
