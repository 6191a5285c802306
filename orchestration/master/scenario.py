"""Scenario files: YAML parsed into typed objects, every problem reported at once.

A scenario names the units (FMU path, parameters), the connections between them
(``"building.x_0 -> isolator.x"``), the time grid, what to record and where results go.
``extends: other.yaml`` takes another file as defaults; ``--set KEY=VALUE`` overrides
any key (``UNIT.PARAM=VALUE`` is short for ``units.UNIT.parameters.PARAM=VALUE``).

Structural checks happen here (unknown keys, wrong types, missing fields); checks that
need the FMUs' model descriptions are in :mod:`orchestration.master.system`.
"""

from __future__ import annotations

import difflib
import math
import os
import re
import shutil
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, Strict, StrictBool, ValidationError, field_validator, model_validator

from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.yaml_source import DataFile, Lines, apply_override, dotted, load_tree, locate, resolved

_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_VARIABLE = re.compile(rf"^\s*({_NAME})\.([A-Za-z_][A-Za-z0-9_.\[\]]*)\s*$")
_CONNECTION = re.compile(r"^\s*(\S+)\s*->\s*(\S+)\s*$")

ParamValue = bool | int | float | str | DataFile
Number = Annotated[float, Strict(), Field(allow_inf_nan=False)]
"""A finite number (an integer is taken as a float); booleans and strings are refused, not converted."""

_PLAIN_NAME = re.compile(r"[^./\\\x00-\x1f\x7f][^/\\\x00-\x1f\x7f]{0,99}")
MAX_STEPS = 10**12
"""Most communication steps a scenario may have (a guard against overflow; memory refuses far fewer)."""
MEMORY_ENV = "MRE_COSIM_MAX_RESULT_MB"
"""Environment variable: the disk space a run's results may take [MiB] (default: the free space where they go)."""


def plain_name(text: str) -> str:
    """ValueError unless ``text`` can name a folder inside another: no path separator, no leading dot."""
    if not isinstance(text, str) or not _PLAIN_NAME.fullmatch(text):
        raise ValueError(f"{text!r} must be a plain name (no '/' or '\\', not starting with '.', no control "
                         "characters, at most 100 characters): it names the run folder")
    return text


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)


class VariableRef(_Strict):
    """``unit.variable``."""

    unit: str
    name: str

    @classmethod
    def parse(cls, text: str) -> VariableRef:
        m = _VARIABLE.match(text) if isinstance(text, str) else None
        if not m:
            raise ValueError(f"expected 'unit.variable', got {text!r}")
        return cls(unit=m.group(1), name=m.group(2))

    def __str__(self) -> str:
        return f"{self.unit}.{self.name}"


class Connection(_Strict):
    """Output ``source`` feeds input ``target``. ``delayed`` connections are read only at step start."""

    source: VariableRef
    target: VariableRef
    delayed: StrictBool = False

    def __str__(self) -> str:
        return f"{self.source} -> {self.target}" + (" (delayed)" if self.delayed else "")


class UnitSpec(_Strict):
    """One co-simulation unit: its FMU file (relative to the scenario file) and parameter values.

    ``interface``: run the FMU's ``co-simulation`` or its ``model-exchange`` interface (default:
    co-simulation when the FMU has it, else model exchange); ``relative_tolerance`` is the
    model-exchange solver's (CVode) relative tolerance, default 1e-6.
    """

    fmu: str
    parameters: dict[str, ParamValue] = Field(default_factory=dict)
    interface: Literal["co-simulation", "model-exchange"] | None = Field(
        None, description="co-simulation or model-exchange (default: co-simulation when the FMU has it)")
    relative_tolerance: Annotated[Number, Field(gt=0, lt=1)] | None = Field(
        None, description="relative tolerance of the model-exchange solver (default 1e-6)")

    @model_validator(mode="after")
    def _tolerance_needs_model_exchange(self) -> UnitSpec:
        if self.relative_tolerance is not None and self.interface != "model-exchange":
            raise ValueError("relative_tolerance is the model-exchange solver's: it needs interface: model-exchange")
        return self

    @field_validator("parameters", mode="before")
    @classmethod
    def _scalars(cls, value: Any) -> Any:
        if isinstance(value, dict):
            for key, item in value.items():
                if not isinstance(item, bool | int | float | str | DataFile):
                    raise ValueError(f"parameter {key!r} must be a number, boolean or string, got {item!r}")
                if isinstance(item, float) and not math.isfinite(item):
                    raise ValueError(f"parameter {key!r} must be a finite number, got {item!r}")
        return value


