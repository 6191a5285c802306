"""FMI 2.0 co-simulation shell of the n-storey shear building on a base floor.

Levels are numbered 0 (base floor) to N_STOREYS (roof). Inputs ag [m/s^2] (ground
acceleration) and F [N] (isolator restoring force, applied to the base against x_0).
Outputs per level j: x_j [m], v_j [m/s] relative to the ground, a_j [m/s^2] absolute
acceleration, arel_j [m/s^2] relative acceleration; per storey j >= 1: drift_j [m] and
shear_j [N]. Displacements, velocities, drifts and shears are states (no direct
feedthrough); accelerations depend directly on ag and F.

Storeys may yield (docs/structures.md): the String parameter ``hysteresis`` is 'linear'
(default: the exact-ZOH linear model, unchanged), 'bilinear' (OpenSees Steel01 without
isotropic hardening, E0 = k_j, Fy = fy_j, b = b_j) or 'bouc-wen' (Wen 1976, exponent n_j,
one pair bw_beta, bw_gamma for all storeys). Per storey j >= 1: fy_j [N], b_j [1], n_j [1];
``substeps`` Newmark sub-steps per communication step. Out-of-range values are refused at
the end of initialization (before any step), naming the parameter. ``p_delta`` with storey
heights ``h_j`` [m] adds the linearised P-Delta stiffness -P_j/h_j (P_j: weight of floors j..n).
``residual_drift_j`` [m]
(drift_j - f_j / k_j, the plastic offset; 0 for linear storeys) are FMI *local* variables:
readable by any importer, not outputs, so that ``outputs: all`` records what it recorded before.
So are the energy integrals ``E_input``, ``E_isolator``, ``E_damping``, ``E_strain``, ``E_hysteretic``,
``E_kinetic`` [J] (``shear_building_core.ENERGY_NAMES``): what the building integrated, exact for the
inputs it held over each step, for the application's energy balance (docs/running.md, "Validity").

The number of storeys is fixed at build time (``N_STOREYS``, the build step renders
variants under their own module names).
"""

from __future__ import annotations

import copy
import math
import sys

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

try:
    import dyke_building
    import fast_exchange
    import shared_copies
    from fast_exchange import FastExchange
    from shear_building_core import (
        ENERGY_NAMES,
        HYSTERESIS_LAWS,
        BuildingParams,
        ConvergenceError,
        HystereticShearBuilding,
        StoreyLaws,
        make_building,
    )
    from shear_building_core import ShearBuilding as BuildingModel
except ImportError as exc:  # the host's Python lacks a package: say which (the build's logging shim shows it)
    raise ImportError(f"the ShearBuilding unit needs the Python packages numpy and scipy in the host's "
                      f"interpreter ({sys.executable}): {exc}") from exc

N_STOREYS = 3
ENERGY_DOCS = (
    "relative input energy so far, -integral of ag sum_j m_j v_j dt (Uang & Bertero 1990)",
    "work the building gave the isolators so far, integral of F v_0 dt with the force it integrated",
    "energy the storey (and base) dampers took so far",
    "recoverable strain energy of the storeys (and k_0) now",
    "hysteretic work of the yielding storeys so far (0 for linear storeys)",
    "relative kinetic energy now, sum_j m_j v_j^2 / 2",
)
# Defaults of the yielding storeys (used only when hysteresis is not 'linear'): the values of
# scenarios/kobe_yielding.yaml, see docs/structures.md.
DEFAULT_FY_DYKE = (3300.0, 3700.0, 3200.0)  # N, storeys 1..3: half the 0 A linear Kobe x0.5 peak shears
DEFAULT_FY = 3200.0  # N, every storey of a variant with another storey count
DEFAULT_B = 0.05  # post-yield stiffness ratio
DEFAULT_N = 2.0  # Bouc-Wen exponent
FMU_CORE_MODULES = ("shear_building_core", "dyke_building", "shared_copies", "fast_exchange")
FMU_REQUIREMENTS: tuple[str, ...] = ("numpy", "scipy")  # besides Python >= 3.11
FMU_FAILED_STEP_STATUS = "error"  # a do_step that returns False (an error it logged) is fmi2Error


_INPUT = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
_PARAMETER = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
_OUTPUT = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.continuous}
_LOCAL = {"causality": Fmi2Causality.local, "variability": Fmi2Variability.continuous}


def _where(j: int) -> str:
    return "base floor" if j == 0 else f"floor {j}"


