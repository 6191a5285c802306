"""The project's units' parameter domains, checked before any run (``ResolveHooks.parameter_check``).

A value outside a unit's domain (a yield shear <= 0, a negative controller weight, a window
shorter than two steps, an OpenSees script that raises) is a configuration error: exit 2,
nothing written, naming the unit, the parameter and the scenario line. Each rule lives once,
in the unit's physics core; the FMU shell applies the same function when it initializes, this
module only finds the core by the FMU's model identifier and hands it the resolved values.

A value the chosen law does not use (``n_j`` without ``hysteresis: bouc-wen``, ``h_j`` without
``p_delta: true``, ``k_stop``/``c_stop`` without ``beyond_range: stop``) is checked too
(:func:`unused_problems`): outside its domain it is refused like any other; inside it, but
different from the FMU's declared start, it is refused as "set but unused", because a user who
writes ``n_1: 3`` and forgets ``hysteresis: bouc-wen`` would otherwise get a linear building
without a word. A value equal to the declared start is not "set" (``kobe_yielding.yaml`` with
``--set building.hysteresis=linear`` stays a linear run of the same building).
"""

from __future__ import annotations

import math
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


def _bouc_wen_isolator(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.bouc_wen_core import parameter_problem

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


def _current_lag(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.current_lag_core import parameter_problem

    return parameter_problem(values)


def _sensor_channels(values: Mapping[str, Any], levels: int) -> tuple[str, str] | None:
    from components.physics.sensor_channels_core import parameter_problem

    return parameter_problem(values)


CHECKS: dict[str, Check] = {
    "ShearBuilding": _shear_building,
    "MreIsolator": _isolator,
    "MreIsolatorC": _isolator,  # the plain-C unit implements the same law (tests/physics/test_c_isolator.py)
    "BoucWenIsolator": _bouc_wen_isolator,
    "ClippedOptimalCurrentController": _clipped_optimal,
    "LyapunovCurrentController": _lyapunov,
    "FrequencyCurrentController": _frequency,
    "SosmCurrentController": _sosm,
    "OpenSeesBuilding": _opensees,
    "CurrentLag": _current_lag,
    "SensorChannels": _sensor_channels,
}
_VARIANT = re.compile(r"(ShearBuilding|OpenSeesBuilding)\d+")  # storey-count variants (python -m components.build)


SCRIPT_PARAMETERS: dict[str, tuple[str, ...]] = {"OpenSeesBuilding": ("script",)}
"""Parameters whose value is a file of code the unit runs (kept as a data file of the plan, hashed)."""


def script_parameters(model_identifier: str) -> tuple[str, ...]:
    """The script parameters of a project unit (its storey-count variants too); () for any other FMU."""
    variant = _VARIANT.fullmatch(model_identifier)
    return SCRIPT_PARAMETERS.get(variant.group(1) if variant else model_identifier, ())


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
    if found is not None:
        return [found]
    unused = UNUSED.get(variant.group(1) if variant else model)
    return unused(description, values) if unused is not None else []


def _declared(description: UnitDescription, name: str) -> Any:
    """The declared start value of a parameter (float if numeric), or None."""
    var = description.variables.get(name)
    if var is None or var.start is None:
        return None
    try:
        return float(var.start)
    except (TypeError, ValueError):
        return var.start


def _set(description: UnitDescription, values: Mapping[str, Any], name: str) -> bool:
    """True if ``values`` gives ``name`` a value other than its declared start (so the scenario set it)."""
    if name not in values:
        return False
    value, start = values[name], _declared(description, name)
    try:
        return start is None or float(value) != float(start)
    except (TypeError, ValueError):
        return value != start


def _building_unused(description: UnitDescription, values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The shear building's parameters its law does not use: in their domain (the core's rule, applied as if
    the law used them), and not set to anything but their declared start."""
    from components.physics.shear_building_core import parameter_problem

    law = str(values.get("hysteresis", "linear"))
    p_delta = str(values.get("p_delta", False)).lower() in ("true", "1")
    unused: dict[str, str] = {}  # family prefix -> what would use it
    if law != "bouc-wen":
        unused.update({"n": "hysteresis: bouc-wen (the Bouc-Wen exponent)",
                       "bw_beta": "hysteresis: bouc-wen", "bw_gamma": "hysteresis: bouc-wen"})
    if law == "linear":
        unused.update({"fy": "hysteresis: bilinear or bouc-wen (the yield shear)",
                       "b": "hysteresis: bilinear or bouc-wen (the post-yield stiffness ratio)"})
    if not p_delta:
        unused["h"] = "p_delta: true (the storey height)"
    names = [n for n in values if n in unused or (n.rpartition("_")[0] in unused and n.rpartition("_")[2].isdigit()
                                                    and n.rpartition("_")[0] != "bw")]
    found = parameter_problem({**values, "hysteresis": "bouc-wen"}) if law != "bouc-wen" else None
    if found is not None:
        parameter, text = found[0], found[1].removeprefix(f"{found[0]}: ")
        if parameter == "bw_beta" and not _set(description, values, "bw_beta") and \
                _set(description, values, "bw_gamma"):
            parameter = "bw_gamma"  # the pair's rule is named by beta; the value set is gamma
        return [(parameter, f"{text} (checked although hysteresis: {law} does not use it)")]
    problems = []
    for name in names:
        if name.startswith("h_"):
            value = values[name]
            try:
                bad = not (math.isfinite(float(value)) and float(value) >= 0.0)
            except (TypeError, ValueError):
                bad = True
            if bad:  # the core checks h_j only with P-Delta; its declared start 0 means "no height given"
                problems.append((name, f"storey height {value!r} m must be > 0 "
                                       "(checked although p_delta: false does not use it)"))
                continue
        if _set(description, values, name):
            family = name if name in unused else name.rpartition("_")[0]
            why = "p_delta: false" if family == "h" else f"hysteresis: {law}"
            problems.append((name, f"{name} = {values[name]!r} is set but unused with {why} (set "
                                   f"{unused[family]}, or leave {name} out)"))
    return problems[:1]


def _isolator_unused(description: UnitDescription, values: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The isolator's stop parameters without ``beyond_range: stop``: in their domain (the core's rule, with a
    valid range), and not set to anything but their declared start."""
    from components.physics.mre_isolator_core import DEVICE_LIMIT_M, IDENTIFIED_RANGE_M, value_problem

    mode = str(values.get("beyond_range", "extrapolate"))
    if mode == "stop":
        return []
    forced = {**values, "beyond_range": "stop", "x_identified": IDENTIFIED_RANGE_M, "x_limit": DEVICE_LIMIT_M}
    found = value_problem(forced)  # each value in its domain; whether the stop out-stiffens the law only matters in use
    if found is not None and found[0] in ("k_stop", "c_stop"):
        return [(found[0], f"{found[1]} (checked although beyond_range: {mode} does not use it)")]
    for name in ("k_stop", "c_stop"):
        if _set(description, values, name):
            return [(name, f"{name} = {values[name]!r} is set but unused with beyond_range: {mode} "
                           f"(set beyond_range: stop, or leave {name} out)")]
    return []


UNUSED: dict[str, Callable[[UnitDescription, Mapping[str, Any]], list[tuple[str, str]]]] = {
    "ShearBuilding": _building_unused,
    "MreIsolator": _isolator_unused,
    "MreIsolatorC": _isolator_unused,
}
