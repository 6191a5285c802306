"""From a scenario to a runnable system: FMUs found (and, through a hook, built), everything checked up front.

:func:`resolve` reads every FMU's model description (no binary is loaded), resolves data
files through the data path, and checks parameters, connections, recorded variables,
limits and loops against the descriptions. All problems are collected into one
ScenarioError, each with the file, line and key it comes from.

Before anything runs it also checks that every FMU holds a library for this platform
that can be loaded (:func:`~orchestration.master.binary_check.check_binary`), that a String
parameter whose description starts with its quoted choices (``'fast' or 'exact'``) is
set to one of them, and that the recorded results fit on disk
(:func:`~orchestration.master.scenario.result_size_problem`).
"""

from __future__ import annotations

import difflib
import re
import stat
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mre_common.env_settings import EnvSettingError, env_megabytes, env_switch
from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.binary_check import check_binary
from orchestration.master.datapath import file_kind, find_data_file
from orchestration.master.errors import Problem, ScenarioError, SimulationError
from orchestration.master.fmi2_cosim_unit import FmuUnit
from orchestration.master.fmi3_cosim_unit import Fmu3Unit
from orchestration.master.fmi_status import LogRecord
from orchestration.master.fmi_unit_base import FmiUnitBase
from orchestration.master.fmu_description import FmuFormatError, read_description
from orchestration.master.graph import AlgebraicLoopError, Link, Port, propagation_order
from orchestration.master.recorder import DEFAULT_SPILL_MB, SPILL_ENV
from orchestration.master.report import PLACEHOLDER, ReportHook
from orchestration.master.runfolder import sha256
from orchestration.master.safe_archive import DEFAULT_UNPACKED_MB, UNPACKED_ENV
from orchestration.master.scenario import (
    CSV_PROCESS_ENV,
    MEMORY_ENV,
    LoadedScenario,
    ReportSpec,
    VariableRef,
    check_report,
    result_size_problem,
)
from orchestration.master.unit import (
    EXCHANGED_TYPES,
    INTEGER_RANGES,
    UnitDescription,
    Variable,
    exchange_kind,
    value_range,
)
from orchestration.master.unit_check import connection_units, warn_once
from orchestration.master.yaml_source import DataFile

_QUOTED = r"""(?:'[^'\n]*'|"[^"\n]*")"""
_CHOICES = re.compile(rf"^\s*(?:one of:?\s*)?({_QUOTED}(?:\s*(?:,|\bor\b|\|)\s*{_QUOTED})+)")


def declared_choices(description: str) -> tuple[str, ...]:
    """The values a String variable accepts when its description starts with them quoted, e.g.
    ``'fast' or 'exact' (the solver to use)``; empty when it declares none."""
    m = _CHOICES.match(description or "")
    return tuple(q[1:-1] for q in re.findall(_QUOTED, m.group(1))) if m else ()


def _choice_problem(var: Any, value: Any) -> str | None:
    """Why a String parameter's value is not one of its declared choices, or None."""
    choices = declared_choices(var.description) if var.type == "String" else ()
    if not choices or value in choices:
        return None
    close = difflib.get_close_matches(str(value), choices, n=1, cutoff=0.6)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"{var.name} = {value!r} is not one of {', '.join(repr(c) for c in choices)}{hint}"


_FLOAT32_MAX = 3.4028234663852886e38


def _compatible(fmi_type: str, value: Any) -> bool:
    """Can a YAML value be set to a variable of this FMI type (no silent bool/number mixing)?"""
    if fmi_type in ("Real", "Float64", "Float32"):
        return isinstance(value, int | float) and not isinstance(value, bool)
    if fmi_type in INTEGER_RANGES or fmi_type == "Enumeration":
        return isinstance(value, int) and not isinstance(value, bool)
    if fmi_type == "Boolean":
        return isinstance(value, bool)
    return fmi_type == "String" and isinstance(value, str)


