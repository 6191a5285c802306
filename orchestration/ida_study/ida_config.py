"""An IDA study file (``scenarios/ida.yaml``): suite, window, time scale, intensity ladder, strategies, limit states.

Read with the project's YAML loader (file and line of every key) and validated with
pydantic (unknown keys refused). Every problem -- of the file, of the suite (unknown name,
a folder without a readable record), of the strategies and the gains -- is collected into
one :class:`~orchestration.master.errors.ScenarioError` before anything is computed.

Strategies are the case study's strategy entries (:mod:`orchestration.building_studies.strategies`):
the shipped ``scenarios/strategies.yaml``, then the study's ``strategy_files``, then its
``strategy_definitions`` (:attr:`LoadedIda.library`); ``{name, overrides}`` entries stay as before.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError, field_validator, model_validator

from orchestration.building_studies.strategies import (
    Strategy,
    StrategyEntry,
    strategy_library,
    uncontrolled_of,
)
from orchestration.building_studies.study_file import apply_overrides
from orchestration.ida_study.suites import DEFAULT_PATTERNS, KNOWN_SUITES
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.scenario import validation_problems
from orchestration.master.yaml_source import load_tree

# Why a strategy that needs the case study's best constant current cannot be an IDA strategy.
NO_BEST_CONSTANT = ("is the case study's best constant current, chosen per record by a sweep over the whole record "
                    "(an oracle no controller can be); an IDA has no such sweep (it would be another current at "
                    "every record and intensity): name a fixed current instead, e.g. strategy_definitions: "
                    "{hold-1.5A: {parameters: {mode: passive, i_passive: 1.5}}}")
# limit-state quantity -> (column of the results table, factor to SI, unit)
QUANTITIES = {
    "isolator_displacement": ("x_base_mm", 1e-3, "m"),
    "storey_drift": ("drift_max_mm", 1e-3, "m"),
    "floor_acceleration": ("acc_max", 1.0, "m/s²"),
    "residual_drift": ("residual_drift_max_mm", 1e-3, "m"),  # largest |residual drift| at the end of the run
    "drift_ratio": ("drift_ratio_max", 1.0, "1"),  # largest peak drift_j / h_j (storey_heights)
    "collapse": ("drift_ratio_max", 1.0, "1"),  # a drift ratio, or a run that collapsed (COLLAPSED_STATUS)
}
# Quantities measured against the storey heights (the study's ``storey_heights``).
RATIO_QUANTITIES = ("drift_ratio", "collapse")


BENCHMARK_KEY = "benchmark"  # the section of a suite benchmark (orchestration.suite_benchmark), run by study.py
MAX_LEVELS = 1000
"""Most intensity levels of a ladder (each is a run per record component and strategy)."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)  # no NaN or infinity anywhere


class FolderSuite(_Strict):
    """The record files of a folder (relative to the study file)."""

    folder: str
    patterns: list[str] = Field(default_factory=lambda: list(DEFAULT_PATTERNS))


class WindowSpec(_Strict):
    """Which part of each record runs: the strong-motion window (else the whole record), then free vibration."""

    strong_motion: StrictBool = True  # true or false, not "yes" or 1
    tail_s: float = Field(2.0, ge=0.0)  # [s] simulated after the window ends (ground at rest)


class IntensitySpec(_Strict):
    """The ladder of intensity levels every record is scaled to."""

    measure: Literal["pga", "sa"] = "sa"
    levels: list[float]  # [g], strictly increasing
    damping: float = Field(0.05, ge=0.0, lt=1.0)  # Sa only
    period_s: float | None = None  # Sa only; None: the isolated period computed from the scenario
    period_current_A: float = Field(0.0, ge=0.0)  # [A] reference current of the isolated period
    period_displacement_m: float = Field(0.008, ge=0.0)  # [m] secant stiffness at this displacement (0: tangent)

    @field_validator("levels")
    @classmethod
    def _ladder(cls, value: list[float]) -> list[float]:
        if not value:
            raise ValueError("the intensity ladder needs at least one level")
        if len(value) > MAX_LEVELS:
            raise ValueError(f"the intensity ladder has {len(value):,} levels: at most {MAX_LEVELS:,}")
        bad = [v for v in value if not (math.isfinite(v) and v > 0)]
        if bad:
            raise ValueError(f"intensity levels must be positive numbers, got {bad}")
        drops = [f"{b:g} after {a:g}" for a, b in itertools.pairwise(value) if not b > a]
        if drops:
            raise ValueError(f"the intensity ladder must increase strictly: {', '.join(drops)}")
        return value

    @field_validator("period_s")
    @classmethod
    def _period(cls, value: float | None) -> float | None:
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"period_s must be positive, got {value}")
        return value


