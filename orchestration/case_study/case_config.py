"""Study configuration (``scenarios/case_study.yaml``): records, strategies, sweep, tuning, reference.

A study runs every record x strategy as a co-simulation through the master. The file is
read with the project's YAML loader (file and line of every key) and validated with
pydantic; every problem is reported as a :class:`~orchestration.master.errors.ScenarioError`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError, field_validator, model_validator

from orchestration.building_studies.strategies import (
    Strategy,
    StrategyEntry,
    strategy_library,
    uncontrolled_of,
    uncontrolled_problems,
    unknown_strategies,
)
from orchestration.building_studies.study_file import REPLACED_KEYS, apply_overrides
from orchestration.case_study.robustness_config import RobustnessSpec
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.scenario import validation_problems
from orchestration.master.yaml_source import load_tree

STRATEGIES = ("passive-off", "passive-on", "best-constant", "sosm", "sosm-fig15", "on-off")  # the default list
GAIN_SETS = ("sosm", "sosm-fig15")  # the SOSM gain sets a strategy entry may name (`gains:`): the study's `gains`
# file and its second gain set, `fig15` (the names of gain sets, not of strategies)


MAX_SWEEP_POINTS = 10_001
"""Most constant currents a sweep may try (each is a co-simulation per record)."""
MAX_TUNING_EVALS = 100_000
"""Most Latin-hypercube samples, and most Nelder-Mead evaluations, of a tuning (each a simulation per record)."""
MAX_TIMEOUT_S = 7 * 86400.0
"""Longest per-process timeout [s] a study may set (a week): a timeout is a bound, not a wish."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # no NaN or infinity anywhere


class SweepSpec(_Strict):
    """Constant currents [A] tried for the best constant current (in-process, per record)."""

    start: float = 0.0
    stop: float | None = None  # None: i_max
    step: float = 0.25

    def currents(self, i_max: float) -> list[float]:
        """The swept currents [A], from start to stop (default i_max) inclusive."""
        stop = i_max if self.stop is None else self.stop
        n = round((stop - self.start) / self.step)
        return [round(self.start + k * self.step, 10) for k in range(n + 1)]

    @model_validator(mode="after")
    def _check(self) -> SweepSpec:
        if not self.step > 0:
            raise ValueError(f"sweep.step must be positive, got {self.step}")
        if self.start < 0 or (self.stop is not None and self.stop < self.start):
            raise ValueError("sweep needs 0 <= start <= stop")
        if self.stop is not None and (self.stop - self.start) / self.step + 1 > MAX_SWEEP_POINTS:
            raise ValueError(f"the sweep from {self.start:g} A to {self.stop:g} A in steps of {self.step:g} A tries "
                             f"more than {MAX_SWEEP_POINTS:,} currents; use a larger sweep.step")
        return self


class ObjectiveSpec(_Strict):
    """J = w_acc a3/a3_off + w_drift d/d_off + penalty max(0, x0/x_limit - 1)
    + w_saturation s_bound + w_zero s_zero + w_mean_current i_mean/i_max (dimensionless).

    s_bound: share of the run's time with the current at the controller's limit i_max;
    s_zero: share at 0 A; i_mean: mean current [A]. The current terms are 0 by default (peaks only).
    """

    w_acc: float = 0.5
    w_drift: float = 0.5
    penalty: float = 10.0
    x_limit: float = 0.015  # m, the isolator's device limit
    w_saturation: float = 0.0
    w_zero: float = 0.0
    w_mean_current: float = 0.0

    @model_validator(mode="after")
    def _check(self) -> ObjectiveSpec:
        if min(self.w_acc, self.w_drift, self.penalty, self.w_saturation, self.w_zero, self.w_mean_current) < 0:
            raise ValueError("objective weights must not be negative")
        if not self.x_limit > 0:
            raise ValueError(f"objective.x_limit must be positive, got {self.x_limit}")
        return self