def typed_parameter(var: Variable, value: Any, fmi_version: str = "2.0") -> tuple[Any, str | None]:
    """A YAML value checked against the variable's declared type: (the value to set, None) or (value, why not).

    Reals take numbers, integers whole numbers within their type's range, Booleans only
    ``true``/``false``, Strings text; an Enumeration takes an item name or an item value.
    """
    fmi_type = var.fmi_type
    unit = f" [{var.unit}]" if var.unit else ""
    if fmi_type == "Enumeration" and var.items:
        names = {name: number for name, number in var.items}
        listed = ", ".join(f"{name} = {number}" for name, number in var.items)
        if isinstance(value, str):
            if value in names:
                return names[value], None
            close = difflib.get_close_matches(value, list(names), n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            return value, f"{var.name!r} is an Enumeration with items {listed}; {value!r} is none of them{hint}"
        if _compatible(fmi_type, value) and value in names.values():
            return value, None
        return value, f"{var.name!r} is an Enumeration with items {listed}, got {value!r} (give an item name or value)"
    if not _compatible(fmi_type, value):
        return value, f"{var.name!r} is {fmi_type}{unit}, got {value!r}"
    if isinstance(value, str) and "\x00" in value:  # the C API's strings end at a NUL: it would be cut silently
        return value, (f"{var.name!r} is {fmi_type}, {value!r} holds a NUL character (\\0) at position "
                       f"{value.index(chr(0))}, which an FMU's C interface cannot pass")
    limits = value_range(fmi_type, fmi_version)
    if limits is not None and not limits[0] <= value <= limits[1]:
        return value, f"{var.name!r} is {fmi_type}, {value!r} is out of its range [{limits[0]}, {limits[1]}]"
    if fmi_type == "Float32" and abs(value) > _FLOAT32_MAX:
        return value, f"{var.name!r} is Float32, {value!r} is beyond its largest value {_FLOAT32_MAX:.9g}"
    return value, None


def _not_exchanged(var: Variable) -> str | None:
    """Why the master cannot connect, set or record this variable (FMI 3.0 Binary, clocks, arrays), or None."""
    if var.fmi_type in EXCHANGED_TYPES:
        return None
    return (f"{var.name!r} is {var.fmi_type}: this master exchanges scalar Real/Float, integer, Enumeration, "
            "Boolean and String variables only (no Binary, clocks or arrays)")


ENGINE_SETTINGS: tuple[tuple[str, float | None, bool], ...] = (
    (UNPACKED_ENV, DEFAULT_UNPACKED_MB, False),
    (MEMORY_ENV, None, False),
    (SPILL_ENV, DEFAULT_SPILL_MB, True),  # 0 is meaningful: always record into a file
)
"""The engine's numeric environment variables: (name, default MiB, whether 0 is allowed)."""


def environment_problems() -> list[Problem]:
    """Every engine ``MRE_COSIM_*`` variable whose value means nothing (not a number, NaN, negative, 0), named."""
    problems = []
    for name, default, zero_ok in ENGINE_SETTINGS:
        try:
            env_megabytes(name, default, zero_ok=zero_ok)
        except EnvSettingError as exc:
            problems.append(Problem(str(exc)))
    try:
        env_switch(CSV_PROCESS_ENV, True)
    except EnvSettingError as exc:
        problems.append(Problem(str(exc)))
    return problems


def check_environment() -> None:
    """ScenarioError naming every engine environment variable that is set to something meaningless."""
    problems = environment_problems()
    if problems:
        raise ScenarioError(problems)


def _hash(path: Path) -> str | None:
    try:
        return sha256(path)
    except OSError:
        return None


class UnloadableUnit(FmiUnitBase):
    """A unit whose FMU could not be read when the run was set up (changed or damaged after it was checked).

    It has the description that was checked, so the system can be built, and fails its setup
    (t = start) with the reason: the run is a failed result, like any unit failure.
    """

    def __init__(self, name: str, path: Path, description: UnitDescription, reason: str) -> None:
        super().__init__(name, path)
        self.description = description
        self.reason = reason

    def setup(self, start_time: float, stop_time: float) -> None:
        self._time = start_time
        raise SimulationError(f"cannot load FMU {self.path}: {self.reason}", unit=self.name, time=start_time)


@dataclass
class SystemPlan:
    """Everything needed to instantiate and run a scenario, checked."""

    loaded: LoadedScenario
    fmu_paths: dict[str, Path]
    descriptions: dict[str, UnitDescription]
    parameters: dict[str, dict[str, Any]]
    links: list[Link]
    recorded: list[Port]
    limits: dict[Port, float]
    data_files: dict[str, Path] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)  # what the application says made the run
    report: ReportSpec = field(default_factory=ReportSpec)  # the report section, as the application's model read it
    report_hook: ReportHook | None = None  # the application's summary entries and figures
    input_hashes: dict[str, str | None] = field(default_factory=dict)  # FMU and data file -> SHA-256 when checked
    periods: dict[str, int] = field(default_factory=dict)  # unit -> its own step in base steps (absent: 1)

    def changed_inputs(self) -> list[str]:
        """The FMUs and data files whose content differs from when they were checked (SHA-256), one text each.

        A run calls this after its units are initialized (they have read their FMUs and data
        then): any change is a failed run, so that ``manifest.json`` records the hash of what was read.
        """
        changed = []
        used = dict.fromkeys(str(p) for p in (*self.fmu_paths.values(), *self.data_files.values()))
        for text in used:
            if text not in self.input_hashes:
                continue  # a path the plan was given after the checks (a batch worker's content-addressed copy)
            digest = self.input_hashes[text]
            now = _hash(Path(text))
            if now != digest:
                what = "is gone or unreadable" if now is None else f"changed (SHA-256 {digest} when checked, now {now})"
                changed.append(f"{text} {what}")
        return changed

    def create_units(self, on_log: Callable[[str, LogRecord], None] | None = None) -> list[FmuUnit | Fmu3Unit]:
        """Fresh FMU units in declaration order (nothing is instantiated yet); FMI 3.0 FMUs as Fmu3Unit, units run as
        model exchange (the scenario's ``interface``, or an FMU without co-simulation) as MeUnit."""
        from orchestration.master.fmi2_me_unit import MeUnit, runs_as_model_exchange

        units: list[FmuUnit | Fmu3Unit] = []
        for name, desc in self.descriptions.items():
            spec, args = self.loaded.scenario.units[name], (name, self.fmu_paths[name], self.parameters[name], on_log)
            try:
                if runs_as_model_exchange(self.fmu_paths[name], spec.interface):
                    units.append(MeUnit(*args, relative_tolerance=spec.relative_tolerance))
                else:
                    units.append((Fmu3Unit if desc.fmi_version.startswith("3.") else FmuUnit)(*args))
            except (FmuFormatError, OSError, ValueError, zipfile.BadZipFile, KeyError) as exc:
                # the FMU changed after it was checked: a failed run (at setup), not a crash before it
                text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                units.append(UnloadableUnit(name, self.fmu_paths[name], desc, text))  # type: ignore[arg-type]
        return units

    def create_algorithm(self, units: list[FmuUnit]) -> CouplingAlgorithm:
        """The coupling algorithm for these units, as the scenario chose it."""
        sim = self.loaded.scenario.simulation
        return CouplingAlgorithm(units, self.links, self.recorded + list(self.limits), sim.algorithm, sim.order,
                                 sim.inputs, self.periods)


