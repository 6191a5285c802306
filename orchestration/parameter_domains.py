"""The project's units' parameter domains, checked before any run (``ResolveHooks.parameter_check``).

A value outside a unit's domain (a yield shear <= 0, a negative controller weight, a window
shorter than two steps, an OpenSees script that raises) is a configuration error: exit 2,
nothing written, naming the unit, the parameter and the scenario line. Each rule lives once,
in the unit's physics core; the FMU shell applies the same function when it initializes, this
module only finds the core by the FMU's model identifier and hands it the resolved values.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from orchestration.master.unit import UnitDescription

Check = Callable[[Mapping[str, Any], int], "tuple[str, str] | None"]


def _levels(values: Mapping[str, Any]) -> int:
    """Levels (base floor and floors) of a unit with parameters m_0 .. m_n."""
    return sum(1 for name in values if re.fullmatch(r"m_\d+", name))


def _shear_building(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.shear_building_core import parameter_problem

    found = parameter_problem(dict(values))
    if found is None:
        return None
    parameter, text = found
    return parameter, text.removeprefix(f"{parameter}: ")  # the Problem's key names the parameter already


def _isolator(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.mre_isolator_core import parameter_problem

    return parameter_problem(values)


def _clipped_optimal(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.clipped_optimal_core import parameter_problem

    return parameter_problem(values, levels)


def _lyapunov(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.lyapunov_controller_core import parameter_problem

    return parameter_problem(values, levels)


def _frequency(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.frequency_controller_core import parameter_problem

    return parameter_problem(values, levels)


def _sosm(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.sosm_controller_core import parameter_problem

    return parameter_problem(values)


def _opensees(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.opensees_building_core import parameter_problem

    return parameter_problem(values, levels - 1 if levels else None)


CHECKS: dict[str, Check] = {
    "ShearBuilding": _shear_building,
    "MreIsolator": _isolator,
    "MreIsolatorC": _isolator,  # the plain-C unit implements the same law (tests/test_c_isolator.py)
    "ClippedOptimalCurrentController": _clipped_optimal,
    "LyapunovCurrentController": _lyapunov,
    "FrequencyCurrentController": _frequency,
    "SosmCurrentController": _sosm,
    "OpenSeesBuilding": _opensees,
}
_VARIANT = re.compile(r"(ShearBuilding|OpenSeesBuilding)\d+")  # storey-count variants (python -m components.build)


def parameter_problems(description: UnitDescription, fmu_path: Path,
                       values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(parameter, problem) pairs for a project unit's resolved parameter values; [] for any other FMU."""
    model = description.model_identifier
    variant = _VARIANT.fullmatch(model)
    check = CHECKS.get(variant.group(1) if variant else model)
    if check is None:
        return []
    levels = sum(1 for v in description.variables.values() if re.fullmatch(r"x_\d+", v.name) and
                 v.causality == "output") or _levels(values)
    found = check(values, levels)
    return [found] if found is not None else []