class LimitStateSpec(_Strict):
    """Exceeded when the run's peak ``quantity`` goes beyond ``threshold`` (SI: m, m, m/s²)."""

    quantity: Literal["isolator_displacement", "storey_drift", "floor_acceleration", "residual_drift",
                      "drift_ratio", "collapse"]
    threshold: float = Field(gt=0.0)
    label: str = ""


class CollapseMarginSpec(_Strict):
    """FEMA P695's S_MT: the MCE spectral acceleration at the building's period [g], and where it comes from.

    Collapse margin ratio CMR = S_CT / S_MT, S_CT the median collapse intensity (FEMA P695, 2009,
    *Quantification of Building Seismic Performance Factors*, section 6.3). Needs ``intensity.measure: sa``.
    """

    s_mt: float = Field(gt=0.0)  # [g]
    source: str  # the design spectrum and period it is read from


class CustomStrategy(_Strict):
    """A strategy defined by scenario overrides (e.g. a unit swap: ``units.controller.fmu=...``)."""

    name: str
    overrides: list[str]


class IdaSpec(_Strict):
    """A whole IDA study, as written in the YAML file (paths relative to it)."""

    name: str = "ida"
    description: str = ""
    scenario: str = "isolated_building.yaml"  # the system; each run sets ground.record, scale and time_scale
    suite: str | FolderSuite
    events: list[str] | None = None  # the suite's records (events) to run, by id (FF01, ...); None: every one
    time_scale: float = Field(1.0, gt=0.0)  # a record sample at tau plays at time_scale * tau
    window: WindowSpec = Field(default_factory=WindowSpec)
    intensity: IntensitySpec
    strategies: list[str | CustomStrategy] = Field(default_factory=lambda: ["passive-off", "passive-on", "sosm"])
    strategy_files: list[str] = Field(default_factory=list)  # more strategy files, over scenarios/strategies.yaml
    strategy_definitions: dict[str, StrategyEntry] = Field(default_factory=dict)  # strategies of this file
    limit_states: dict[str, LimitStateSpec]
    storey_heights: list[float] | None = None  # [m] h_j of storeys 1..n: for drift_ratio and collapse
    collapse_margin: CollapseMarginSpec | None = None  # S_MT for FEMA P695's CMR (else the ratio to the records)
    overrides: list[str] = Field(default_factory=list)
    i_max: float = Field(3.0, gt=0.0)
    gains: str = "sosm_gains.yaml"
    fig15_gains: str = "sosm_gains_fig15.yaml"  # the gain set of strategy entries with gains: sosm-fig15
    confidence: float = Field(0.95, gt=0.0, lt=1.0)
    workers: int | None = Field(None, ge=1)
    max_worker_deaths: int = Field(2, ge=0)
    timeout_s: float | None = Field(900.0, gt=0.0, le=7 * 86400.0)  # [s] per run: a bound (at most a week)
    output: str = "studies"

    @field_validator("suite", mode="before")
    @classmethod
    def _suite(cls, value: Any) -> Any:
        if isinstance(value, str) and value not in KNOWN_SUITES:
            raise ValueError(f"unknown suite {value!r} (known: {', '.join(KNOWN_SUITES)}; or a folder: "
                             "{folder: PATH})")
        return value

    @field_validator("events")
    @classmethod
    def _events(cls, value: list[str] | None) -> list[str] | None:
        if value is not None and not value:
            raise ValueError("events lists no record: leave it out to run every record of the suite")
        if value is not None and len(set(value)) != len(value):
            raise ValueError(f"events are named twice: {value}")
        return value

    @field_validator("strategies")
    @classmethod
    def _strategies(cls, value: list[str | CustomStrategy]) -> list[str | CustomStrategy]:
        names = [s if isinstance(s, str) else s.name for s in value]
        if not names:
            raise ValueError("a study needs at least one strategy")
        if len(set(names)) != len(names):
            raise ValueError(f"strategies are named twice: {names}")
        return value

    @field_validator("limit_states")
    @classmethod
    def _limit_states(cls, value: dict[str, LimitStateSpec]) -> dict[str, LimitStateSpec]:
        if not value:
            raise ValueError("a study needs at least one limit state")
        return value

    @model_validator(mode="after")
    def _period_needed(self) -> IdaSpec:
        if self.intensity.measure == "pga" and self.intensity.period_s is not None:
            raise ValueError("intensity.period_s is for measure 'sa' only")
        ratios = [n for n, ls in self.limit_states.items() if ls.quantity in RATIO_QUANTITIES]
        if ratios and not self.storey_heights:
            raise ValueError(f"limit states {ratios} are drift ratios: give storey_heights [m], one per storey")
        if self.storey_heights is not None and not all(math.isfinite(h) and h > 0 for h in self.storey_heights):
            raise ValueError(f"storey_heights must be positive lengths [m], got {self.storey_heights}")
        if self.collapse_margin is not None and self.intensity.measure != "sa":
            raise ValueError("collapse_margin (FEMA P695's S_MT) needs intensity.measure 'sa'")
        return self

    @property
    def strategy_names(self) -> list[str]:
        return [s if isinstance(s, str) else s.name for s in self.strategies]