@dataclass(frozen=True)
class ResolveHooks:
    """What an application adds to the engine's checks; the engine itself knows no FMU sources or file formats.

    ``prepare_fmu(path)`` may build or refresh an FMU before its description is read and
    returns a problem text or None; ``data_checks[kind](path)`` checks a data file named
    with ``!kind`` and returns a problem text or None; ``default_data_dirs`` are searched
    after ``--data-dir`` and ``MRE_COSIM_DATA``; ``provenance()`` says what made the run
    (package version, source revision) for the manifest; ``report`` reads the application's
    keys of the scenario's ``report`` section and adds its summary entries and figures
    (:class:`~orchestration.master.report.ReportHook`; without it that section may hold only
    ``caption`` and ``labels``); ``data_kind(description, variable)`` names the kind of data
    file a variable takes (e.g. ``record``), so that a file given with the generic ``!data`` tag is
    checked as that kind too; ``parameter_check(description, fmu_path, values)`` gets every parameter's
    resolved value (the scenario's, else the declared start; a data file as its found path) and returns
    (parameter, problem text) pairs for values outside the unit's own domains, refused before any run.
    """

    prepare_fmu: Callable[[Path], str | None] | None = None
    data_checks: Mapping[str, Callable[[Path], str | None]] = field(default_factory=dict)
    default_data_dirs: tuple[Path, ...] = ()
    provenance: Callable[[], dict[str, Any]] | None = None
    report: ReportHook | None = None
    data_kind: Callable[[UnitDescription, str], str | None] | None = None  # the kind a variable's data file must be
    # (parameter, problem) pairs for a unit's parameter values outside the unit's own domains
    parameter_check: Callable[[UnitDescription, Path, Mapping[str, Any]], list[tuple[str, str]]] | None = None


