"""A suite benchmark's file: an IDA study (suite, window, intensity, strategies) with a ``benchmark:`` section.

The section (:class:`SuiteBenchmarkSpec`) says which events train the tuner (``train``: a list, or a count drawn
with ``split_seed``),
which are scored (default: every other event), which strategies are tuned, with what budget, seed and objective,
and which criteria the verdict compares. Read with the project's YAML loader (file and line of every key), every
problem of the IDA part and of the section collected together.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    ValidationError,
    field_validator,
    model_validator,
)

from orchestration.building_studies.strategies import uncontrolled_problems
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

    train: list[str] | StrictInt  # the records the tuner sees (both components of each), or how many split_seed draws
    split_by: Literal["record", "earthquake"] = "record"  # earthquake: every earthquake's records on one side
    split_seed: int = Field(1, ge=0, le=2**32 - 1)
    score: list[str] | None = None  # the records scored (default: every record not trained on)
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

    @field_validator("train", "score")
    @classmethod
    def _records(cls, value: list[str] | int | None) -> list[str] | int | None:
        if isinstance(value, list) and (not value or len(set(value)) != len(value)):
            raise ValueError(f"name records, each once: {value}")
        if isinstance(value, int) and value < 1:
            raise ValueError(f"a count of training records must be at least 1, got {value}")
        return value

    @model_validator(mode="after")
    def _split(self) -> SuiteBenchmarkSpec:
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
        raise ScenarioError(Problem("a suite benchmark chooses its records with benchmark.train and "
                                    "benchmark.score, not events", "events", *lines.get(("events",),
                                                                                               (str(path), None))))
    loaded = LoadedIda(spec, path, lines)
    problems = loaded.strategy_problems()  # unknown names first: then the uncontrolled case, which every criterion
    if not problems and loaded.uncontrolled is None:  # is over
        problems = uncontrolled_problems([s for s in spec.strategies if isinstance(s, str)], loaded.library, lines,
                                         path, "strategies")
    if problems:
        raise ScenarioError(problems)
    return loaded, bench