def output_table(n_levels: int) -> list[tuple[str, str, str]]:
    """(name, unit, description) of the outputs, in the order of ``BuildingModel.output_vector``."""
    levels, storeys = range(n_levels), range(1, n_levels)
    return (
        [(f"x_{j}", "m", f"displacement of the {_where(j)} relative to the ground") for j in levels]
        + [(f"v_{j}", "m/s", f"velocity of the {_where(j)} relative to the ground") for j in levels]
        + [(f"a_{j}", "m/s2", f"absolute acceleration of the {_where(j)}") for j in levels]
        + [(f"arel_{j}", "m/s2", f"acceleration of the {_where(j)} relative to the ground") for j in levels]
        + [(f"drift_{j}", "m", f"inter-storey drift x_{j} - x_{j - 1}") for j in storeys]
        + [(f"shear_{j}", "N", f"shear force in storey {j}") for j in storeys]
    )


class ShearBuilding(FastExchange, Fmi2Slave):
    """Shear building on a base floor, exact discretization of the linear model."""

    description = "n-storey shear building on a base floor (relative coordinates, exact ZOH stepping)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._slave_attrs = frozenset(vars(self)) | {"_slave_attrs"}
        self._set_defaults(N_STOREYS)
        self.fmi_units = {"ag": "m/s2", "F": "N"}
        self.fmi_dependencies = {}
        # Registered in this order, so that the value references of the linear model's variables stay as they were.
        self._register_linear_model()
        outputs = self._register_outputs(output_table(self.n_levels))
        self._register_yielding_storeys()
        self._register_energies(len(outputs))
        # The master exchanges the same value references every step: fast paths for them (fast_exchange).
        self.exchange_fast(inputs=("ag", "F"), outputs=(*outputs, *ENERGY_NAMES))

    def _set_defaults(self, n: int) -> None:
        """The start values of the variables (the paper's building for 3 storeys) and the unit's own state."""
        self.n_levels = n + 1
        default = BuildingParams.dyke() if n == 3 else BuildingParams.uniform(n)
        self.ag = 0.0
        self.F = 0.0
        self.m = list(default.m)
        self.k = list(default.k)
        self.c = list(default.c)
        self.hysteresis = "linear"
        self.fy = [math.nan] + (list(DEFAULT_FY_DYKE) if n == 3 else [DEFAULT_FY] * n)  # index 0 unused
        self.b = [math.nan] + [DEFAULT_B] * n
        self.n_exp = [math.nan] + [DEFAULT_N] * n
        self.bw_beta = 0.5
        self.bw_gamma = 0.5
        self.substeps = 4
        self.p_delta = False
        self.h = [math.nan] + [0.0] * n  # storey heights [m]; 0: not given (P-Delta refuses it)
        self._model: BuildingModel | HystereticShearBuilding | None = None
        self._failed = ""
        self._copy_problem = ""
        self._cache_key: tuple | None = None
        self._values: list[float] = []
        self._n_values = 0  # outputs and energies that _exchanged_outputs gives

    def _register_linear_model(self) -> None:
        """Inputs ag and F, and m_j, k_j, c_j of every level."""
        self.register_variable(Real("ag", description="ground acceleration", **_INPUT))
        self.register_variable(
            Real("F", description="isolator restoring force, acts on the base against x_0", **_INPUT)
        )
        for j in range(self.n_levels):
            spring = "base to ground" if j == 0 else f"storey {j}"
            self._param(f"m_{j}", self.m, j, "kg", f"mass of the {_where(j)}", _PARAMETER)
            self._param(f"k_{j}", self.k, j, "N/m", f"stiffness, {spring}", _PARAMETER)
            self._param(f"c_{j}", self.c, j, "N.s/m", f"damping, {spring}", _PARAMETER)

    def _register_outputs(self, table: list[tuple[str, str, str]]) -> list[str]:
        """The outputs of ``table`` (name, unit, description; in the order of output_vector); their names."""
        for index, (name, unit, text) in enumerate(table):
            self.register_variable(Real(name, description=text, getter=self._value_getter(index), **_OUTPUT))
            self.fmi_units[name] = unit
            if name.startswith(("a_", "arel_")):
                self.fmi_dependencies[name] = ("ag", "F")
        self._n_values += len(table)
        return [name for name, _, _ in table]

    def _value_getter(self, index: int):
        return lambda: self._exchanged_outputs()[index]

    def _register_yielding_storeys(self) -> None:
        """The storey laws' parameters, the residual drifts and P-Delta (registered after the outputs)."""
        choices = " or ".join(f"'{h}'" for h in HYSTERESIS_LAWS)
        self.register_variable(String("hysteresis", description=f"{choices}: storey law for all storeys",
                                      **_PARAMETER))
        for j in range(1, self.n_levels):
            self._param(f"fy_{j}", self.fy, j, "N", f"yield shear of storey {j} (bilinear, bouc-wen)", _PARAMETER)
            self._param(f"b_{j}", self.b, j, "1", f"post-yield stiffness ratio of storey {j}, in [0, 1)", _PARAMETER)
            self._param(f"n_{j}", self.n_exp, j, "1", f"Bouc-Wen exponent of storey {j} (>= 1)", _PARAMETER)
        self.register_variable(Real("bw_beta", description="Bouc-Wen beta, all storeys", **_PARAMETER))
        self.register_variable(Real("bw_gamma", description="Bouc-Wen gamma, all storeys", **_PARAMETER))
        self.fmi_units.update(bw_beta="1", bw_gamma="1")
        self.register_variable(Integer("substeps", description="Newmark sub-steps per step (yielding storeys)",
                                       **_PARAMETER))
        for j in range(1, self.n_levels):
            name = f"residual_drift_{j}"
            self.register_variable(Real(name, description=f"residual drift of storey {j}: drift - f/k_{j}",
                                        getter=lambda s=j - 1: self._residual(s), **_LOCAL))
            self.fmi_units[name] = "m"
        self.register_variable(Boolean("p_delta", description="add the linearised P-Delta stiffness -P_j/h_j",
                                       **_PARAMETER))
        for j in range(1, self.n_levels):
            self._param(f"h_{j}", self.h, j, "m", f"height of storey {j} (P-Delta)", _PARAMETER)

    def _register_energies(self, first: int) -> None:
        """The energy integrals (locals, like residual_drift_j), after the outputs in ``_exchanged_outputs``."""
        for k, (name, text) in enumerate(zip(ENERGY_NAMES, ENERGY_DOCS, strict=True)):
            self.register_variable(Real(name, description=text, getter=self._value_getter(first + k), **_LOCAL))
            self.fmi_units[name] = "J"
        self._n_values += len(ENERGY_NAMES)

    def _param(self, name, store, j, unit, text, attrs) -> None:
        def setter(value, store=store, j=j):
            store[j] = float(value)
            self._model = None

        self.register_variable(Real(name, description=text, getter=lambda: store[j], setter=setter, **attrs))
        self.fmi_units[name] = unit

    def _laws(self) -> StoreyLaws:
        return StoreyLaws(self.hysteresis, tuple(self.fy[1:]), tuple(self.b[1:]), tuple(self.n_exp[1:]),
                          self.bw_beta, self.bw_gamma, int(self.substeps), bool(self.p_delta), tuple(self.h[1:]))

    def _residual(self, s: int) -> float:
        model = self._building()
        if model is None:
            return math.nan
        return float(model.residual_drifts()[s]) if isinstance(model, HystereticShearBuilding) else 0.0

    def _building(self) -> BuildingModel | HystereticShearBuilding | None:
        """The model for the present parameters, or None (logged once) if they are invalid."""
        if self._model is None:
            try:
                self._model = make_building(BuildingParams(tuple(self.m), tuple(self.k), tuple(self.c)),
                                            self._laws())
                self._failed = ""
            except ValueError as exc:
                if not self._failed:
                    self.log(f"invalid building parameters: {exc}", Fmi2Status.error)
                self._failed = f"invalid building parameters: {exc}"
            self._cache_key = None
        return self._model

    def _exchanged_outputs(self) -> list[float]:
        """All outputs, then the energies, for the present state and inputs, computed once per change (NaN if
        the parameters are invalid)."""
        model = self._building()
        if model is None:
            return [math.nan] * self._n_values
        key = (self.ag, self.F, model.steps, id(model))
        if key != self._cache_key:
            self._values = model.output_vector(self.ag, self.F).tolist() + model.energies().tolist()
            self._cache_key = key
        return self._values

    def exit_initialization_mode(self):
        self._model = None  # String and Integer parameters may have changed since the last build
        # another FMU's copy of a shared module (the building table, the fast paths) with other code: refused
        self._failed = ""
        self._copy_problem = shared_copies.copy_problem((dyke_building, fast_exchange), self.resources)
        if self._copy_problem:
            self.log(self._copy_problem, Fmi2Status.error)
            return
        self._building()  # logs invalid parameters; an exception here would be fmi2Fatal

    def do_step(self, current_time: float, step_size: float) -> bool:
        model = None if self._copy_problem else self._building()
        if model is None:
            self.log(self._copy_problem or self._failed, Fmi2Status.error)
            return False
        if not (math.isfinite(self.ag) and math.isfinite(self.F)):
            self.log(
                f"input ag = {self.ag} or F = {self.F} is not finite at t = {current_time:.6g} s",
                Fmi2Status.error,
            )
            return False
        try:
            model.step(self.ag, self.F, step_size)
        except ConvergenceError as exc:
            self.log(f"storey laws did not converge at t = {current_time:.6g} s: {exc}", Fmi2Status.error)
            return False
        return True

    # FMU state (fmi2GetFMUstate/fmi2SetFMUstate): every instance attribute the shell added,
    # registered or not, deep-copied; pythonfmu's own bookkeeping is left alone.
    def _get_fmu_state(self) -> dict:
        return {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._slave_attrs}

    def _set_fmu_state(self, state: dict) -> None:
        vars(self).update(copy.deepcopy(state))