def _prepare(path: Path, hooks: ResolveHooks) -> str | None:
    if hooks.prepare_fmu is not None:
        return hooks.prepare_fmu(path)
    return None if path.is_file() else f"FMU file {path} does not exist"


def resolve(loaded: LoadedScenario, data_dirs: tuple[Path, ...] = (), hooks: ResolveHooks | None = None) -> SystemPlan:
    """Check a loaded scenario against its FMUs; raises ScenarioError listing every problem."""
    hooks = hooks or ResolveHooks()
    check_environment()  # a meaningless MRE_COSIM_* value would make every later check misleading
    sc = loaded.scenario
    problems: list[Problem] = []
    hashes: dict[str, str | None] = {}
    descriptions: dict[str, UnitDescription] = {}
    fmu_paths: dict[str, Path] = {}
    parameters: dict[str, dict[str, Any]] = {}
    data_files: dict[str, Path] = {}

    for name in sc.units:
        path = loaded.fmu_path(name)
        fmu_paths[name] = path
        looping = path.is_symlink() and not path.exists()
        if "\x00" in str(path):  # no file can have this name (and the OS calls would raise ValueError)
            text: str | None = f"{str(path)!r} holds a NUL character (\\0): no file has such a name"
        else:
            text = f"{path}: a symbolic link to nothing (dangling or looping)" if looping else _prepare(path, hooks)
        if text is not None:
            problems.append(loaded.problem(text, "units", name, "fmu"))
            continue
        try:
            descriptions[name], md = read_description(path, name, sc.units[name].interface)
        except FmuFormatError as exc:
            problems.append(loaded.problem(str(exc), "units", name, "fmu"))
            continue
        text = check_binary(path, md, sc.units[name].interface)
        if text is not None:
            problems.append(loaded.problem(text, "units", name, "fmu"))
        hashes[str(path)] = _hash(path)

    for name, spec in sc.units.items():
        parameters[name] = {}
        unit_problems = len(problems)
        desc = descriptions.get(name)
        for pname, value in spec.parameters.items():
            if isinstance(value, DataFile):
                try:
                    found = find_data_file(value.name, data_dirs, loaded.base_dir("units", name, "parameters", pname),
                                           hooks.default_data_dirs)
                except OSError as exc:  # not found, not a regular file, not readable
                    problems.append(loaded.problem(str(exc), "units", name, "parameters", pname))
                    continue
                kind = value.kind
                if kind == "data" and desc is not None and hooks.data_kind is not None:
                    kind = hooks.data_kind(desc, pname) or kind
                check = hooks.data_checks.get(kind)
                text = check(found) if check is not None else None
                if text is not None:
                    problems.append(loaded.problem(text, "units", name, "parameters", pname))
                    continue
                data_files[f"{name}.{pname}"] = found
                hashes[str(found)] = _hash(found)
                value = str(found)
            elif isinstance(value, str) and value and desc is not None and hooks.data_kind is not None:
                text = _plain_path_problem(value, hooks.data_kind(desc, pname), hooks)
                if text is not None:
                    problems.append(loaded.problem(text, "units", name, "parameters", pname))
                    continue
            if desc is None:
                continue
            var = desc.variables.get(pname)
            if var is None:
                problems.append(loaded.problem(f"{desc.model_identifier} has no variable {pname!r}",
                                               "units", name, "parameters", pname))
                continue
            if var.causality not in ("parameter", "input") or var.variability == "constant":
                problems.append(loaded.problem(
                    f"{pname!r} is a {var.variability} {var.causality}, not a settable parameter",
                    "units", name, "parameters", pname))
                continue
            text = _not_exchanged(var)
            if text is None:
                value, text = typed_parameter(var, value, desc.fmi_version)
            if text is not None:
                problems.append(loaded.problem(text, "units", name, "parameters", pname))
                continue
            text = _choice_problem(var, value) or _bounds_problem(var, value)
            if text is not None:
                problems.append(loaded.problem(text, "units", name, "parameters", pname))
                continue
            parameters[name][pname] = value
        if desc is not None and hooks.parameter_check is not None and len(problems) == unit_problems:
            problems += _domain_problems(loaded, name, desc, fmu_paths[name], parameters[name], hooks)

    periods = _unit_periods(loaded, descriptions, problems)

    def port(ref: VariableRef, causality: str, *key: Any, also: tuple[str, ...] = ()) -> Port | None:
        desc = descriptions.get(ref.unit)
        if ref.unit not in sc.units:
            problems.append(loaded.problem(f"no unit named {ref.unit!r} (units: {', '.join(sc.units)})", *key))
            return None
        if desc is None:
            return None  # the unit's own problem is reported already
        var = desc.variables.get(ref.name)
        if var is None:
            problems.append(loaded.problem(f"{ref.unit} ({desc.model_identifier}) has no variable {ref.name!r}", *key))
            return None
        if var.causality != causality and var.causality not in also:
            expected = " or ".join((causality, *also))
            problems.append(loaded.problem(f"{ref} is {var.causality}, expected {expected}", *key))
            return None
        text = _not_exchanged(var)
        if text is not None:
            problems.append(loaded.problem(f"{ref}: {text}", *key))
            return None
        return (ref.unit, ref.name)

    links: list[Link] = []
    driven: dict[Port, int] = {}
    for k, conn in enumerate(sc.connections):
        src = port(conn.source, "output", "connections", k)
        dst = port(conn.target, "input", "connections", k)
        if src is None or dst is None:
            continue
        vs = descriptions[src[0]].variables[src[1]]
        vd = descriptions[dst[0]].variables[dst[1]]
        if exchange_kind(vs.fmi_type) != exchange_kind(vd.fmi_type):
            problems.append(loaded.problem(
                f"type mismatch: {conn.source} is {vs.fmi_type}, {conn.target} is {vd.fmi_type} "
                "(connections join equal types; the master converts none)", "connections", k))
            continue
        if vs.fmi_type == "Enumeration" and vs.items and vd.items and sorted(vs.items) != sorted(vd.items):
            problems.append(loaded.problem(
                f"enumeration mismatch: {conn.source} has items {_items(vs)}, {conn.target} has {_items(vd)}",
                "connections", k))
            continue
        unit_problem, unit_warning = connection_units(str(conn.source), str(conn.target), vs.unit, vd.unit)
        if unit_problem:
            problems.append(loaded.problem(unit_problem, "connections", k))
            continue
        if unit_warning:
            warn_once(unit_warning)
        if dst in driven:
            problems.append(loaded.problem(f"{conn.target} is already driven by connections[{driven[dst]}]",
                                           "connections", k))
            continue
        driven[dst] = k
        links.append(Link(src, dst, conn.delayed))

    for link in links:  # the grid rules of units with their own step are the Real fast path's
        for end in (link.source, link.target):
            var = descriptions[end[0]].variables[end[1]]
            if end[0] in periods and not var.fast_real:
                problems.append(loaded.problem(
                    f"{end[0]}.{end[1]} is {var.fmi_type} and connected: a unit with its own step exchanges Real "
                    f"values only (leave units.{end[0]}.step out)", "units", end[0], "step"))

    for name, desc in descriptions.items():
        for var in desc.inputs():
            if (name, var.name) not in driven and var.start is None and var.name not in parameters[name]:
                problems.append(loaded.problem(f"input {var.name!r} is not connected and has no start value",
                                               "units", name))

    report, report_problems = check_report(loaded, hooks.report.model if hooks.report is not None else ReportSpec)
    problems += report_problems
    for where, text in report.templates() if report is not None else ():
        for m in PLACEHOLDER.finditer(text):
            if m.group(1) not in sc.units:
                problems.append(loaded.problem(f"{{{m.group(1)}.{m.group(2)}}}: no unit named {m.group(1)!r} "
                                               f"(units: {', '.join(sc.units)})", "report", *where))

    recorded: list[Port] = []
    if sc.outputs == "all":  # every output the master can exchange (FMI 3.0 Binary, clocks, arrays are left out)
        recorded = [(n, v.name) for n, d in descriptions.items() for v in d.outputs() if _not_exchanged(v) is None]
    else:
        for k, ref in enumerate(sc.outputs):
            p = port(ref, "output", "outputs", k, also=("local",))  # a local is recorded only when named
            if p is not None and p not in recorded:
                recorded.append(p)
    for key, ref in report.variables() if report is not None else ():
        p = port(ref, "output", "report", *key)
        if p is not None and p not in recorded:
            recorded.append(p)
    for ref in report.optional_variables() if report is not None else ():  # recorded where the unit has them
        var = descriptions[ref.unit].variables.get(ref.name) if ref.unit in descriptions else None
        if (var is not None and var.causality in ("output", "local") and _not_exchanged(var) is None
                and (ref.unit, ref.name) not in recorded):
            recorded.append((ref.unit, ref.name))
    limits: dict[Port, float] = {}
    for text, limit in sc.limits.max_abs.items():
        p = port(VariableRef.parse(text), "output", "limits", "max_abs", text)
        if p is not None and descriptions[p[0]].variables[p[1]].fmi_type == "String":
            problems.append(loaded.problem(f"{text} is a String: max_abs needs a number", "limits", "max_abs", text))
        elif p is not None:
            limits[p] = limit

    order = sc.simulation.order
    if order is not None and sorted(order) != sorted(sc.units):
        problems.append(loaded.problem(f"must list every unit once: {', '.join(sc.units)}", "simulation", "order"))

    if len(descriptions) == len(sc.units) and not problems:
        try:
            propagation_order(descriptions, links)
        except AlgebraicLoopError as exc:
            problems.append(loaded.problem(str(exc), "connections"))

    if sc.simulation.executor == "native" and len(descriptions) == len(sc.units):
        text = _native_problem(loaded, descriptions, links, recorded + list(limits))
        if text is not None:
            problems.append(loaded.problem(text, "simulation", "executor"))

    text = result_size_problem(sc.simulation, len(recorded), Path(sc.results.dir))
    if text is not None:
        problems.append(loaded.problem(text, "simulation", "stop_time"))

    if problems:
        raise ScenarioError(problems)
    provenance = hooks.provenance() if hooks.provenance is not None else {}
    return SystemPlan(loaded, fmu_paths, descriptions, parameters, links, recorded, limits, data_files, provenance,
                      report, hooks.report, hashes, periods)