class SimulationSpec(_Strict):
    """Time grid and coupling algorithm."""

    step: Number = Field(gt=0, description="communication step [s]")
    stop_time: Number = Field(description="[s]")
    start_time: Number = Field(0.0, description="[s]")
    algorithm: Literal["gauss-seidel", "jacobi"] = "gauss-seidel"
    inputs: Literal["step-mean", "hold"] = Field(
        "step-mean", description="inputs held over a step: estimated mean of the source, or its latest value"
    )
    order: list[str] | None = None
    executor: Literal["auto", "native", "python"] = Field(
        "auto", description="who runs the steps: the C loop (native), Python, or native when it can (auto)"
    )

    @model_validator(mode="after")
    def _grid(self) -> SimulationSpec:
        span = self.stop_time - self.start_time
        if span <= 0:
            raise ValueError(f"stop_time ({self.stop_time} s) must be after start_time ({self.start_time} s)")
        if not math.isfinite(span):
            raise ValueError(f"the span from start_time to stop_time ({self.start_time} s to {self.stop_time} s) "
                             "is too large to represent")
        if self.step > span:
            raise ValueError(f"step ({self.step} s) is larger than the simulated span ({span} s)")
        ratio = span / self.step
        if not ratio <= MAX_STEPS:
            raise ValueError(f"{span:g} s in steps of {self.step:g} s is {ratio:.3g} steps, more than "
                             f"{MAX_STEPS:.0e}: lengthen step or shorten the span")
        n = round(ratio)
        if abs(n * self.step - span) > 1e-9 * max(1.0, span):
            raise ValueError(
                f"the span {span} s is not a whole number of steps of {self.step} s "
                f"({span / self.step:.6g} steps): the last step must land on stop_time"
            )
        return self

    @property
    def n_steps(self) -> int:
        """Number of communication steps."""
        return round((self.stop_time - self.start_time) / self.step)


class ResultsSpec(_Strict):
    """Where run folders go (relative to the working directory)."""

    dir: str = "runs"

    @field_validator("dir")
    @classmethod
    def _dir(cls, value: str) -> str:
        if not value.strip() or "\x00" in value:
            raise ValueError("must name a folder")
        return value


class ReportSpec(_Strict):
    """Roles of recorded variables for the run summary and plots (all optional)."""

    base_displacement: VariableRef | None = None
    drifts: list[VariableRef] = Field(default_factory=list)
    floor_accelerations: list[VariableRef] = Field(default_factory=list)
    current: VariableRef | None = None
    isolator_force: VariableRef | None = None
    ground_acceleration: VariableRef | None = None
    caption: str = Field("", description="what was run, for every figure: {unit.param} is filled with the "
                                         "run's value (e.g. '{ground.record} x{ground.scale}')")
    labels: dict[str, str] = Field(default_factory=dict, description="readable names: 'unit.variable' or "
                                                                      "'unit.param=value' -> text")
    displacement_limits: dict[str, Number | str] = Field(
        default_factory=dict, description="named limits [m] drawn on the hysteresis plot: a value or 'unit.param'")

    @field_validator("labels")
    @classmethod
    def _label_keys(cls, value: dict[str, str]) -> dict[str, str]:
        for key in value:
            VariableRef.parse(key.split("=", 1)[0])
        return value

    @field_validator("displacement_limits")
    @classmethod
    def _limit_refs(cls, value: dict[str, Number | str]) -> dict[str, Number | str]:
        for label, ref in value.items():
            if isinstance(ref, str):
                VariableRef.parse(ref)
            elif not ref > 0:
                raise ValueError(f"displacement limit {label!r} must be positive, got {ref}")
        return value

    @field_validator("base_displacement", "current", "isolator_force", "ground_acceleration", mode="before")
    @classmethod
    def _one(cls, value: Any) -> Any:
        return VariableRef.parse(value) if isinstance(value, str) else value

    @field_validator("drifts", "floor_accelerations", mode="before")
    @classmethod
    def _many(cls, value: Any) -> Any:
        if isinstance(value, list):
            return [VariableRef.parse(v) if isinstance(v, str) else v for v in value]
        return value

    def variables(self) -> list[VariableRef]:
        """Every variable the report needs."""
        single = [self.base_displacement, self.current, self.isolator_force, self.ground_acceleration]
        return [v for v in single if v is not None] + list(self.drifts) + list(self.floor_accelerations)


