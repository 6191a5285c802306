"""Scenario files: YAML parsed into typed objects, every problem reported at once.

A scenario names the units (FMU path, parameters), the connections between them
(``"plant.y -> controller.u"``), the time grid, what to record and where results go.
``extends: other.yaml`` takes another file as defaults; ``--set KEY=VALUE`` overrides
any key (``UNIT.PARAM=VALUE`` is short for ``units.UNIT.parameters.PARAM=VALUE``).

Structural checks happen here (unknown keys, wrong types, missing fields); checks that
need the FMUs' model descriptions are in :mod:`orchestration.master.resolve`.
"""

from __future__ import annotations

import difflib
import math
import os
import re
import shutil
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializeAsAny,
    Strict,
    StrictBool,
    StrictInt,
    ValidationError,
    field_validator,
    model_validator,
)

from mre_common.env_settings import EnvSettingError, env_megabytes
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
CSV_PROCESS_ENV = "MRE_COSIM_CSV_PROCESS"  # 1 (default): timeseries.csv written by a forked process; 0: by the run
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
        default=None, description="co-simulation or model-exchange (default: co-simulation when the FMU has it)")
    relative_tolerance: Annotated[Number, Field(gt=0, lt=1)] | None = Field(
        default=None, description="relative tolerance of the model-exchange solver (default 1e-6)")
    step: Annotated[Number, Field(gt=0)] | None = Field(
        default=None, description="the unit's own communication step [s]: a whole multiple of simulation.step "
                          "(default: simulation.step)")

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
    start_time: Number = Field(default=0.0, description="[s]")
    algorithm: Literal["gauss-seidel", "jacobi"] = "gauss-seidel"
    inputs: Literal["step-mean", "hold"] = Field(
        default="step-mean", description="inputs held over a step: estimated mean of the source, or its latest value"
    )
    order: list[str] | None = None
    executor: Literal["auto", "native", "python"] = Field(
        default="auto", description="who runs the steps: the C loop (native), Python, or native when it can (auto)"
    )
    output_interval: StrictInt = Field(
        default=1, ge=1, le=MAX_STEPS,
        description="the results file holds every n-th communication point (and the last); "
                    "the summary's peaks and statistics still come from every step")
    output_format: Literal["csv", "parquet"] = Field(
        default="csv", description="timeseries.csv (12 significant digits), or timeseries.parquet (float64, zstd)")

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

    def step_multiple(self, unit_step: float) -> tuple[int, str | None]:
        """A unit's own step [s] as a whole number m of base steps: (m, None), or (0, why not).

        ``unit_step`` must be at least ``step``, a whole multiple of it (to 1e-9 relative) and
        divide the simulated span, so that every unit's last step ends on ``stop_time``.
        """
        if not unit_step > 0:
            return 0, f"must be positive, got {unit_step!r} s"
        if unit_step < self.step * (1 - 1e-9):
            return 0, f"{unit_step:g} s is smaller than simulation.step ({self.step:g} s): a unit steps at most " \
                      "as often as the base step"
        m = round(unit_step / self.step)
        if abs(m * self.step - unit_step) > 1e-9 * unit_step:
            return 0, (f"{unit_step:g} s is not a whole multiple of simulation.step ({self.step:g} s): it is "
                       f"{unit_step / self.step:.6g} base steps")
        if self.n_steps % m:
            span = self.stop_time - self.start_time
            return 0, (f"{unit_step:g} s does not divide the simulated span ({span:g} s = {self.n_steps} base steps "
                       f"of {self.step:g} s, not a multiple of {m}): the unit's last step must end on stop_time")
        return m, None


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
    """The ``report`` section: what names a run for a reader (caption, labels), and the application's keys.

    The engine knows ``caption`` and ``labels`` only. An application that draws figures or adds
    to the summary (:class:`~orchestration.master.report.ReportHook`) declares its own keys in a
    subclass of this model (which refuses unknown keys). Loaded without the application's model,
    this section keeps other keys as they are (``model_extra``) until
    :func:`~orchestration.master.resolve.resolve` checks them against the application's model
    (and refuses them as unknown keys when there is none).

    Every field of a subclass holding a :class:`VariableRef` (or a list of them) names a recorded
    variable: it is checked as an output of its unit and always recorded.
    """

    model_config = ConfigDict(extra="allow")

    caption: str = Field(default="", description="what was run, for every figure: {unit.param} is filled with the "
                                         "run's value (e.g. '{ground.record} x{ground.scale}')")
    labels: dict[str, str] = Field(default_factory=dict, description="readable names: 'unit.variable' or "
                                                                      "'unit.param=value' -> text")

    @field_validator("labels")
    @classmethod
    def _label_keys(cls, value: dict[str, str]) -> dict[str, str]:
        for key in value:
            VariableRef.parse(key.split("=", 1)[0])
        return value

    def variables(self) -> list[tuple[tuple[str | int, ...], VariableRef]]:
        """Every recorded variable the section names, with its key (``("sensors", 0)``), in field order."""
        out: list[tuple[tuple[str | int, ...], VariableRef]] = []
        for name in type(self).model_fields:
            value = getattr(self, name)
            if isinstance(value, VariableRef):
                out.append(((name,), value))
            elif isinstance(value, list):
                out += [((name, k), v) for k, v in enumerate(value) if isinstance(v, VariableRef)]
        return out

    def optional_variables(self) -> list[VariableRef]:
        """Variables the application's report reads when the unit has them (an output or a local): recorded
        then, and no problem when the unit lacks them (another FMU in its place). None by default."""
        return []

    def templates(self) -> list[tuple[tuple[str, ...], str]]:
        """Every text that may name ``{unit.param}``, with its key (checked against the scenario's units).

        A subclass with more such texts (a ``unit.param`` reference) adds them.
        """
        out: list[tuple[tuple[str, ...], str]] = [(("caption",), self.caption)]
        for key, text in self.labels.items():
            out += [(("labels", key), text), (("labels", key), "{" + key.split("=", 1)[0] + "}")]
        return out