def _unit_periods(loaded: LoadedScenario, descriptions: dict[str, UnitDescription],
                  problems: list[Problem]) -> dict[str, int]:
    """Each unit's own step (``units.NAME.step``) as a whole number of base steps; problems appended.

    A unit that has no communication step of its own cannot take one: a model-exchange unit is
    integrated by the master, on the base grid, with its inputs held over each base step.
    """
    from orchestration.master.fmi2_me_unit import runs_as_model_exchange

    sim = loaded.scenario.simulation
    periods: dict[str, int] = {}
    for name, spec in loaded.scenario.units.items():
        if spec.step is None:
            continue
        m, text = sim.step_multiple(spec.step)
        if text is None and name in descriptions and runs_as_model_exchange(loaded.fmu_path(name), spec.interface):
            text = ("a model-exchange unit has no communication step of its own: the master integrates it on the "
                    f"base grid (simulation.step); leave units.{name}.step out, or run its co-simulation interface")
        if text is not None:
            problems.append(loaded.problem(text, "units", name, "step"))
        elif m > 1:
            periods[name] = m
    return periods


def _domain_problems(loaded: LoadedScenario, name: str, desc: UnitDescription, path: Path, values: dict[str, Any],
                     hooks: ResolveHooks) -> list[Problem]:
    """The application's domain checks of one unit's parameters (``ResolveHooks.parameter_check``) as Problems:
    at the parameter's key when the scenario sets it, else at the unit (the declared start is at fault)."""
    resolved = {v.name: _start_value(v) for v in desc.variables.values()
                if v.causality == "parameter" and v.start is not None}
    resolved.update(values)
    problems = []
    for pname, text in hooks.parameter_check(desc, path, resolved) if hooks.parameter_check is not None else ():
        if pname in values:
            problems.append(loaded.problem(text, "units", name, "parameters", pname))
        else:
            start = " (declared start value)" if pname in desc.variables else ""
            problems.append(loaded.problem(f"{pname}{start}: {text}", "units", name))
    return problems