class LoadedIda:
    """A validated IDA study with its file (paths in it are relative to that file)."""

    def __init__(self, spec: IdaSpec, path: Path, lines: dict | None = None) -> None:
        self.spec = spec
        self.path = path
        self.lines = lines or {}
        self._library: dict[str, Strategy] | None = None

    def base_dir(self, *key: Any) -> Path:
        """Folder that a relative path at ``key`` is relative to: that of the file that wrote the key (a study
        reached through ``extends`` keeps its own folder); this study file's folder for ``--set`` and defaults."""
        file, _ = self.lines.get(tuple(key), ("", None))
        return Path(file).parent if file and not file.startswith("--set") and Path(file).is_file() else self.path.parent

    def resolve(self, name: str, *key: Any) -> Path:
        """A path of the study (``key``: where the file sets it), absolute."""
        p = Path(name)
        return p if p.is_absolute() else (self.base_dir(*key) / p).resolve()

    def strategy_file(self, k: int) -> Path:
        """The ``k``-th of ``strategy_files``, absolute."""
        return self.resolve(self.spec.strategy_files[k], "strategy_files", k)

    @property
    def library(self) -> dict[str, Strategy]:
        """Every strategy entry the study may name, as the case study reads them: the shipped file
        (``scenarios/strategies.yaml``), then its ``strategy_files``, then its own ``strategy_definitions``.

        ScenarioError for a strategy file that is missing or malformed.
        """
        if self._library is None:
            files = [self.strategy_file(k) for k in range(len(self.spec.strategy_files))]
            self._library = strategy_library(files, self.spec.strategy_definitions, self.path, self.lines)
        return self._library

    @property
    def uncontrolled(self) -> str | None:
        """The listed strategy whose entry says ``uncontrolled: true`` (None: none, or several): the indices are over
        its runs."""
        return uncontrolled_of([s for s in self.spec.strategies if isinstance(s, str)], self.library)

    def strategy_problems(self) -> list[Problem]:
        """Located problems of the strategies the study names: a missing strategy file, an unknown name, or an
        entry that needs the case study's best constant current (refused: :data:`NO_BEST_CONSTANT`)."""
        problems = []
        for k in range(len(self.spec.strategy_files)):
            if not self.strategy_file(k).is_file():
                file, line = self.lines.get(("strategy_files", k), (str(self.path), None))
                problems.append(Problem(f"strategy file {self.strategy_file(k)} does not exist", f"strategy_files.{k}",
                                        file, line))
        if problems:
            return problems
        try:
            library = self.library
        except ScenarioError as exc:
            return list(exc.problems)
        for k, s in enumerate(self.spec.strategies):
            if not isinstance(s, str):
                continue
            whole = self.lines.get(("strategies",), (str(self.path), None))  # the list's line (a --set)
            file, line = whole if whole[0].startswith("--set") else self.lines.get(("strategies", k), whole)
            if s not in library:
                known = ", ".join(n for n in library if not library[n].needs_sweep)
                problems.append(Problem(f"unknown strategy {s!r} (known: {known}; or {{name: NAME, overrides: "
                                        "[...]})", f"strategies.{k}", file, line))
            elif library[s].needs_sweep:
                problems.append(Problem(f"strategy {s!r} {NO_BEST_CONSTANT}", f"strategies.{k}", file, line))
        return problems




def load_ida(path: Path | str, overrides: tuple[str, ...] = ()) -> tuple[LoadedIda | None, list[Problem], Any]:
    """Read and validate an IDA study file: (study or None, every problem of the file, its raw data).

    ScenarioError only for a file that cannot be read as YAML at all.
    """
    path = Path(path).resolve()
    if not path.is_file():
        return None, [Problem(f"study file {path} does not exist")], None
    data, lines = load_tree(path)
    if not isinstance(data, dict):
        return None, [Problem("an IDA study file is a mapping of keys", "", str(path))], data
    apply_overrides(data, lines, overrides)
    if BENCHMARK_KEY in data:
        file, line = lines.get((BENCHMARK_KEY,), (str(path), None))
        return None, [Problem("this file is a suite benchmark (it has 'benchmark'): run it with study.py, which "
                              "tunes on its training events and scores on the others", BENCHMARK_KEY, file, line)], data
    try:
        spec = IdaSpec.model_validate(data)
    except ValidationError as exc:
        return None, validation_problems(exc, lines, path, IdaSpec), data
    return LoadedIda(spec, path, lines), [], data