def variable_refs(value: Any) -> Any:
    """A ``unit.variable`` text, or a list of them, as VariableRef (for a report model's "before" validator)."""
    if isinstance(value, str):
        return VariableRef.parse(value)
    if isinstance(value, list):
        return [VariableRef.parse(v) if isinstance(v, str) else v for v in value]
    return value


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
    report: SerializeAsAny[ReportSpec] = Field(default_factory=ReportSpec)  # dumped with the application's keys
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
    exc: ValidationError, lines: Lines, path: Path, model: type[BaseModel] | None = None,
    prefix: tuple[Any, ...] = (),
) -> list[Problem]:
    """Pydantic errors as located problems (file, line, key path), in the tool's wording.

    ``model``: the validated model, for "did you mean" suggestions on unknown keys; ``prefix``:
    the key path of what ``model`` validated within the file (``("report",)`` for that section).
    """
    problems = []
    for err in exc.errors():
        loc = tuple(err["loc"])
        # Drop pydantic's internal location parts (union branches, validator names).
        key = tuple(p for p in loc if not (isinstance(p, str) and ("[" in p or p.startswith("function-"))))
        file, line = locate(lines, prefix + key)
        message = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            message = unknown_key_message(model, key)
        elif err["type"] == "missing":
            message = "required key is missing"
        problems.append(Problem(message, dotted(prefix + key), file or str(path), line))
    return problems


def read_report(raw: Any, lines: Lines, path: Path,
                model: type[ReportSpec] = ReportSpec) -> tuple[ReportSpec | None, list[Problem]]:
    """A ``report`` section (``raw``, from the file) read by the application's ``model``: (it, []) or (None, problems).

    With the engine's own :class:`ReportSpec` (no application model) any key besides
    ``caption`` and ``labels`` is an unknown key.
    """
    try:
        spec = model.model_validate({} if raw is None else raw)
    except ValidationError as exc:
        return None, validation_problems(exc, lines, path, model, ("report",))
    problems = []
    for key in spec.model_extra or {}:
        file, line = locate(lines, ("report", key))
        problems.append(Problem(unknown_key_message(model, (key,)), dotted(("report", key)), file or str(path), line))
    return (None, problems) if problems else (spec, [])


def check_report(loaded: LoadedScenario,
                 model: type[ReportSpec] = ReportSpec) -> tuple[ReportSpec | None, list[Problem]]:
    """The loaded scenario's ``report`` section as ``model`` reads it (see :func:`read_report`)."""
    spec = loaded.scenario.report
    if isinstance(spec, model) and not spec.model_extra:
        return spec, []
    return read_report(loaded.raw.get("report") if isinstance(loaded.raw, dict) else None, loaded.lines,
                       loaded.path, model)