def _start_value(var: Variable) -> Any:
    """A declared start value (text in the model description) as the Python value a scenario would set."""
    text = str(var.start)
    try:
        if var.type in ("Real", "Float64", "Float32"):
            return float(text)
        if var.type == "Boolean":
            return text.strip().lower() in ("true", "1")
        if var.type in INTEGER_RANGES or var.type == "Enumeration":
            return int(text)
    except ValueError:
        return text
    return var.start


def _plain_path_problem(value: str, kind: str | None, hooks: ResolveHooks) -> str | None:
    """Why a plain string given to a variable that takes a data file of ``kind`` cannot be that file, or None.

    The unit receives the text as it is (relative to the current folder); a ``!record`` or
    ``!data`` tag searches the data path instead.
    """
    check = hooks.data_checks.get(kind) if kind is not None else None
    if check is None:
        return None
    path = Path(value).absolute()  # the unit opens it from the current folder
    hint = f"(a plain string goes to the unit as it is; write !{kind} {value} to search the data path)"
    try:
        info = path.stat()  # never opens it: a FIFO does not block
    except (OSError, ValueError):
        return f"{kind} file {value!r} not found: no {path} {hint}"
    if not stat.S_ISREG(info.st_mode):
        return f"{kind} file {value!r}: {path} is {file_kind(info.st_mode)}, not a regular file"
    return check(path)


