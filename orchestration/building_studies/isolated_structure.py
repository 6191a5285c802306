"""The building and isolators of a scenario as the in-process model has them, from its units' identifiers and
the parameters it sets: no record, no controller (the light part of
:mod:`orchestration.building_studies.in_process_model`, which a run's periods use without importing the
controllers' cores)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from components.physics.mre_isolator_core import TABLE2, GeneralizedCoefficients
from components.physics.shear_building_core import BuildingParams

_IGNORED_ISOLATOR = {"x_identified", "x_limit", "i_max", "n_isolators"}


class NotMonolithic(ValueError):
    """The scenario sets parameters the in-process model does not represent."""


MONOLITHIC_UNITS = {"ground": "GroundMotionSource", "building": "ShearBuilding", "isolator": "MreIsolator",
                    "controller": "SosmCurrentController"}
"""The units (name: FMU model identifier) the in-process model represents: the paper's system."""


def units_problem(identifiers: Mapping[str, str]) -> str | None:
    """:func:`monolithic_problem` from each unit's FMU model identifier (unit name: identifier, '' if unknown)."""
    extra = sorted(set(identifiers) - set(MONOLITHIC_UNITS))
    if extra:
        return f"the scenario has units the in-process model lacks: {', '.join(extra)}"
    for unit, identifier in MONOLITHIC_UNITS.items():
        if unit not in identifiers:
            return f"the scenario has no unit {unit!r}"
        given = identifiers[unit]
        if unit != "controller" and given and given != identifier:
            return f"{unit} is {given}, the in-process model has {identifier} only"
    return None


@dataclass(frozen=True)
class IsolatedStructure:
    """The building and its isolators as the in-process model has them (no ground motion, no controller)."""

    building: BuildingParams
    coeffs: GeneralizedCoefficients
    n_isolators: int
    i_max: float  # [A]


def structure_setup(identifiers: Mapping[str, str], parameters: Mapping[str, Mapping[str, Any]]) -> IsolatedStructure:
    """The building and isolators of a scenario from its units' identifiers and the parameters it sets.

    NotMonolithic as :func:`system_setup` (another unit, a parameter the model does not represent)."""
    problem = units_problem(identifiers)
    if problem is not None:
        raise NotMonolithic(f"{problem}: the in-process model is the paper's system only")
    iso = parameters.get("isolator", {})
    return IsolatedStructure(_building(parameters.get("building", {})), _coefficients(iso),
                             int(iso.get("n_isolators", 2)), float(iso.get("i_max", 3.0)))


def _building(set_values: Mapping[str, Any]) -> BuildingParams:
    """The Dyke building with the scenario's m_j, k_j, c_j; NotMonolithic for any other parameter."""
    b = BuildingParams.dyke()
    values = {"m": list(b.m), "k": list(b.k), "c": list(b.c)}
    for name, value in set_values.items():
        kind, _, j = name.partition("_")
        if kind not in values or not j.isdigit() or int(j) >= len(values[kind]):
            raise NotMonolithic(f"building parameter {name} is not represented in the in-process model")
        values[kind][int(j)] = float(value)
    return BuildingParams(m=tuple(values["m"]), k=tuple(values["k"]), c=tuple(values["c"]))


def _coefficients(set_values: Mapping[str, Any]) -> GeneralizedCoefficients:
    """Table 2 with the scenario's isolator coefficients; NotMonolithic for a parameter the model lacks."""
    coeffs = TABLE2.as_dict()
    for name, value in set_values.items():
        if name in coeffs:
            coeffs[name] = float(value)
        elif name not in _IGNORED_ISOLATOR:
            raise NotMonolithic(f"isolator parameter {name} is not represented in the in-process model")
    return GeneralizedCoefficients(**coeffs)