class LimitsSpec(_Strict):
    """Physical plausibility limits: a run stops when a watched variable leaves them."""

    max_abs: dict[str, Number] = Field(default_factory=dict)

    @field_validator("max_abs")
    @classmethod
    def _refs(cls, value: dict[str, float]) -> dict[str, float]:
        for key, limit in value.items():
            VariableRef.parse(key)
            if not limit > 0:
                raise ValueError(f"limit for {key} must be positive, got {limit}")
        return value


class Scenario(_Strict):
    """A whole co-simulation scenario, as resolved (defaults merged, overrides applied)."""

    name: str
    description: str = ""
    units: dict[str, UnitSpec]
    connections: list[Connection] = Field(default_factory=list)
    simulation: SimulationSpec
    outputs: Literal["all"] | list[VariableRef] = "all"
    results: ResultsSpec = Field(default_factory=ResultsSpec)
    report: ReportSpec = Field(default_factory=ReportSpec)
    limits: LimitsSpec = Field(default_factory=LimitsSpec)

    @field_validator("name")
    @classmethod
    def _name(cls, value: str) -> str:
        return plain_name(value)

    @field_validator("units")
    @classmethod
    def _unit_names(cls, value: dict[str, UnitSpec]) -> dict[str, UnitSpec]:
        if not value:
            raise ValueError("a scenario needs at least one unit")
        for name in value:
            if not re.fullmatch(_NAME, name):
                raise ValueError(f"unit name {name!r} must be a plain identifier")
        return value

    @field_validator("connections", mode="before")
    @classmethod
    def _connections(cls, value: Any) -> Any:
        if not isinstance(value, list):
            return value
        out = []
        for item in value:
            if isinstance(item, str):
                m = _CONNECTION.match(item)
                if not m:
                    raise ValueError(f"expected 'unit.output -> unit.input', got {item!r}")
                item = {"source": m.group(1), "target": m.group(2)}
            if isinstance(item, dict):
                item = dict(item)
                for key in ("source", "target"):
                    if isinstance(item.get(key), str):
                        item[key] = VariableRef.parse(item[key])
            out.append(item)
        return out

    @field_validator("outputs", mode="before")
    @classmethod
    def _outputs(cls, value: Any) -> Any:
        if isinstance(value, list):
            return [VariableRef.parse(v) if isinstance(v, str) else v for v in value]
        return value


class LoadedScenario:
    """A validated scenario with where it came from (file, key lines) for later problem reports."""

    def __init__(self, scenario: Scenario, path: Path, lines: Lines, raw: dict[str, Any]) -> None:
        self.scenario = scenario
        self.path = path
        self.lines = lines
        self.raw = raw

    def problem(self, message: str, *key: Any) -> Problem:
        """A problem located at a key path of the scenario."""
        file, line = locate(self.lines, key)
        return Problem(message, dotted(key), file or str(self.path), line)

    def base_dir(self, *key: Any) -> Path:
        """Folder that relative paths at a key are relative to: that of the file that set the key
        (a base file reached through ``extends`` keeps its own folder); the working directory
        for command-line overrides."""
        file, _ = self.lines.get(tuple(key), ("", None))
        if file.startswith("--set"):
            return Path.cwd()
        return Path(file).parent if file and Path(file).is_file() else self.path.parent

    def fmu_path(self, unit: str) -> Path:
        """Absolute FMU path of a unit (relative paths: see :meth:`base_dir`)."""
        fmu = Path(self.scenario.units[unit].fmu).expanduser()
        return fmu if fmu.is_absolute() else resolved(self.base_dir("units", unit, "fmu") / fmu)


def _model_at(model: type[BaseModel] | None, key: tuple[Any, ...]) -> type[BaseModel] | None:
    """The pydantic model that holds the keys at ``key`` (through dict values, lists and optionals)."""
    annotation: Any = model
    for part in key:
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            field_info = annotation.model_fields.get(part) if isinstance(part, str) else None
            if field_info is None:
                return None
            annotation = field_info.annotation
            continue
        args = [a for a in get_args(annotation) if a is not type(None)]
        annotation = args[-1] if args else None  # dict[str, M] -> M, list[M] -> M, M | None -> M
    args = [a for a in get_args(annotation) if a is not type(None)] if not isinstance(annotation, type) else []
    if len(args) == 1:
        annotation = args[0]
    return annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None


