"""The in-process model of a planned scenario: the paper's system (ground, shear building, MRE isolator, SOSM
controller) as :class:`~components.physics.monolithic.SystemSetup`, for the Radau reference, the current sweep,
the gain tuning and the IDA's isolated period.

:func:`monolithic_problem` says why a scenario is not that system; :func:`system_setup` builds the model or raises
:class:`NotMonolithic`.
"""

from __future__ import annotations

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.monolithic import SystemSetup
from components.physics.mre_isolator_core import TABLE2, GeneralizedCoefficients
from components.physics.shear_building_core import BuildingParams
from components.physics.sosm_controller_core import HAND_PICKED_GAINS, SosmGains
from orchestration.master.resolve import SystemPlan

DEFAULT_GAINS = HAND_PICKED_GAINS  # the hand-picked gains: the tuning's first point
_IGNORED_ISOLATOR = {"x_identified", "x_limit", "i_max", "n_isolators"}


class NotMonolithic(ValueError):
    """The scenario sets parameters the in-process model does not represent."""


MONOLITHIC_UNITS = {"ground": "GroundMotionSource", "building": "ShearBuilding", "isolator": "MreIsolator",
                    "controller": "SosmCurrentController"}
"""The units (name: FMU model identifier) the in-process model represents: the paper's system."""


def monolithic_problem(plan: SystemPlan) -> str | None:
    """Why the in-process model cannot represent a planned scenario (another isolator FMU, a unit it lacks, such
    as a coil lag), or None. The controller's FMU does not matter for a constant current."""
    extra = sorted(set(plan.descriptions) - set(MONOLITHIC_UNITS))
    if extra:
        return f"the scenario has units the in-process model lacks: {', '.join(extra)}"
    for unit, identifier in MONOLITHIC_UNITS.items():
        desc = plan.descriptions.get(unit)
        if desc is None:
            return f"the scenario has no unit {unit!r}"
        if unit != "controller" and desc.model_identifier and desc.model_identifier != identifier:
            return f"{unit} is {desc.model_identifier}, the in-process model has {identifier} only"
    return None


def system_setup(plan: SystemPlan, passive_current: float | None, gains: SosmGains | None = None) -> SystemSetup:
    """In-process model of a planned scenario; ``passive_current`` None means SOSM with ``gains``.

    NotMonolithic when the scenario is not the paper's system (:func:`monolithic_problem`) or sets parameters
    the model does not represent."""
    problem = monolithic_problem(plan)
    if problem is not None:
        raise NotMonolithic(f"{problem}: the in-process model (the Radau reference, the tuning) is the paper's system "
                            "only (a study on another plant: reference.enabled: false)")
    par = plan.parameters
    ground = par.get("ground", {})
    motion = GroundMotion(read_record(plan.data_files["ground.record"]), scale=float(ground.get("scale", 1.0)),
                          time_scale=float(ground.get("time_scale", 1.0)))
    b = BuildingParams.dyke()
    values = {"m": list(b.m), "k": list(b.k), "c": list(b.c)}
    for name, value in par.get("building", {}).items():
        kind, _, j = name.partition("_")
        if kind not in values or not j.isdigit() or int(j) >= len(values[kind]):
            raise NotMonolithic(f"building parameter {name} is not represented in the in-process model")
        values[kind][int(j)] = float(value)
    building = BuildingParams(m=tuple(values["m"]), k=tuple(values["k"]), c=tuple(values["c"]))
    iso = par.get("isolator", {})
    coeffs = TABLE2.as_dict()
    for name, value in iso.items():
        if name in coeffs:
            coeffs[name] = float(value)
        elif name not in _IGNORED_ISOLATOR:
            raise NotMonolithic(f"isolator parameter {name} is not represented in the in-process model")
    i_max = float(iso.get("i_max", 3.0))
    if gains is None:
        gains = DEFAULT_GAINS
    return SystemSetup(motion, building, GeneralizedCoefficients(**coeffs), int(iso.get("n_isolators", 2)), i_max,
                       passive_current, gains)
