"""What every co-simulation of a building study gets: the study's overrides and current limit, and the variables
it records (the studies compute their criteria from every recorded step, in the run: case_study/run_numbers.py,
ida_study/ida_jobs.py)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

# Recorded variables of every co-simulation of a study (the report roles are added by the master).
RECORDED = ("building.x_0", "building.v_0", "building.drift_1", "building.drift_2", "building.drift_3",
            "building.a_0", "building.a_1", "building.a_2", "building.a_3", "building.shear_1",
            "building.shear_2", "building.shear_3", "isolator.F", "controller.i")


class StudyRuns(Protocol):
    """The settings of a study that every run gets (a case study's StudySpec has them)."""

    @property
    def overrides(self) -> Sequence[str]: ...

    @property
    def i_max(self) -> float: ...


def run_overrides(spec: StudyRuns) -> tuple[str, ...]:
    """Overrides every run of a study gets: the study's own, then the current limit of both units."""
    return (*spec.overrides, f"isolator.i_max={spec.i_max}", f"controller.i_max={spec.i_max}")
