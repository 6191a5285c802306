"""A suite benchmark's file: an IDA study (suite, window, intensity, strategies) with a ``benchmark:`` section.

The section (:class:`SuiteBenchmarkSpec`) says which events train the tuner (a list, or a seeded draw of a count),
which are scored (default: every other event), which strategies are tuned, with what budget, seed and objective,
and which criteria the verdict compares. Read with the project's YAML loader (file and line of every key), every
problem of the IDA part and of the section collected together.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError, field_validator, model_validator

from orchestration.building_studies.study_file import apply_overrides
from orchestration.case_study.case_config import ObjectiveSpec
from orchestration.ida_study.ida_config import BENCHMARK_KEY, IdaSpec, LoadedIda
from orchestration.ida_study.paired_verdict import CRITERIA
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.scenario import validation_problems
from orchestration.master.yaml_source import load_tree


class SuiteBenchmarkSpec(BaseModel):
    """The ``benchmark:`` section: the split by event, the tuning and the verdict."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    train_events: list[str] | None = None  # the suite's records the tuner sees (both components of each)
    train_count: int | None = Field(None, ge=1)  # or: this many records drawn with split_seed
    split_seed: int = Field(1, ge=0, le=2**32 - 1)
    score_events: list[str] | None = None  # the records scored (default: every record not trained on)
    overlap: StrictBool = False  # true: training records may be scored too (in-sample, declared on purpose)
    tune: list[str]  # strategies tuned, each with tunable: ranges; scored as <name>-tuned
    budget: int = Field(16, ge=1, le=100_000)  # settings per strategy, each a run per training component and level
    seed: int = Field(1, ge=0, le=2**32 - 1)  # the tuner's seed, the same for every strategy
    objective: ObjectiveSpec = Field(default_factory=ObjectiveSpec)
    criteria: list[str] = Field(default_factory=lambda: ["J3", "J4", "J5"])
    alpha: float = Field(0.05, gt=0.0, lt=1.0)  # family-wise error rate of the paired tests

    @field_validator("tune")
    @classmethod
    def _tune(cls, value: list[str]) -> list[str]:
        if not value:
            raise ValueError("tune lists no strategy")
        if len(set(value)) != len(value):
            raise ValueError(f"strategies are named twice: {value}")
        return value

    @field_validator("criteria")
    @classmethod
    def _criteria(cls, value: list[str]) -> list[str]:
        unknown = [c for c in value if c not in CRITERIA]
        if unknown or not value:
            raise ValueError(f"unknown criteria {unknown} (known: {', '.join(CRITERIA)})" if unknown else
                             "criteria lists none")
        return value

    @model_validator(mode="after")
    def _split(self) -> SuiteBenchmarkSpec:
        if (self.train_events is None) == (self.train_count is None):
            raise ValueError("give the training records as train_events: [...] or as train_count: N (drawn with "
                             "split_seed), one of the two")
        for key in ("train_events", "score_events"):
            names = getattr(self, key)
            if names is not None and (not names or len(set(names)) != len(names)):
                raise ValueError(f"{key} must name records, each once: {names}")
        o = self.objective
        if o.w_saturation or o.w_zero or o.w_mean_current:
            raise ValueError("objective: the current terms (w_saturation, w_zero, w_mean_current) are not measured "
                             "by the suite's runs: leave them at 0")
        return self


def load_benchmark(path: Path | str, overrides: tuple[str, ...] = ()
                   ) -> tuple[LoadedIda, SuiteBenchmarkSpec]:
    """The IDA part and the ``benchmark:`` section of a suite benchmark file; ScenarioError listing every problem."""
    path = Path(path).resolve()
    if not path.is_file():
        raise ScenarioError(Problem(f"study file {path} does not exist"))
    data, lines = load_tree(path)
    if not isinstance(data, dict) or not isinstance(data.get(BENCHMARK_KEY), dict):
        raise ScenarioError(Problem("a suite benchmark file is an IDA study with a 'benchmark:' mapping",
                                    BENCHMARK_KEY, str(path)))
    apply_overrides(data, lines, overrides)
    section: Any = data.pop(BENCHMARK_KEY)
    problems: list[Problem] = []
    spec = bench = None
    try:
        spec = IdaSpec.model_validate(data)
    except ValidationError as exc:
        problems += validation_problems(exc, lines, path, IdaSpec)
    try:
        bench = SuiteBenchmarkSpec.model_validate(section)
    except ValidationError as exc:
        problems += validation_problems(exc, lines, path, SuiteBenchmarkSpec, (BENCHMARK_KEY,))
    if problems or spec is None or bench is None:
        raise ScenarioError(problems)
    if spec.events is not None:
        raise ScenarioError(Problem("a suite benchmark chooses its records with benchmark.train_events and "
                                    "benchmark.score_events, not events", "events", *lines.get(("events",),
                                                                                               (str(path), None))))
    if "passive-off" not in spec.strategy_names:
        raise ScenarioError(Problem("strategies must include passive-off: every criterion is against it",
                                    "strategies", *lines.get(("strategies",), (str(path), None))))
    return LoadedIda(spec, path, lines), bench
