"""The roles of the isolated building's co-simulation, and what an FMU must provide to play one.

A role is what the studies and the report need from a unit, not a set of names: a controller is
"an output that is the current command [A]" and, optionally, "a parameter that limits it [A]".
Our FMUs call these ``i`` and ``i_max``; a strategy entry maps them onto another tool's names
(``current: u``, ``limit: imax``; :mod:`orchestration.building_studies.strategies`). The isolator and
building roles list the variables the shipped scenarios connect; a foreign unit in those roles is
wired by the scenario's own connections.

:func:`check_role` compares an FMU's variables with a role (names, causality, units) and returns
every problem; ``mre-cosim inspect FMU --role ROLE`` prints it (:mod:`orchestration.inspect`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from orchestration.master.fmu_description import read_description
from orchestration.master.unit import UnitDescription, Variable


@dataclass(frozen=True)
class RoleVariable:
    """One variable a role needs: our name for it, its causality, its SI unit and what it is."""

    name: str
    causality: str  # "input", "output" or "parameter"
    unit: str
    what: str
    required: bool = True


ROLES: dict[str, tuple[RoleVariable, ...]] = {
    "controller": (
        RoleVariable("i", "output", "A", "the current command (strategy entry: current)"),
        RoleVariable("i_max", "parameter", "A", "the current limit the study sets (strategy entry: limit); "
                                               "without one the controller keeps its own", required=False),
    ),
    "isolator": (
        RoleVariable("x", "input", "m", "the base displacement"),
        RoleVariable("v", "input", "m/s", "the base velocity"),
        RoleVariable("i", "input", "A", "the coil current"),
        RoleVariable("F", "output", "N", "the force of the isolators together"),
    ),
    "building": (
        RoleVariable("ag", "input", "m/s2", "the ground acceleration"),
        RoleVariable("F", "input", "N", "the isolators' force on the base floor"),
        RoleVariable("x_0", "output", "m", "the base displacement"),
        RoleVariable("v_0", "output", "m/s", "the base velocity"),
        *(RoleVariable(f"a_{j}", "output", "m/s2", f"floor {j}'s absolute acceleration") for j in range(4)),
        *(RoleVariable(f"drift_{j}", "output", "m", f"storey {j}'s drift") for j in range(1, 4)),
    ),
}
"""Role -> the variables it needs, under our names."""


def _same_unit(declared: str | None, wanted: str) -> bool:
    """Whether a declared unit is the role's (``m/s2`` and ``m/s^2`` are one)."""
    return (declared or "").replace("^", "").replace(" ", "") == wanted.replace("^", "")


def describe_variable(v: Variable) -> str:
    """One variable as ``name (causality, unit)``, as the problems and ``inspect`` list them."""
    return f"{v.name} ({v.causality}, {v.unit or 'no unit'})"


def fmu_offer(description: UnitDescription, causality: str | None = None) -> str:
    """What an FMU has (of one causality, or of all the role-relevant ones), for a problem's message."""
    kinds = (causality,) if causality else ("input", "output", "parameter")
    found = [describe_variable(v) for v in description.variables.values() if v.causality in kinds]
    return ", ".join(found) or "none"


def check_variable(description: UnitDescription, name: str, causality: str, unit: str, what: str
                   ) -> tuple[str | None, str | None]:
    """(problem, warning) for variable ``name`` of a unit playing ``what`` (None: fine).

    A missing variable or one of another causality is a problem naming what the FMU has; a
    different non-empty unit is a problem; no unit at all (common in other tools' exports) is
    accepted with a warning naming both ends.
    """
    v = description.variables.get(name)
    if v is None:
        return (f"{description.name} has no {causality} {name!r} for {what}; its {causality}s: "
                f"{fmu_offer(description, causality)}"), None
    if v.causality != causality:
        return (f"{description.name}.{name} is {'an' if v.causality[0] in 'aeiou' else 'a'} {v.causality}, "
                f"{what} must be {'an' if causality[0] in 'aeiou' else 'a'} {causality}; its {causality}s: "
                f"{fmu_offer(description, causality)}"), None
    if not v.unit:
        return None, f"{description.name}.{name} declares no unit; taken as {unit} ({what})"
    if not _same_unit(v.unit, unit):
        return f"{description.name}.{name} is in {v.unit}, {what} is in {unit}", None
    return None, None


def check_role(description: UnitDescription, role: str, names: dict[str, str] | None = None
               ) -> tuple[list[str], list[str]]:
    """(problems, warnings) of a unit playing ``role``; ``names`` maps our names to the FMU's."""
    names = names or {}
    problems, warnings = [], []
    for rv in ROLES[role]:
        name = names.get(rv.name, rv.name)
        if not rv.required and name not in description.variables:
            continue
        problem, warning = check_variable(description, name, rv.causality, rv.unit, rv.what)
        problems += [problem] if problem else []
        warnings += [warning] if warning else []
    return problems, warnings


def read_unit(path: Path, name: str) -> UnitDescription:
    """The variables of the FMU at ``path`` as unit ``name`` (FmuFormatError if it is no FMU we can read)."""
    return read_description(Path(path), name)[0]
