"""What one identification run produced: data, fits, the current-dependent model."""

from __future__ import annotations

from dataclasses import dataclass, field

from components.identification.bouc_wen_joint import JointFit
from components.identification.generalized import GeneralizedFit
from components.identification.identifiers import IdentResult
from components.identification.joint_fits import Bootstrap
from components.identification.model_selection import Selection
from components.identification.models import FitData
from components.identification.paper_tables import Condition


@dataclass
class RunResult:
    """Everything a run produced (also written to the output folder)."""

    data: dict[Condition, FitData]
    results: dict[str, dict[Condition, IdentResult]]
    generalized: dict[str, GeneralizedFit] = field(default_factory=dict)
    generalization_errors: dict[str, str] = field(default_factory=dict)
    synthetic: bool = False
    joint: JointFit | None = None
    generalized_rms: dict[str, dict[Condition, float]] = field(default_factory=dict)
    selection: list[Selection] = field(default_factory=list)
    bootstrap: Bootstrap | None = None

    @property
    def not_converged(self) -> list[IdentResult]:
        return [r for per in self.results.values() for r in per.values() if not r.converged]
