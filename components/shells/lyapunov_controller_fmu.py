"""FMI 2.0 co-simulation shell of the Lyapunov current controller (after Jansen and Dyke 2000).

Inputs: base displacement x [m] and velocity v [m/s] relative to the ground, absolute
floor accelerations a_0 (base) .. a_3 [m/s^2], isolator restoring force F [N].
Outputs: command current i [A] in {0, i_max} and the switching function [1]
z'PB (f(i_max) - f(0)) (i_max where it is negative); set in each step from the inputs at
the step's start (a state of the unit: no direct feedthrough). P (Lyapunov equation) and
the Kalman gain are computed with scipy at initialization (lyapunov_controller_core,
lqg_plant_core).
"""

from __future__ import annotations

import copy
import math
import sys

from pythonfmu import Fmi2Slave, Real

try:
    import lqg_plant_core as plant_core
    import model_based_shell as shared
    from lqg_plant_core import NoiseIntensities
    from lyapunov_controller_core import LyapunovController, LyapunovDesign, controller_parts, lyapunov_weights
except ImportError as exc:  # the host's Python lacks a package: say which (the build's logging shim shows it)
    raise ImportError(f"the LyapunovCurrentController unit needs the Python packages numpy and scipy in the "
                      f"host's interpreter ({sys.executable}): {exc}") from exc

FMU_CORE_MODULES = ("lqg_plant_core", "mre_isolator_core", "dyke_building", "shared_copies",
                    "model_based_shell", "lyapunov_controller_core")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy", "scipy")  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

UNIT = "LyapunovCurrentController"
# Q of the Lyapunov equation: the weighted squared responses (no control weight)
_Q_DOCS = {name: (unit, f"Lyapunov Q: {text}") for name, (unit, text) in plant_core.WEIGHT_DOCS.items() if name != "r"}
_DESIGN = {
    "i_max": ("A", "largest current i_max"),
    "x_lin": ("m", "amplitude of the secant linearisation of the sinh spring at 0 A (0: tangent at 0)"),
}
_OUTPUTS = ("_i", "_switch")


class LyapunovCurrentController(Fmi2Slave):
    """Bang-bang current that makes the Lyapunov function's rate smaller (Q-weighted, passive-off P)."""

    description = "Lyapunov current controller of the MRE isolators (after Jansen and Dyke 2000)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        shared.set_sensor_defaults(self)
        shared.set_model_defaults(self, ((_DESIGN, LyapunovDesign()), (_Q_DOCS, lyapunov_weights()),
                                         (plant_core.NOISE_DOCS, NoiseIntensities())))
        self._controller: LyapunovController | None = None
        self._failed = ""
        self._i = 0.0
        self._switch = 0.0

        # switch = z'PB (f(i_max) - f(0)): the change of dV/dt from 0 A to i_max; V = 1/2 z'Pz is in seconds
        # (the weights make the cost integrand dimensionless), so dV/dt and the switch are pure numbers
        self.fmi_units = {"i": "A", "switch": "1"}
        self.fmi_dependencies = {}
        shared.register_sensors(self)
        shared.register_model_parameters(self, _DESIGN, _Q_DOCS, plant_core.NOISE_DOCS)
        self.register_variable(Real("i", description="command current", getter=lambda: self._i, **shared.HELD_OUTPUT))
        self.register_variable(Real("switch", description="z'PB (f(i_max) - f(0)), the change of dV/dt from 0 A "
                                    "to i_max: i_max where negative (P from the passive-off Lyapunov equation, "
                                    "z the Kalman estimate)",
                                    getter=lambda: self._switch, **shared.OUTPUT))

    def exit_initialization_mode(self):
        if not shared.start_controller(self, UNIT, LyapunovController, controller_parts, _OUTPUTS):
            return
        c = self._controller
        if all(math.isfinite(u) for u in (self.x, self.v)):
            self._i = c.current(c.estimator.z, self.x, self.v)
            self._switch = c.switch

    def do_step(self, current_time: float, step_size: float) -> bool:
        if not shared.step_estimated(self, UNIT, current_time, step_size, _OUTPUTS):
            return False
        self._switch = self._controller.switch
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