class TuningSpec(_Strict):
    """How the SOSM gains are tuned (orchestration/case_study/tuning.py); see docs/case_study.md."""

    record: str | list[str] = "elcentro"  # one record, or several: J is then their mean
    stop_time: float | None = None  # s; None: the record scenario's own stop time (every tuning record)
    seed: int = Field(1, ge=0, lt=2**32)
    n_samples: int = Field(24, ge=1, le=MAX_TUNING_EVALS)  # seeded Latin-hypercube samples
    max_evals: int = Field(80, ge=0, le=MAX_TUNING_EVALS)  # Nelder-Mead evaluations from the best sample
    # lam [1/s], rho [A/s], theta [m^0.5 s^-1.5], ratio = zeta theta / rho [-]; optional s_release [m/s]: the
    # release band (not in the paper) is then tuned too, else it stays 0 (the paper's law)
    bounds: dict[str, tuple[float, float]] = Field(default_factory=lambda: {
        "lam": (0.5, 50.0), "rho": (1.0, 200.0), "theta": (0.05, 20.0), "ratio": (1.05, 100.0)})

    @property
    def records(self) -> list[str]:
        """The tuning records, in order."""
        return [self.record] if isinstance(self.record, str) else list(self.record)

    @field_validator("stop_time")
    @classmethod
    def _stop_time(cls, value: float | None) -> float | None:
        if value is not None and not value > 0:
            raise ValueError(f"tuning.stop_time must be positive (s), got {value}")
        return value

    @field_validator("record")
    @classmethod
    def _record(cls, value: str | list[str]) -> str | list[str]:
        if isinstance(value, list) and (not value or len(set(value)) != len(value)):
            raise ValueError("tuning.record needs at least one record, each once")
        return value

    @field_validator("bounds")
    @classmethod
    def _bounds(cls, value: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
        if set(value) - {"s_release"} != {"lam", "rho", "theta", "ratio"}:
            raise ValueError("tuning.bounds needs exactly lam, rho, theta, ratio and optionally s_release")
        for key, (lo, hi) in value.items():
            if not 0 < lo < hi:
                raise ValueError(f"tuning.bounds.{key} needs 0 < low < high, got {lo}, {hi}")
        if value["ratio"][0] <= 1.0:
            raise ValueError("tuning.bounds.ratio (zeta*theta/rho) must stay above 1 (Eq. 39)")
        return value


class StrategyTuningSpec(_Strict):
    """Which strategies ``tune.py`` tunes alike (:mod:`orchestration.case_study.strategy_tuner`), on what, how long.

    Each listed strategy's ``tunable:`` parameters are searched by differential evolution with the same ``budget``
    (parameter settings, each one co-simulation per record, the first ``stop_time`` seconds) and the same ``seed``,
    against the study's ``objective``; the tuned entries are written as a strategy file, ``output`` (relative to the
    study's ``output`` folder).
    """

    strategies: list[str] = Field(min_length=1)  # names of strategy entries that declare tunable:
    record: str | list[str] = "elcentro"  # the training records: J is their mean
    stop_time: float | None = Field(20.0, gt=0.0)  # s, every training run's length; None: each record's own
    budget: int = Field(40, ge=1, le=MAX_TUNING_EVALS)  # parameter settings tried per strategy (>= parameters + 1)
    seed: int = Field(1, ge=0, lt=2**32)  # one seed for every strategy
    output: str = "tuned_strategies.yaml"  # the strategy file written, in the study's output folder

    @property
    def records(self) -> list[str]:
        """The training records, in order."""
        return [self.record] if isinstance(self.record, str) else list(self.record)

    @field_validator("record")
    @classmethod
    def _record(cls, value: str | list[str]) -> str | list[str]:
        if isinstance(value, list) and (not value or len(set(value)) != len(value)):
            raise ValueError("strategy_tuning.record needs at least one record, each once")
        return value

    @field_validator("strategies")
    @classmethod
    def _strategies(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise ValueError("strategy_tuning.strategies lists a strategy twice")
        return value


class GainSetSpec(_Strict):
    """The second SOSM gain set (strategy ``sosm-fig15``): its own current limit, objective and tuning.

    Tuned by ``python orchestration/tune.py STUDY --gain-set sosm-fig15 --force`` into ``gains``.
    """

    gains: str = "sosm_gains_fig15.yaml"
    i_max: float = 2.5  # A: the controller's limit (the isolator keeps the study's i_max)
    objective: ObjectiveSpec = Field(default_factory=lambda: ObjectiveSpec(w_saturation=1.0))
    tuning: TuningSpec = Field(default_factory=TuningSpec)

    @model_validator(mode="after")
    def _check(self) -> GainSetSpec:
        if not (np.isfinite(self.i_max) and self.i_max > 0):
            raise ValueError(f"fig15.i_max must be positive, got {self.i_max}")
        return self


class BenchmarkSpec(_Strict):
    """The controller benchmark's criteria (Narasimhan et al. 2006): criteria.csv and its report sections."""

    baseline: str = "passive-off"  # J1...J9 are ratios to this strategy's values
    second_baseline: str | None = "passive-on"  # the same table normalised by this one too
    best_constant: str = "best-constant"  # the strategy every other one is judged against
    j6_reference: str = "passive-on"  # J6 (the controllable force) is over this strategy's, on the same record


class ReferenceSpec(_Strict):
    """Monolithic Radau reference of the passive strategies (constant currents)."""

    enabled: StrictBool = True  # true or false, not "yes" or 1
    rtol: float = 1e-8
    tolerance: float = 0.25  # largest relative peak error accepted (README, coupling error)


class FigureUnitsSpec(_Strict):
    """The study figures' axes: acceleration in m/s2 or g (standard gravity), drift in mm or as the drift ratio
    drift_j / h_j in % (``storey_heights`` h_j [m] of storeys 1..n). The tables stay in SI."""

    acceleration: Literal["m/s2", "g"] = "m/s2"
    drift: Literal["mm", "ratio"] = "mm"
    storey_heights: list[float] | None = None

    @field_validator("storey_heights", mode="before")
    @classmethod
    def _heights(cls, value: Any) -> Any:
        numbers = isinstance(value, list) and all(isinstance(h, int | float) and not isinstance(h, bool)
                                                  for h in value)
        if value is not None and not (numbers and value and all(np.isfinite(h) and h > 0 for h in value)):
            raise ValueError(f"storey heights must be finite positive lengths [m], one per storey, got {value}")
        return value

    @model_validator(mode="after")
    def _ratio(self) -> FigureUnitsSpec:
        if self.drift == "ratio" and not self.storey_heights:
            raise ValueError("drift: ratio needs storey_heights [m], one per storey (drift_j / h_j)")
        return self


class StudySpec(_Strict):
    """A whole study, as written in the YAML file (paths relative to it)."""

    name: str = "case_study"
    description: str = ""
    records: dict[str, str]
    strategies: list[str] = Field(default_factory=lambda: list(STRATEGIES))  # names of strategy entries
    strategy_files: list[str] = Field(default_factory=list)  # more strategy files, over the shipped one
    strategy_definitions: dict[str, StrategyEntry] = Field(default_factory=dict)  # strategies of this file
    benchmark: BenchmarkSpec | None = None  # criteria.csv and the benchmark's report sections
    robustness: RobustnessSpec | None = None  # variants of plant and sensors (robustness.csv), needs benchmark
    overrides: list[str] = Field(default_factory=list)
    i_max: float = 3.0
    paper_current_range: tuple[float, float] = (0.0, 2.5)
    x_identified: float = Field(0.008, gt=0.0)  # m
    x_limit: float = Field(0.015, gt=0.0)  # m
    gains: str = "sosm_gains.yaml"
    sweep: SweepSpec = Field(default_factory=SweepSpec)
    objective: ObjectiveSpec = Field(default_factory=ObjectiveSpec)
    tuning: TuningSpec = Field(default_factory=TuningSpec)
    fig15: GainSetSpec = Field(default_factory=GainSetSpec)  # the second gain set (strategy sosm-fig15)
    strategy_tuning: StrategyTuningSpec | None = None  # tune.py: tune these strategies alike (not the SOSM gains)
    reference: ReferenceSpec = Field(default_factory=ReferenceSpec)
    figure_units: FigureUnitsSpec = Field(default_factory=FigureUnitsSpec)  # the figures' axes (tables stay SI)
    # each run folder keeps its time series (as the runs' simulation.output_interval and output_format say); the
    # tables and criteria come from every step, computed in each run, either way (case_study/run_numbers.py)
    timeseries: StrictBool = False
    workers: int | None = None  # local cluster: worker processes (None: one per core)
    max_worker_deaths: int = 2  # a job whose worker dies is run again elsewhere at most this many times
    timeout_s: float | None = Field(1800.0, gt=0.0, le=MAX_TIMEOUT_S)  # [s] per co-simulation process (a bound)
    output: str = "studies"

    @model_validator(mode="after")
    def _check(self) -> StudySpec:
        if not self.records:
            raise ValueError("a study needs at least one record")
        if len(set(self.strategies)) != len(self.strategies):
            raise ValueError("strategies are listed twice")
        if not (np.isfinite(self.i_max) and self.i_max > 0):
            raise ValueError(f"i_max must be positive, got {self.i_max}")
        if self.workers is not None and self.workers < 1:
            raise ValueError("workers must be at least 1")
        if self.max_worker_deaths < 0:
            raise ValueError("max_worker_deaths must not be negative")
        low, high = self.paper_current_range
        if not 0 <= low <= high:
            raise ValueError(f"paper_current_range needs 0 <= low <= high (A), got {low:g}, {high:g}")
        if self.sweep.stop is None and (self.i_max - self.sweep.start) / self.sweep.step + 1 > MAX_SWEEP_POINTS:
            raise ValueError(f"the sweep from {self.sweep.start:g} A to i_max = {self.i_max:g} A in steps of "
                             f"{self.sweep.step:g} A tries more than {MAX_SWEEP_POINTS:,} currents; use a larger "
                             "sweep.step")
        if self.robustness is not None and self.benchmark is None:
            raise ValueError("robustness needs a benchmark section (its criteria are normalised by the benchmark's "
                             "baseline)")
        unknown = [s for s in (self.robustness.strategies or []) if s not in self.strategies] if self.robustness else []
        if unknown:
            raise ValueError(f"robustness.strategies: {', '.join(map(repr, unknown))} not among the study's strategies "
                             f"({', '.join(self.strategies)})")
        if self.fig15.i_max > self.i_max:
            raise ValueError(f"fig15.i_max ({self.fig15.i_max} A) must not exceed i_max ({self.i_max} A)")
        return self


def variant_strategies(spec: StudySpec) -> list[str]:
    """The strategies that run under the robustness variants: ``robustness.strategies``, else all the study's."""
    rob = spec.robustness
    return [] if rob is None else list(rob.strategies) if rob.strategies is not None else list(spec.strategies)


class LoadedStudy:
    """A validated study with its file (paths in it are relative to that file)."""

    def __init__(self, spec: StudySpec, path: Path, raw: dict[str, Any], lines: dict | None = None) -> None:
        self.spec = spec
        self.path = path
        self.raw = raw
        self.lines = lines or {}
        self._library: dict[str, Strategy] | None = None

    @property
    def library(self) -> dict[str, Strategy]:
        """Every strategy the study may name: the shipped file, its strategy_files, its own definitions."""
        if self._library is None:
            files = [Path(f) if Path(f).is_absolute() else self.base_dir("strategy_files", k) / f
                     for k, f in enumerate(self.spec.strategy_files)]
            self._library = strategy_library(files, self.spec.strategy_definitions, self.path, self.lines)
        return self._library

    def base_dir(self, *key: Any) -> Path:
        """Folder that a relative path at ``key`` is relative to: that of the file that wrote the key (a study
        reached through ``extends`` keeps its own folder); this study file's folder for ``--set`` and defaults."""
        file, _ = self.lines.get(tuple(key), ("", None))
        return Path(file).parent if file and not file.startswith("--set") and Path(file).is_file() else self.path.parent

    def strategy(self, name: str) -> Strategy:
        """A strategy the study names."""
        return self.library[name]

    @property
    def uncontrolled(self) -> str:
        """The study's uncontrolled strategy: the one listed whose entry says ``uncontrolled: true`` (checked
        to be one when the file is read)."""
        name = uncontrolled_of(self.spec.strategies, self.library)
        if name is None:
            raise ScenarioError(uncontrolled_problems(self.spec.strategies, self.library, self.lines, self.path,
                                                      "strategies"))
        return name

    @property
    def needs_sweep(self) -> bool:
        """Whether a listed strategy takes the record's best constant current: the sweep runs first."""
        return any(self.strategy(s).needs_sweep for s in self.spec.strategies)

    def scenario_path(self, record: str) -> Path:
        """Scenario file of a record (absolute)."""
        p = Path(self.spec.records[record])
        return p if p.is_absolute() else (self.base_dir("records", record) / p).resolve()

    @property
    def gains_path(self) -> Path:
        """The SOSM gains file written by the tuning procedure (absolute)."""
        return self.gain_set_path("sosm")

    def gain_set_path(self, gain_set: str) -> Path:
        """The gains file of an SOSM gain set (``sosm``: the study's ``gains``; ``sosm-fig15``: ``fig15.gains``),
        absolute."""
        key = ("gains",) if gain_set == "sosm" else ("fig15", "gains")
        p = Path(self.spec.gains if gain_set == "sosm" else self.spec.fig15.gains)
        return p if p.is_absolute() else (self.base_dir(*key) / p).resolve()

    def gain_set(self, gain_set: str) -> tuple[float, ObjectiveSpec, TuningSpec]:
        """Controller current limit [A], objective and tuning of an SOSM gain set."""
        if gain_set == "sosm":
            return self.spec.i_max, self.spec.objective, self.spec.tuning
        return self.spec.fig15.i_max, self.spec.fig15.objective, self.spec.fig15.tuning


def load_study(path: Path | str, overrides: tuple[str, ...] = ()) -> LoadedStudy:
    """Read and validate a study file; ``overrides`` are ``KEY=VALUE`` (VALUE as YAML). Raises ScenarioError."""
    path = Path(path).resolve()
    if not path.is_file():
        raise ScenarioError(f"study file {path} does not exist")
    data, lines = load_tree(path, replace=REPLACED_KEYS)
    apply_overrides(data, lines, overrides)
    try:
        spec = StudySpec.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(validation_problems(exc, lines, path, StudySpec)) from None
    study = LoadedStudy(spec, path, data, lines)
    missing = [Problem(f"scenario file {study.scenario_path(r)} does not exist", f"records.{r}", str(path))
               for r in spec.records if not study.scenario_path(r).is_file()]
    for k, f in enumerate(spec.strategy_files):
        p = Path(f) if Path(f).is_absolute() else study.base_dir("strategy_files", k) / f
        if not p.is_file():
            file, line = lines.get(("strategy_files", k), (str(path), None))
            missing.append(Problem(f"strategy file {p.resolve()} does not exist", f"strategy_files.{k}", file, line))
    if not missing:
        missing = unknown_strategies(spec.strategies, study.library, lines, path, "strategies")
    if not missing and spec.strategy_tuning is not None:
        missing = unknown_strategies(spec.strategy_tuning.strategies, study.library, lines, path,
                                     "strategy_tuning.strategies")
    if not missing:
        missing = (uncontrolled_problems(spec.strategies, study.library, lines, path, "strategies")
                   + folder_name_problems(study) + reference_problems(study) + benchmark_problems(study))
    if missing:
        raise ScenarioError(missing)
    return study


def reference_problems(study: LoadedStudy) -> list[Problem]:
    """A listed strategy marked ``radau_reference`` whose current is not a constant known before the runs (the
    Radau reference integrates the same equations at that constant current), at the strategy's line."""
    out = []
    for k, s in enumerate(study.spec.strategies):
        strategy = study.strategy(s)
        if strategy.entry.radau_reference and (strategy.needs_sweep or strategy.constant_current(1.0, None) is None):
            file, line = study.lines.get(("strategies", k)) or (str(study.path), None)
            out.append(Problem(f"strategy {s!r} is marked radau_reference, but its current is not a constant known "
                               "before the runs (the scenario's controller in passive mode, i_passive a number or "
                               "${i_max})", f"strategies.{k}", file or str(study.path), line))
    return out


def benchmark_problems(study: LoadedStudy) -> list[Problem]:
    """The benchmark's baselines, best constant current and J6 reference, each a strategy the study knows (one the
    study does not list leaves its columns or verdicts empty, as the report says)."""
    bench = study.spec.benchmark
    if bench is None:
        return []
    out = []
    for key in ("baseline", "second_baseline", "best_constant", "j6_reference"):
        name = getattr(bench, key)
        if name is not None and name not in study.library:
            file, line = study.lines.get(("benchmark", key)) or study.lines.get(("benchmark",)) or (
                str(study.path), None)
            out.append(Problem(f"unknown strategy {name!r} (known: {', '.join(study.library)})",
                               f"benchmark.{key}", file or str(study.path), line))
    return out


RUN_FILE_RESERVE = 48
"""Bytes kept after a run folder's name for the study's own suffixes (``.tmp`` staging names)."""


def folder_name_problems(study: LoadedStudy) -> list[Problem]:
    """The ids that name run folders (``runs/<record>-<strategy>[--<variant>]``), checked to be plain names
    within the file system's byte limit, at their keys' lines, before anything is written."""
    from mre_common.fs_limits import name_problem, plain_name_problem

    spec, lines, out = study.spec, study.lines, []

    def add(message: str, *key: Any) -> None:
        file, line = lines.get(tuple(key)) or lines.get(tuple(key[:1])) or (str(study.path), None)
        out.append(Problem(message, ".".join(str(k) for k in key), file or str(study.path), line))

    for r in spec.records:
        if (problem := plain_name_problem(r)) is not None:
            add(f"record id {problem}", "records", r)
    for k, s in enumerate(spec.strategies):
        if (problem := plain_name_problem(s)) is not None:
            add(f"strategy {problem}", "strategies", k)
    if out:
        return out
    variants = [""] + [f"--{v}" for v in (spec.robustness.variant_names() if spec.robustness else [])]
    longest = max(variants, key=lambda v: len(os.fsencode(v)))
    folder = Path(spec.output)
    for r in spec.records:
        for k, s in enumerate(spec.strategies):
            problem = name_problem(f"{r}-{s}{longest}", folder, RUN_FILE_RESERVE)
            if problem is not None:
                add(f"run folder runs/{r[:30]}-{s[:30]}{longest[:30]}: {problem}", "strategies", k)
                return out
    return out
