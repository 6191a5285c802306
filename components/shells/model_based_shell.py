"""Shared pythonfmu glue of the model-based controller shells (clipped-optimal, Lyapunov, frequency control).

Not an FMU itself (no ``_fmu.py``): the three shells list it in ``FMU_CORE_MODULES`` beside
``lqg_plant_core``, so it travels in each of their FMUs (the build takes a listed module from
``components/physics/``, else from here) and each shell imports it by its bare name. pythonfmu FMUs
share one interpreter, so the copy loaded first serves all three: :func:`copy_problems` refuses to
start when that copy, or that of a module it shares with other FMUs (``lqg_plant_core`` and the
modules it imports: ``mre_isolator_core``, the isolator law, also in the isolator and SOSM FMUs, and
``dyke_building``, also in the building FMU), came from another FMU with other code. The module
keeps no state of its own: everything lives on the shell instance.

What it shares: the sensor inputs (x [m], v [m/s], a_0..a_3 [m/s^2], F [N]) and the model
parameters (``n_isolators``, the tables of ``lqg_plant_core``, the building m_j, k_j, c_j), their
registration with SI units; building the core's controller at initialization (a problem is logged
and fails the first step, never an exception: that would be fmi2Fatal); and the step of a
controller fed by the Kalman estimate, where a non-finite input or a diverging estimate is an
error naming the unit and the time.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import dyke_building
import lqg_plant_core as plant_core
import mre_isolator_core
import shared_copies
from lqg_plant_core import EstimatorDiverged
from pythonfmu import Fmi2Causality, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

N_LEVELS = 4  # base floor and three storeys (the paper's building)
INPUT = {"causality": Fmi2Causality.input, "variability": Fmi2Variability.continuous}
PARAMETER = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
OUTPUT = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.continuous}
HELD_OUTPUT = {"causality": Fmi2Causality.output, "variability": Fmi2Variability.discrete}  # held between steps
Docs = dict[str, tuple[str, str]]

LOADED_SOURCE = Path(__file__).read_bytes()  # as loaded: the FMU folder it came from may be gone later


def copy_problems(resources: str | None) -> str:
    """A text if ``lqg_plant_core``, ``mre_isolator_core``, ``dyke_building``, ``shared_copies`` or this module was
    loaded from another FMU with other code, else ""."""
    return (plant_core.foreign_copy_problem(resources)
            or shared_copies.copy_problem((mre_isolator_core, dyke_building, sys.modules[__name__]), resources))


def set_model_defaults(slave: Any, sources: Iterable[tuple[Docs, Any]]) -> None:
    """The parameters' start values on the shell: ``n_isolators``, each table's names from its source
    object (a design dataclass) and those of :data:`lqg_plant_core.ISOLATOR_DOCS` and the building's."""
    isolator = plant_core.IsolatorLaw()
    slave.n_isolators = isolator.n_isolators
    for table, source in (*sources, (plant_core.ISOLATOR_DOCS, isolator)):
        for name in table:
            setattr(slave, name, getattr(source, name))
    for name, value in plant_core.building_defaults(N_LEVELS).items():
        setattr(slave, name, value)


def set_sensor_defaults(slave: Any) -> None:
    """The sensor inputs' start values: 0."""
    slave.x = slave.v = slave.F = 0.0
    for j in range(N_LEVELS):
        setattr(slave, f"a_{j}", 0.0)


def register_sensors(slave: Any) -> None:
    """Inputs x [m], v [m/s] (relative to the ground), a_0..a_3 [m/s^2] (absolute), F [N], with their units."""
    slave.fmi_units.update({"x": "m", "v": "m/s", "F": "N"})
    slave.register_variable(Real("x", description="base displacement relative to the ground", **INPUT))
    slave.register_variable(Real("v", description="base velocity relative to the ground", **INPUT))
    for j in range(N_LEVELS):
        where = "base floor" if j == 0 else f"floor {j}"
        slave.register_variable(Real(f"a_{j}", description=f"absolute acceleration of the {where}", **INPUT))
        slave.fmi_units[f"a_{j}"] = "m/s2"
    slave.register_variable(Real("F", description="measured restoring force of the isolators together", **INPUT))


def register_model_parameters(slave: Any, *tables: Docs) -> None:
    """``n_isolators`` and the real parameters of ``tables``, then of the isolator and building models."""
    slave.register_variable(Integer("n_isolators", description="controller's model: devices in parallel",
                                    **PARAMETER))
    for table in (*tables, plant_core.ISOLATOR_DOCS, plant_core.building_docs(N_LEVELS)):
        for name, (unit, text) in table.items():
            slave.register_variable(Real(name, description=text, **PARAMETER))
            slave.fmi_units[name] = unit


def parameter_values(slave: Any) -> dict[str, Any]:
    """Every parameter's present value by FMU name (the core builds the design from them)."""
    return {v.name: getattr(slave, v.name) for v in slave.vars.values() if v.causality == Fmi2Causality.parameter}


def fail(slave: Any, unit: str, text: str, outputs: Iterable[str]) -> None:
    """Mark the unit failed: the text (prefixed by the unit) logged as an error, ``outputs`` set to NaN."""
    slave._failed = f"{unit}: {text}"
    for name in outputs:
        setattr(slave, name, math.nan)
    slave.log(slave._failed, Fmi2Status.error)


def start_controller(slave: Any, unit: str, controller_class: Callable[..., Any],
                     parts: Callable[[dict[str, Any], int], tuple], outputs: Iterable[str]) -> bool:
    """At exit of initialization: ``slave._controller`` from the parameters (``parts``: the core's
    ``controller_parts``, the function the pre-run check uses too); False after :func:`fail` on a problem."""
    slave._failed = ""
    problem = copy_problems(slave.resources)
    if not problem:
        try:
            slave._controller = controller_class(*parts(parameter_values(slave), N_LEVELS))
        except (ValueError, ArithmeticError, TypeError, MemoryError) as exc:  # LinAlgError is a ValueError
            problem = f"invalid parameter: {exc}"
    if problem:
        fail(slave, unit, problem, outputs)
        return False
    return True


def step_estimated(slave: Any, unit: str, current_time: float, step_size: float, outputs: Iterable[str]) -> bool:
    """One step of a controller fed by the Kalman estimate: ``slave._i`` from the sensor inputs at the step's
    start. False (an error logged) after a failure, for a non-finite input or when the estimate diverges or the
    filter is unstable at this step (then the unit stays failed, ``outputs`` NaN)."""
    if slave._failed:
        slave.log(slave._failed, Fmi2Status.error)
        return False
    acc = [getattr(slave, f"a_{j}") for j in range(N_LEVELS)]
    if not all(math.isfinite(u) for u in (slave.x, slave.v, slave.F, *acc)):
        slave.log(f"{unit}: input x = {slave.x}, v = {slave.v}, F = {slave.F} or a floor acceleration {acc} "
                  f"is not finite at t = {current_time:.6g} s", Fmi2Status.error)
        return False
    try:
        slave._i = slave._controller.update(slave.x, slave.v, acc, slave.F, step_size)
    except EstimatorDiverged as exc:
        fail(slave, unit, f"{exc} at t = {current_time:.6g} s", outputs)
        return False
    except ValueError as exc:  # the filter is unstable at this communication step
        fail(slave, unit, f"{exc} (t = {current_time:.6g} s)", outputs)
        return False
    return True
