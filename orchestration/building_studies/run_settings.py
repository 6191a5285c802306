"""What every co-simulation of a building study gets and must keep: the study's overrides and current limit,
the variables it records, and a results file with every step (the studies' criteria are computed from it)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

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


def every_step_problem(sim: Any) -> str | None:
    """Why a study cannot run a scenario whose results file is decimated or not CSV (None: it can): its criteria
    are computed from every step of each run's ``timeseries.csv``."""
    if sim.output_interval == 1 and sim.output_format == "csv":
        return None
    return (f"simulation.output_interval = {sim.output_interval}, output_format = {sim.output_format}: a study "
            "computes its criteria from every step of its runs' timeseries.csv, so its runs need the defaults "
            "(1, csv); set them on single runs (run.py)")