def _bounds_problem(var: Variable, value: Any) -> str | None:
    """Why a number is outside the variable's declared ``min``/``max``, or None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    low, high = var.min_value, var.max_value
    if (low is not None and value < low) or (high is not None and value > high):
        unit = f" {var.unit}" if var.unit else ""
        span = f"[{'-inf' if low is None else f'{low:g}'}, {'inf' if high is None else f'{high:g}'}]{unit}"
        return f"{var.name} = {value!r} is outside its declared range {span} (min/max in the model description)"
    return None


def _native_problem(loaded: LoadedScenario, descriptions: dict[str, UnitDescription], links: list[Link],
                    ports: list[Port]) -> str | None:
    """Why ``executor: native`` cannot run this system (checked before anything runs), or None."""
    from orchestration.master.fmi2_me_unit import runs_as_model_exchange

    not_cosim = [name for name, desc in descriptions.items() if desc.fmi_version != "2.0"
                 or runs_as_model_exchange(loaded.fmu_path(name), loaded.scenario.units[name].interface)]
    if not_cosim:
        return (f"native: unit(s) {', '.join(not_cosim)} are not FMI 2.0 co-simulation FMUs; the native executor "
                "drives only those (use executor: auto or python)")
    typed = sorted({f"{u}.{v} ({descriptions[u].variables[v].fmi_type})" for u, v in
                    [p for link in links for p in (link.source, link.target)] + ports
                    if not descriptions[u].variables[v].fast_real})
    if typed:
        shown = ", ".join(typed[:5]) + (f" and {len(typed) - 5} more" if len(typed) > 5 else "")
        return (f"native: the system exchanges or records values that are not Real ({shown}); the native executor "
                "moves Real values only (use executor: auto or python)")
    from orchestration.master.native_stepper import NativeUnavailable, kernel_library

    try:
        kernel_library()
    except NativeUnavailable as exc:
        return f"native: the native executor is not available on this machine: {exc} (use executor: auto or python)"
    return None


def _items(var: Variable) -> str:
    return ", ".join(f"{name} = {number}" for name, number in var.items)
