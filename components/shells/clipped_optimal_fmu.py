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

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

try:
    import lqg_plant_core as plant_core
    from clipped_optimal_core import ClippedOptimalController, ClippedOptimalDesign, controller_parts
    from lqg_plant_core import EstimatorDiverged, IsolatorLaw, NoiseIntensities, Weights
except ImportError as exc:  # the host's Python lacks a package: say which (the build's logging shim shows it)
    raise ImportError(f"the ClippedOptimalCurrentController unit needs the Python packages numpy and scipy in the "
                      f"host's interpreter ({sys.executable}): {exc}") from exc

FMU_CORE_MODULES = ("lqg_plant_core", "clipped_optimal_core")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy", "scipy")  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error

UNIT = "ClippedOptimalCurrentController"
N_LEVELS = 4  # base floor and three storeys (the paper's building)
_DESIGN = {
    "i_max": ("A", "largest current i_max"),
    "i_nom": ("A", "nominal current of the isolators in the linearised design plant"),
    "x_lin": ("m", "amplitude of the secant linearisation of the sinh spring (0: tangent at 0)"),
}


class ClippedOptimalCurrentController(Fmi2Slave):
    """LQG desired isolator force, turned into a current by Dyke's clipping or by the inverse model."""

    description = "Clipped-optimal (LQG) current controller of the MRE isolators (Dyke et al. 1996)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        design, weights, noise, isolator = ClippedOptimalDesign(), Weights(), NoiseIntensities(), IsolatorLaw()
        self.x = 0.0
        self.v = 0.0
        self.F = 0.0
        for j in range(N_LEVELS):
            setattr(self, f"a_{j}", 0.0)
        self.law = design.law
        self.n_grid = design.n_grid
        self.n_isolators = isolator.n_isolators
        for name in _DESIGN:
            setattr(self, name, getattr(design, name))
        for table, source in ((plant_core.WEIGHT_DOCS, weights), (plant_core.NOISE_DOCS, noise),
                              (plant_core.ISOLATOR_DOCS, isolator)):
            for name in table:
                setattr(self, name, getattr(source, name))
        for name, value in plant_core.building_defaults(N_LEVELS).items():
            setattr(self, name, value)
        self._controller: ClippedOptimalController | None = None
        self._failed = ""
        self._i = 0.0
        self._f_c = 0.0

        self.fmi_units = {"x": "m", "v": "m/s", "F": "N", "i": "A", "f_c": "N"}
        self.fmi_dependencies = {}
        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        out = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.continuous}
        self.register_variable(Real("x", description="base displacement relative to the ground", **inp))
        self.register_variable(Real("v", description="base velocity relative to the ground", **inp))
        for j in range(N_LEVELS):
            where = "base floor" if j == 0 else f"floor {j}"
            self.register_variable(Real(f"a_{j}", description=f"absolute acceleration of the {where}", **inp))
            self.fmi_units[f"a_{j}"] = "m/s2"
        self.register_variable(Real("F", description="measured restoring force of the isolators together", **inp))
        self.register_variable(String("law", description="current law: 'clipped' (Dyke) or 'inverse' (Eq. 17)",
                                      **par))
        self.register_variable(Integer("n_grid", description="inverse law: currents in the search grid", **par))
        self.register_variable(Integer("n_isolators", description="controller's model: devices in parallel", **par))
        tables = (_DESIGN, plant_core.WEIGHT_DOCS, plant_core.NOISE_DOCS, plant_core.ISOLATOR_DOCS,
                  plant_core.building_docs(N_LEVELS))
        for table in tables:
            for name, (unit, text) in table.items():
                self.register_variable(Real(name, description=text, **par))
                self.fmi_units[name] = unit
        self.register_variable(Real("i", description="command current", getter=lambda: self._i, **out))
        self.register_variable(Real("f_c", description="desired isolator restoring force (LQG)",
                                    getter=lambda: self._f_c, **out))

    def _make_controller(self) -> ClippedOptimalController:
        # the core's controller_parts: the same function the pre-run check (parameter_problem) uses
        return ClippedOptimalController(*controller_parts(self._parameter_values(), N_LEVELS))

    def _parameter_values(self) -> dict:
        """Every parameter's present value by FMU name (the core builds the design from them)."""
        return {v.name: getattr(self, v.name) for v in self.vars.values() if v.causality == Fmi2Causality.parameter}

    def _acc(self) -> list[float]:
        return [getattr(self, f"a_{j}") for j in range(N_LEVELS)]

    def exit_initialization_mode(self):
        # Problems are logged and fail the first step: an exception here would be fmi2Fatal.
        self._failed = plant_core.foreign_copy_problem(self.resources)
        if not self._failed:
            try:
                self._controller = self._make_controller()
            except (ValueError, ArithmeticError, TypeError, MemoryError) as exc:  # LinAlgError is a ValueError
                self._failed = f"invalid parameter: {exc}"
        if self._failed:
            self._failed = f"{UNIT}: {self._failed}"
            self._i = self._f_c = math.nan
            self.log(self._failed, Fmi2Status.error)
            return
        c = self._controller
        self._f_c = c.desired_force(c.estimator.z)
        if all(math.isfinite(u) for u in (self.x, self.v, self.F)):
            self._i = c.current(self._f_c, self.x, self.v, self.F)

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._failed:
            self.log(self._failed, Fmi2Status.error)
            return False
        acc = self._acc()
        if not all(math.isfinite(u) for u in (self.x, self.v, self.F, *acc)):
            self.log(f"{UNIT}: input x = {self.x}, v = {self.v}, F = {self.F} or a floor acceleration {acc} "
                     f"is not finite at t = {current_time:.6g} s", Fmi2Status.error)
            return False
        try:
            self._i = self._controller.update(self.x, self.v, acc, self.F, step_size)
        except EstimatorDiverged as exc:
            self._failed = f"{UNIT}: {exc} at t = {current_time:.6g} s"
        except ValueError as exc:  # the filter is unstable at this communication step
            self._failed = f"{UNIT}: {exc} (t = {current_time:.6g} s)"
        if self._failed:
            self._i = self._f_c = math.nan
            self.log(self._failed, Fmi2Status.error)
            return False
        self._f_c = self._controller.f_c
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
