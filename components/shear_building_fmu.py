"""FMI 2.0 co-simulation shell of the n-storey shear building on a base floor.

Levels are numbered 0 (base floor) to N_STOREYS (roof). Inputs ag [m/s^2] (ground
acceleration) and F [N] (isolator restoring force, applied to the base against x_0).
Outputs per level j: x_j [m], v_j [m/s] relative to the ground, a_j [m/s^2] absolute
acceleration, arel_j [m/s^2] relative acceleration; per storey j >= 1: drift_j [m] and
shear_j [N]. Displacements, velocities, drifts and shears are states (no direct
feedthrough); accelerations depend directly on ag and F.

The number of storeys is fixed at build time (``N_STOREYS``, the build step renders
variants under their own module names).
"""

from __future__ import annotations

import math

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status
from shear_building_core import BuildingParams
from shear_building_core import ShearBuilding as BuildingModel

N_STOREYS = 3
FMU_CORE_MODULES = ("shear_building_core",)


class ShearBuilding(Fmi2Slave):
    """Shear building on a base floor, exact discretization of the linear model."""

    description = "n-storey shear building on a base floor (relative coordinates, exact ZOH stepping)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        n = N_STOREYS
        self.n_levels = n + 1
        default = BuildingParams.dyke() if n == 3 else BuildingParams.uniform(n)
        self.ag = 0.0
        self.F = 0.0
        self.m = list(default.m)
        self.k = list(default.k)
        self.c = list(default.c)
        self._model: BuildingModel | None = None
        self._cache_key: tuple | None = None
        self._acc = np.zeros(self.n_levels)
        self._arel = np.zeros(self.n_levels)

        inp = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
        out = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.continuous}
        par = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        self.register_variable(Real("ag", description="ground acceleration", **inp))
        self.register_variable(
            Real("F", description="isolator restoring force, acts on the base against x_0", **inp)
        )
        self.fmi_units = {"ag": "m/s2", "F": "N"}
        feed = ("ag", "F")
        self.fmi_dependencies = {}
        for j in range(self.n_levels):
            where = "base floor" if j == 0 else f"floor {j}"
            self._param(f"m_{j}", self.m, j, "kg", f"mass of the {where}", par)
            spring = "base to ground" if j == 0 else f"storey {j}"
            self._param(f"k_{j}", self.k, j, "N/m", f"stiffness, {spring}", par)
            self._param(f"c_{j}", self.c, j, "N.s/m", f"damping, {spring}", par)
        for j in range(self.n_levels):
            where = "base floor" if j == 0 else f"floor {j}"
            self._output(f"x_{j}", f"displacement of the {where} relative to the ground", "m",
                         lambda j=j: self._state()[j], out)
            self._output(f"v_{j}", f"velocity of the {where} relative to the ground", "m/s",
                         lambda j=j: self._state()[self.n_levels + j], out)
            self._output(f"a_{j}", f"absolute acceleration of the {where}", "m/s2",
                         lambda j=j: self._accelerations()[0][j], out)
            self._output(f"arel_{j}", f"acceleration of the {where} relative to the ground", "m/s2",
                         lambda j=j: self._accelerations()[1][j], out)
            self.fmi_dependencies[f"a_{j}"] = feed
            self.fmi_dependencies[f"arel_{j}"] = feed
        for j in range(1, self.n_levels):
            self._output(f"drift_{j}", f"inter-storey drift x_{j} - x_{j - 1}", "m",
                         lambda j=j: self._state()[j] - self._state()[j - 1], out)
            self._output(f"shear_{j}", f"shear force in storey {j}", "N",
                         lambda j=j: self._storey_shear(j), out)

    def _param(self, name, store, j, unit, text, attrs) -> None:
        def setter(value, store=store, j=j):
            store[j] = float(value)
            self._model = None

        self.register_variable(Real(name, description=text, getter=lambda: store[j], setter=setter, **attrs))
        self.fmi_units[name] = unit

    def _output(self, name, text, unit, getter, attrs) -> None:
        self.register_variable(Real(name, description=text, getter=getter, **attrs))
        self.fmi_units[name] = unit

    def _building(self) -> BuildingModel:
        if self._model is None:
            self._model = BuildingModel(BuildingParams(tuple(self.m), tuple(self.k), tuple(self.c)))
            self._cache_key = None
        return self._model

    def _state(self) -> np.ndarray:
        return self._building().q

    def _accelerations(self) -> tuple[np.ndarray, np.ndarray]:
        model = self._building()
        key = (self.ag, self.F, model.steps)
        if key != self._cache_key:
            self._arel = model.relative_acceleration(self.ag, self.F)
            self._acc = self._arel + self.ag
            self._cache_key = key
        return self._acc, self._arel

    def _storey_shear(self, j: int) -> float:
        q = self._state()
        n = self.n_levels
        return self.k[j] * (q[j] - q[j - 1]) + self.c[j] * (q[n + j] - q[n + j - 1])

    def exit_initialization_mode(self):
        try:
            self._building()
        except ValueError as exc:
            self.log(f"invalid building parameters: {exc}", Fmi2Status.error)
            raise

    def do_step(self, current_time: float, step_size: float) -> bool:
        if not (math.isfinite(self.ag) and math.isfinite(self.F)):
            self.log(
                f"input ag = {self.ag} or F = {self.F} is not finite at t = {current_time:.6g} s",
                Fmi2Status.error,
            )
            return False
        self._building().step(self.ag, self.F, step_size)
        return True
