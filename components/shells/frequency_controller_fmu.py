"""FMI 2.0 co-simulation shell of the frequency current controller (after Gu et al. 2015).

Input: ground acceleration ag [m/s^2], sampled at each communication point. Outputs:
command current i [A], the dominant frequency of the ground acceleration over the last
window f_dominant [Hz] (0 until the first window has filled) and the isolated structure's
first natural frequency at the commanded current f_structure [Hz] (linearised model). All
are set in each step from the input at the step's start (no direct feedthrough). The
window and the update interval are counted in communication steps (see
frequency_controller_core for the method).
"""

from __future__ import annotations

import copy
import math
import sys

from pythonfmu import Fmi2Slave, Integer, Real
from pythonfmu.enums import Fmi2Status

try:
    import model_based_shell as shared
    from frequency_controller_core import FrequencyController, FrequencyDesign, controller_parts
except ImportError as exc:  # the host's Python lacks a package: say which (the build's logging shim shows it)
    raise ImportError(f"the FrequencyCurrentController unit needs the Python packages numpy and scipy in the "
                      f"host's interpreter ({sys.executable}): {exc}") from exc

FMU_CORE_MODULES = ("lqg_plant_core", "mre_isolator_core", "dyke_building", "shared_copies",
                    "model_based_shell", "frequency_controller_core")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy", "scipy")  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

UNIT = "FrequencyCurrentController"
_REALS = {
    "i_max": ("A", "largest current i_max"),
    "i_start": ("A", "current held until the first window has filled"),
    "f_lo": ("Hz", "lowest frequency searched for the ground's dominant frequency"),
    "f_hi": ("Hz", "highest frequency searched for the ground's dominant frequency"),
    "x_lin": ("m", "amplitude of the secant linearisation of the sinh spring (0: tangent at 0)"),
}
_INTEGERS = {
    "window": "moving window of the ground acceleration, in communication steps (>= 2)",
    "update_every": "steps between two estimates of the dominant frequency (>= 1)",
    "n_grid": "currents of the grid on which the natural frequency is precomputed (>= 2)",
}
_OUTPUTS = ("_i", "_f_dominant", "_f_structure")


class FrequencyCurrentController(Fmi2Slave):
    """Current that keeps the first natural frequency away from the ground motion's dominant frequency."""

    description = "Frequency current controller of the MRE isolators (after Gu et al. 2015)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        design = FrequencyDesign()
        self.ag = 0.0
        shared.set_model_defaults(self, (({**_REALS, **_INTEGERS}, design),))
        self._controller: FrequencyController | None = None
        self._failed = ""
        self._i = design.i_start
        self._f_dominant = 0.0
        self._f_structure = 0.0

        self.fmi_units = {"ag": "m/s2", "i": "A", "f_dominant": "Hz", "f_structure": "Hz"}
        self.fmi_dependencies = {}
        self.register_variable(Real("ag", description="ground acceleration", **shared.INPUT))
        for name, text in _INTEGERS.items():
            self.register_variable(Integer(name, description=text, **shared.PARAMETER))
        shared.register_model_parameters(self, _REALS)
        self.register_variable(Real("i", description="command current", getter=lambda: self._i, **shared.HELD_OUTPUT))
        self.register_variable(Real("f_dominant", description="dominant frequency of the ground acceleration over "
                                    "the last window (0 before the first window has filled)",
                                    getter=lambda: self._f_dominant, **shared.OUTPUT))
        self.register_variable(Real("f_structure", description="first natural frequency of the isolated structure "
                                    "at the commanded current (linearised model)",
                                    getter=lambda: self._f_structure, **shared.OUTPUT))

    def exit_initialization_mode(self):
        if not shared.start_controller(self, UNIT, FrequencyController, controller_parts, _OUTPUTS):
            return
        self._i = self._controller.i
        self._f_structure = self._controller.f_structure

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        if not math.isfinite(self.ag):
            self.log(f"{UNIT}: input ag = {self.ag} is not finite at t = {current_time:.6g} s", Fmi2Status.error)
            return False
        c = self._controller
        self._i = c.update(self.ag, step_size)
        if math.isfinite(c.f_dominant):
            self._f_dominant = c.f_dominant
        self._f_structure = c.f_structure
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
