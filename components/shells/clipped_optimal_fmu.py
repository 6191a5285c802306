"""FMI 2.0 co-simulation shell of the clipped-optimal current controller (Dyke et al. 1996).

Inputs: base displacement x [m] and velocity v [m/s] relative to the ground, absolute
floor accelerations a_0 (base) .. a_3 [m/s^2], isolator restoring force F [N].
Outputs: command current i [A] and the desired isolator force f_c [N]; both set in each
step from the inputs at the step's start (a state of the unit: no direct feedthrough).
``law`` selects the current law: "clipped" (Dyke's clipping) or "inverse" (the current
whose Eq. 17 force is closest to f_c). The LQR and Kalman gains are computed with scipy
at initialization (see clipped_optimal_core and lqg_plant_core).
"""

from __future__ import annotations

import copy
import math
import sys

from pythonfmu import Fmi2Slave, Integer, Real, String

try:
    import lqg_plant_core as plant_core
    import model_based_shell as shared
    from clipped_optimal_core import ClippedOptimalController, ClippedOptimalDesign, controller_parts
    from lqg_plant_core import NoiseIntensities, Weights
except ImportError as exc:  # the host's Python lacks a package: say which (the build's logging shim shows it)
    raise ImportError(f"the ClippedOptimalCurrentController unit needs the Python packages numpy and scipy in the "
                      f"host's interpreter ({sys.executable}): {exc}") from exc

FMU_CORE_MODULES = ("lqg_plant_core", "mre_isolator_core", "dyke_building", "shared_copies",
                    "model_based_shell", "clipped_optimal_core")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy", "scipy")  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

UNIT = "ClippedOptimalCurrentController"
_DESIGN = {
    "i_max": ("A", "largest current i_max"),
    "i_nom": ("A", "nominal current of the isolators in the linearised design plant"),
    "x_lin": ("m", "amplitude of the secant linearisation of the sinh spring (0: tangent at 0)"),
}
_OUTPUTS = ("_i", "_f_c")


class ClippedOptimalCurrentController(Fmi2Slave):
    """LQG desired isolator force, turned into a current by Dyke's clipping or by the inverse model."""

    description = "Clipped-optimal (LQG) current controller of the MRE isolators (Dyke et al. 1996)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        design = ClippedOptimalDesign()
        shared.set_sensor_defaults(self)
        self.law = design.law
        self.n_grid = design.n_grid
        shared.set_model_defaults(self, ((_DESIGN, design), (plant_core.WEIGHT_DOCS, Weights()),
                                         (plant_core.NOISE_DOCS, NoiseIntensities())))
        self._controller: ClippedOptimalController | None = None
        self._failed = ""
        self._i = 0.0
        self._f_c = 0.0

        self.fmi_units = {"i": "A", "f_c": "N"}
        self.fmi_dependencies = {}
        shared.register_sensors(self)
        self.register_variable(String("law", description="current law: 'clipped' (Dyke) or 'inverse' (Eq. 17)",
                                      **shared.PARAMETER))
        self.register_variable(Integer("n_grid", description="inverse law: currents in the search grid",
                                       **shared.PARAMETER))
        shared.register_model_parameters(self, _DESIGN, plant_core.WEIGHT_DOCS, plant_core.NOISE_DOCS)
        self.register_variable(Real("i", description="command current", getter=lambda: self._i, **shared.HELD_OUTPUT))
        self.register_variable(Real("f_c", description="desired isolator restoring force (LQG)",
                                    getter=lambda: self._f_c, **shared.OUTPUT))

    def exit_initialization_mode(self):
        if not shared.start_controller(self, UNIT, ClippedOptimalController, controller_parts, _OUTPUTS):
            return
        c = self._controller
        self._f_c = c.desired_force(c.estimator.z)
        if all(math.isfinite(u) for u in (self.x, self.v, self.F)):
            self._i = c.current(self._f_c, self.x, self.v, self.F)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if not shared.step_estimated(self, UNIT, current_time, step_size, _OUTPUTS):
            return False
        self._f_c = self._controller.f_c
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