def load_scenario(path: Path | str, overrides: tuple[str, ...] = (),
                  report_model: type[ReportSpec] | None = None) -> LoadedScenario:
    """Read, merge, override and validate a scenario file. Raises ScenarioError with all problems.

    ``report_model``: the application's model of the ``report`` section (its problems are then
    reported with all others); without it the section's other keys are checked by
    :func:`~orchestration.master.resolve.resolve` against the application's hooks.
    """
    path = resolved(path)
    data, lines = load_tree(path)
    data.setdefault("name", _name_from(path.stem))
    units = data.get("units")
    unit_names = set(units) if isinstance(units, dict) else set()
    for assignment in overrides:
        apply_override(data, lines, assignment, unit_names)
    return validate_scenario(data, lines, path, report_model)


def validate_scenario(data: dict[str, Any], lines: Lines, path: Path,
                      report_model: type[ReportSpec] | None = None) -> LoadedScenario:
    """A scenario tree (merged and overridden) validated: ScenarioError listing every problem."""
    problems: list[Problem] = []
    report = None
    if report_model is not None:
        report, problems = read_report(data.get("report"), lines, path, report_model)
        data_checked = {k: v for k, v in data.items() if k != "report"}
    else:
        data_checked = data
    try:
        scenario = Scenario.model_validate(data_checked)
    except ValidationError as exc:
        problems = validation_problems(exc, lines, path, Scenario) + problems
    if problems:
        raise ScenarioError(problems)
    if report is not None:
        scenario = scenario.model_copy(update={"report": report})
    return LoadedScenario(scenario, path, lines, data)


def _name_from(stem: str) -> str:
    """A plain run-folder name made from a file name (leading dots and control characters dropped)."""
    name = re.sub(r"[\x00-\x1f\x7f\\]", "_", stem).lstrip(".")[:100]
    return name or "scenario"


CSV_BYTES_PER_VALUE = 20  # the most '%.12g' and its separator take ("-1.23456789012e-100,")


def _free_bytes(folder: Path) -> int:
    """Free disk space [B] where ``folder`` is or would be created (its nearest existing ancestor)."""
    probe = Path(folder).absolute()
    while not os.path.exists(probe) and probe != probe.parent:  # False (not an error) for a name too long
        probe = probe.parent
    try:
        return shutil.disk_usage(probe).free
    except OSError:
        return 2**62  # unknown: let the write itself report a full disk


def rows_written(rows: int, interval: int) -> int:
    """How many of ``rows`` recorded rows the results file holds at ``output_interval``: every n-th and the last."""
    return 0 if rows <= 0 else -(-rows // interval) + int((rows - 1) % interval != 0)


def result_size_problem(simulation: SimulationSpec, n_recorded: int, results_dir: Path) -> str | None:
    """Why a run's results would not fit on disk (checked before any folder is created), or None.

    Large results are recorded into a memory-mapped file in the run folder (memory does not
    grow with the run's length, :class:`~orchestration.master.recorder.Recorder`), then written
    as ``timeseries.csv``: at most 8 + 20 bytes per sample and column. The budget is the free
    space where the results go, or ``MRE_COSIM_MAX_RESULT_MB``.
    """
    rows, cols = simulation.n_steps + 1, n_recorded + 1
    written = rows_written(rows, simulation.output_interval)
    need = rows * cols * 8 + written * cols * CSV_BYTES_PER_VALUE
    try:
        budget = env_megabytes(MEMORY_ENV, None)
    except EnvSettingError as exc:
        return str(exc)
    source = MEMORY_ENV if budget is not None else f"the free space in {results_dir}; {MEMORY_ENV} sets another budget"
    if budget is None:
        budget = _free_bytes(results_dir)
    if need <= budget:
        return None
    return (f"the run would record {rows:,} samples x {cols} columns (time and {n_recorded} variables), up to "
            f"{_bytes(need)} on disk, more than {_bytes(budget)} ({source}): shorten simulation.stop_time, "
            "lengthen simulation.step, or record fewer variables (outputs: [unit.variable, ...])")


def _bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"
