"""The in-process model of a planned scenario: the paper's system (ground, shear building, MRE isolator, SOSM
controller) as :class:`~components.physics.monolithic.SystemSetup`, for the Radau reference, the current sweep,
the gain tuning and the IDA's isolated period.

:func:`monolithic_problem` says why a scenario is not that system; :func:`system_setup` builds the model or raises
:class:`NotMonolithic`; :func:`structure_setup` builds its building and isolators alone (no record read), for a
run's periods.
"""

from __future__ import annotations

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.monolithic import SystemSetup
from components.physics.sosm_controller_core import HAND_PICKED_GAINS, SosmGains
from orchestration.building_studies.isolated_structure import (
    MONOLITHIC_UNITS,
    IsolatedStructure,
    NotMonolithic,
    structure_setup,
    units_problem,
)
from orchestration.master.resolve import SystemPlan

DEFAULT_GAINS = HAND_PICKED_GAINS  # the hand-picked gains: the tuning's first point
__all__ = ["DEFAULT_GAINS", "MONOLITHIC_UNITS", "IsolatedStructure", "NotMonolithic", "monolithic_problem",
           "structure_setup", "system_setup", "units_problem"]


def monolithic_problem(plan: SystemPlan) -> str | None:
    """Why the in-process model cannot represent a planned scenario (another isolator FMU, a unit it lacks, such
    as a coil lag), or None. The controller's FMU does not matter for a constant current."""
    return units_problem({unit: desc.model_identifier for unit, desc in plan.descriptions.items()})


def system_setup(plan: SystemPlan, passive_current: float | None, gains: SosmGains | None = None) -> SystemSetup:
    """In-process model of a planned scenario; ``passive_current`` None means SOSM with ``gains``.

    NotMonolithic when the scenario is not the paper's system (:func:`monolithic_problem`) or sets parameters
    the model does not represent."""
    problem = monolithic_problem(plan)
    if problem is not None:
        raise NotMonolithic(f"{problem}: the in-process model (the Radau reference, the tuning) is the paper's system "
                            "only (a study on another plant: reference.enabled: false)")
    structure = structure_setup({unit: desc.model_identifier for unit, desc in plan.descriptions.items()},
                                plan.parameters)
    ground = plan.parameters.get("ground", {})
    motion = GroundMotion(read_record(plan.data_files["ground.record"]), scale=float(ground.get("scale", 1.0)),
                          time_scale=float(ground.get("time_scale", 1.0)))
    if gains is None:
        gains = DEFAULT_GAINS
    return SystemSetup(motion, structure.building, structure.coeffs, structure.n_isolators, structure.i_max,
                       passive_current, gains)