def unknown_key_message(model: type[BaseModel] | None, key: tuple[Any, ...]) -> str:
    """'unknown key', with the closest allowed names when there are any."""
    holder = _model_at(model, key[:-1]) if model is not None and key else None
    if holder is None or not isinstance(key[-1], str):
        return "unknown key"
    names = [f.alias or n for n, f in holder.model_fields.items()]
    close = difflib.get_close_matches(key[-1], names, n=3, cutoff=0.6)
    return f"unknown key (did you mean {' or '.join(repr(c) for c in close)}?)" if close else "unknown key"


def validation_problems(
    exc: ValidationError, lines: Lines, path: Path, model: type[BaseModel] | None = None
) -> list[Problem]:
    """Pydantic errors as located problems (file, line, key path), in the tool's wording.

    ``model``: the validated model, for "did you mean" suggestions on unknown keys.
    """
    problems = []
    for err in exc.errors():
        loc = tuple(err["loc"])
        # Drop pydantic's internal location parts (union branches, validator names).
        key = tuple(p for p in loc if not (isinstance(p, str) and ("[" in p or p.startswith("function-"))))
        file, line = locate(lines, key)
        message = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            message = unknown_key_message(model, key)
        elif err["type"] == "missing":
            message = "required key is missing"
        problems.append(Problem(message, dotted(key), file or str(path), line))
    return problems


def load_scenario(path: Path | str, overrides: tuple[str, ...] = ()) -> LoadedScenario:
    """Read, merge, override and validate a scenario file. Raises ScenarioError with all problems."""
    path = resolved(path)
    data, lines = load_tree(path)
    data.setdefault("name", _name_from(path.stem))
    units = data.get("units")
    unit_names = set(units) if isinstance(units, dict) else set()
    for assignment in overrides:
        apply_override(data, lines, assignment, unit_names)
    try:
        scenario = Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(validation_problems(exc, lines, path, Scenario)) from None
    return LoadedScenario(scenario, path, lines, data)


def _name_from(stem: str) -> str:
    """A plain run-folder name made from a file name (leading dots and control characters dropped)."""
    name = re.sub(r"[\x00-\x1f\x7f\\]", "_", stem).lstrip(".")[:100]
    return name or "scenario"


CSV_BYTES_PER_VALUE = 20  # the most '%.12g' and its separator take ("-1.23456789012e-100,")


def _free_bytes(folder: Path) -> int:
    """Free disk space [B] where ``folder`` is or would be created (its nearest existing ancestor)."""
    probe = Path(folder).absolute()
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    try:
        return shutil.disk_usage(probe).free
    except OSError:
        return 2**62  # unknown: let the write itself report a full disk


def result_size_problem(simulation: SimulationSpec, n_recorded: int, results_dir: Path) -> str | None:
    """Why a run's results would not fit on disk (checked before any folder is created), or None.

    Large results are recorded into a memory-mapped file in the run folder (memory does not
    grow with the run's length, :class:`~orchestration.master.recorder.Recorder`), then written
    as ``timeseries.csv``: at most 8 + 20 bytes per sample and column. The budget is the free
    space where the results go, or ``MRE_COSIM_MAX_RESULT_MB``.
    """
    rows, cols = simulation.n_steps + 1, n_recorded + 1
    need = rows * cols * (8 + CSV_BYTES_PER_VALUE)
    text = os.environ.get(MEMORY_ENV, "").strip()
    try:
        budget = int(float(text) * 2**20) if text else _free_bytes(results_dir)
    except (ValueError, OverflowError):
        budget = _free_bytes(results_dir)
    if need <= budget:
        return None
    source = MEMORY_ENV if text else f"the free space in {results_dir}; {MEMORY_ENV} sets another budget"
    return (f"the run would record {rows:,} samples x {cols} columns (time and {n_recorded} variables), up to "
            f"{_bytes(need)} on disk, more than {_bytes(budget)} ({source}): shorten simulation.stop_time, "
            "lengthen simulation.step, or record fewer variables (outputs: [unit.variable, ...])")


def _bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"
