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
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TypeAlias

import numpy as np

from mre_common.env_settings import EnvSettingError, env_megabytes, env_switch
from mre_common.hashing import file_sha256
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
    Unit,
    UnitDescription,
    Variable,
    exchange_kind,
    start_value,
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


def did_you_mean(word: str, options: Sequence[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``options`` to ``word`` (difflib, ratio >= 0.6), else ``""``."""
    close = difflib.get_close_matches(word, list(options), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _choice_problem(var: Any, value: Any) -> str | None:
    """Why a String parameter's value is not one of its declared choices, or None."""
    choices = declared_choices(var.description) if var.type == "String" else ()
    if not choices or value in choices:
        return None
    hint = did_you_mean(str(value), choices)
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
            hint = did_you_mean(value, list(names))
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
        return file_sha256(path)
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
        self._fail()

    def _fail(self) -> NoReturn:
        raise SimulationError(f"cannot load FMU {self.path}: {self.reason}", unit=self.name, time=self._time)

    # the rest of the Unit protocol: never reached (setup fails first), and failing the same way if it were
    def exit_initialization(self) -> None:
        self._fail()

    def get_real(self, handle: Any) -> np.ndarray:
        self._fail()

    def set_real(self, handle: Any, values: np.ndarray) -> None:
        self._fail()

    def get_values(self, fmi_type: str, refs: Sequence[int]) -> list[Any]:
        self._fail()

    def set_values(self, fmi_type: str, refs: Sequence[int], values: Sequence[Any]) -> None:
        self._fail()

    def step(self, t: float, h: float) -> None:
        self._fail()


if TYPE_CHECKING:
    from orchestration.master.fmi2_me_unit import MeUnit

FmiUnit: TypeAlias = "FmuUnit | MeUnit | Fmu3Unit | UnloadableUnit"
"""The units a plan creates: FMI 2.0 co-simulation, FMI 2.0 model exchange, FMI 3.0 co-simulation, and a unit
whose FMU could not be read when the run was set up (it fails at setup)."""


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

    def create_units(self, on_log: Callable[[str, LogRecord], None] | None = None) -> list[FmiUnit]:
        """Fresh FMU units in declaration order (nothing is instantiated yet); FMI 3.0 FMUs as Fmu3Unit, units run as
        model exchange (the scenario's ``interface``, or an FMU without co-simulation) as MeUnit."""
        from orchestration.master.fmi2_me_unit import MeUnit, runs_as_model_exchange

        units: list[FmiUnit] = []
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
                units.append(UnloadableUnit(name, self.fmu_paths[name], desc, text))
        return units

    def create_algorithm(self, units: Sequence[Unit]) -> CouplingAlgorithm:
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
    """Check a loaded scenario against its FMUs; raises ScenarioError listing every problem.

    The checks run in stages, each adding its problems to the one list: the FMUs, each unit's
    parameters, the units' own steps, the connections, the report section, the recorded
    variables and limits, then the system as a whole (order, loops, executor, result size).
    """
    hooks = hooks or ResolveHooks()
    check_environment()  # a meaningless MRE_COSIM_* value would make every later check misleading
    r = _Resolution(loaded, data_dirs, hooks)
    r.read_fmus()
    r.check_parameters()
    periods = _unit_periods(loaded, r.descriptions, r.problems)
    links = r.connections()
    r.check_links_of_own_steps(links, periods)
    r.check_unconnected_inputs(links)
    report = r.report_section()
    recorded = r.recorded(report)
    limits = r.limits()
    r.check_system(links, recorded + list(limits))
    r.check_result_size(len(recorded))
    if r.problems:
        raise ScenarioError(r.problems)
    if report is None:  # read_report returns None only with problems
        raise ScenarioError([loaded.problem("the report section could not be read", "report")])
    provenance = hooks.provenance() if hooks.provenance is not None else {}
    return SystemPlan(loaded, r.fmu_paths, r.descriptions, r.parameters, links, recorded, limits, r.data_files,
                      provenance, report, hooks.report, r.hashes, periods)


class _Resolution:
    """The state of one :func:`resolve`: what is found so far, and every problem, in the order found."""

    def __init__(self, loaded: LoadedScenario, data_dirs: tuple[Path, ...], hooks: ResolveHooks) -> None:
        self.loaded = loaded
        self.sc = loaded.scenario
        self.data_dirs = data_dirs
        self.hooks = hooks
        self.problems: list[Problem] = []
        self.hashes: dict[str, str | None] = {}
        self.descriptions: dict[str, UnitDescription] = {}
        self.fmu_paths: dict[str, Path] = {}
        self.parameters: dict[str, dict[str, Any]] = {}
        self.data_files: dict[str, Path] = {}

    def problem(self, text: str, *key: Any) -> None:
        self.problems.append(self.loaded.problem(text, *key))

    # -- the FMUs ---------------------------------------------------------------------------------------
    def read_fmus(self) -> None:
        """Each unit's FMU found (prepared by the hook), its description read, its binary checked, its hash taken."""
        for name in self.sc.units:
            path = self.loaded.fmu_path(name)
            self.fmu_paths[name] = path
            text = self._fmu_file_problem(path)
            if text is not None:
                self.problem(text, "units", name, "fmu")
                continue
            interface = self.sc.units[name].interface
            try:
                self.descriptions[name], md = read_description(path, name, interface)
            except FmuFormatError as exc:
                self.problem(str(exc), "units", name, "fmu")
                continue
            text = check_binary(path, md, interface)
            if text is not None:
                self.problem(text, "units", name, "fmu")
            self.hashes[str(path)] = _hash(path)

    def _fmu_file_problem(self, path: Path) -> str | None:
        if "\x00" in str(path):  # no file can have this name (and the OS calls would raise ValueError)
            return f"{str(path)!r} holds a NUL character (\\0): no file has such a name"
        try:
            if path.is_symlink() and not path.exists():
                return f"{path}: a symbolic link to nothing (dangling or looping)"
        except OSError as exc:  # a name the file system refuses, e.g. longer than it allows
            return f"{str(path)[:200]}{'...' if len(str(path)) > 200 else ''}: not a usable file name ({exc.strerror})"
        return _prepare(path, self.hooks)

    # -- parameters -------------------------------------------------------------------------------------
    def check_parameters(self) -> None:
        """Every unit's parameters: data files found and checked, values checked against their variables; then
        the application's domain checks of a unit whose parameters are otherwise fine."""
        for name, spec in self.sc.units.items():
            self.parameters[name] = {}
            unit_problems = len(self.problems)
            desc = self.descriptions.get(name)
            for pname, value in spec.parameters.items():
                self._parameter(name, desc, pname, value)
            if desc is not None and self.hooks.parameter_check is not None and len(self.problems) == unit_problems:
                self.problems += _domain_problems(self.loaded, name, desc, self.fmu_paths[name],
                                                  self.parameters[name], self.hooks)

    def _parameter(self, name: str, desc: UnitDescription | None, pname: str, value: Any) -> None:
        """One parameter: its value checked and put into ``parameters``, or its problem recorded."""
        key = ("units", name, "parameters", pname)
        hooks = self.hooks
        if isinstance(value, DataFile):
            value = self._data_file(name, desc, pname, value)
            if value is None:
                return
        elif isinstance(value, str) and value and desc is not None and hooks.data_kind is not None:
            text = _plain_path_problem(value, hooks.data_kind(desc, pname), hooks)
            if text is not None:
                self.problem(text, *key)
                return
        if desc is None:
            return
        var = desc.variables.get(pname)
        if var is None:
            settable = [v.name for v in desc.variables.values()
                        if v.causality in ("parameter", "input") and v.variability != "constant"]
            self.problem(f"{desc.model_identifier} has no variable {pname!r}{did_you_mean(pname, settable)}", *key)
            return
        if var.causality not in ("parameter", "input") or var.variability == "constant":
            self.problem(f"{pname!r} is a {var.variability} {var.causality}, not a settable parameter", *key)
            return
        text = _not_exchanged(var)
        if text is None:
            value, text = typed_parameter(var, value, desc.fmi_version)
        if text is None:
            text = _choice_problem(var, value) or _bounds_problem(var, value)
        if text is not None:
            self.problem(text, *key)
            return
        self.parameters[name][pname] = value

    def _data_file(self, name: str, desc: UnitDescription | None, pname: str, value: DataFile) -> str | None:
        """A ``!kind`` data file found on the data path and checked as its kind: its path (hashed), or None."""
        key = ("units", name, "parameters", pname)
        hooks = self.hooks
        try:
            found = find_data_file(value.name, self.data_dirs, self.loaded.base_dir(*key), hooks.default_data_dirs)
        except OSError as exc:  # not found, not a regular file, not readable
            self.problem(str(exc), *key)
            return None
        kind = value.kind
        if kind == "data" and desc is not None and hooks.data_kind is not None:
            kind = hooks.data_kind(desc, pname) or kind
        check = hooks.data_checks.get(kind)
        text = check(found) if check is not None else None
        if text is not None:
            self.problem(text, *key)
            return None
        self.data_files[f"{name}.{pname}"] = found
        self.hashes[str(found)] = _hash(found)
        return str(found)

    # -- ports and connections --------------------------------------------------------------------------
    def port(self, ref: VariableRef, causality: str, *key: Any, also: tuple[str, ...] = ()) -> Port | None:
        """The port a reference names, if it is a variable of that causality the master exchanges; else None."""
        desc = self.descriptions.get(ref.unit)
        if ref.unit not in self.sc.units:
            self.problem(f"no unit named {ref.unit!r} (units: {', '.join(self.sc.units)})", *key)
            return None
        if desc is None:
            return None  # the unit's own problem is reported already
        var = desc.variables.get(ref.name)
        if var is None:
            wanted = [v.name for v in desc.variables.values() if v.causality in (causality, *also)]
            hint = did_you_mean(ref.name, wanted)
            self.problem(f"{ref.unit} ({desc.model_identifier}) has no variable {ref.name!r}{hint}", *key)
            return None
        if var.causality != causality and var.causality not in also:
            expected = " or ".join((causality, *also))
            self.problem(f"{ref} is {var.causality}, expected {expected}", *key)
            return None
        text = _not_exchanged(var)
        if text is not None:
            self.problem(f"{ref}: {text}", *key)
            return None
        return (ref.unit, ref.name)

    def connections(self) -> list[Link]:
        """The scenario's connections as links: both ends exist and match in type, items and unit, each input
        driven once."""
        links: list[Link] = []
        driven: dict[Port, int] = {}
        for k, conn in enumerate(self.sc.connections):
            src = self.port(conn.source, "output", "connections", k)
            dst = self.port(conn.target, "input", "connections", k)
            if src is None or dst is None:
                continue
            text = self._connection_problem(conn, src, dst)
            if text is None and dst in driven:
                text = f"{conn.target} is already driven by connections[{driven[dst]}]"
            if text is not None:
                self.problem(text, "connections", k)
                continue
            driven[dst] = k
            links.append(Link(src, dst, conn.delayed))
        return links

    def _connection_problem(self, conn: Any, src: Port, dst: Port) -> str | None:
        """Why two ports cannot be connected (type, enumeration items, physical unit), or None (unit warnings
        are warned once)."""
        vs = self.descriptions[src[0]].variables[src[1]]
        vd = self.descriptions[dst[0]].variables[dst[1]]
        if exchange_kind(vs.fmi_type) != exchange_kind(vd.fmi_type):
            return (f"type mismatch: {conn.source} is {vs.fmi_type}, {conn.target} is {vd.fmi_type} "
                    "(connections join equal types; the master converts none)")
        if vs.fmi_type == "Enumeration" and vs.items and vd.items and sorted(vs.items) != sorted(vd.items):
            return f"enumeration mismatch: {conn.source} has items {_items(vs)}, {conn.target} has {_items(vd)}"
        unit_problem, unit_warning = connection_units(str(conn.source), str(conn.target), vs.unit, vd.unit)
        if unit_problem:
            return unit_problem
        if unit_warning:
            warn_once(unit_warning)
        return None

    def check_links_of_own_steps(self, links: list[Link], periods: dict[str, int]) -> None:
        """The grid rules of units with their own step are the Real fast path's: their links carry Reals only."""
        for link in links:
            for end in (link.source, link.target):
                var = self.descriptions[end[0]].variables[end[1]]
                if end[0] in periods and not var.fast_real:
                    self.problem(f"{end[0]}.{end[1]} is {var.fmi_type} and connected: a unit with its own step "
                                 f"exchanges Real values only (leave units.{end[0]}.step out)", "units", end[0], "step")

    def check_unconnected_inputs(self, links: list[Link]) -> None:
        """Every input is connected, set as a parameter, or has a start value."""
        driven = {link.target for link in links}
        for name, desc in self.descriptions.items():
            for var in desc.inputs():
                if (name, var.name) not in driven and var.start is None and var.name not in self.parameters[name]:
                    self.problem(f"input {var.name!r} is not connected and has no start value", "units", name)

    # -- the report section, recorded variables and limits -------------------------------------------------
    def report_section(self) -> ReportSpec | None:
        """The report section as the application's model reads it; its placeholders name units."""
        hooks, sc = self.hooks, self.sc
        report, report_problems = check_report(self.loaded, hooks.report.model if hooks.report is not None
                                               else ReportSpec)
        self.problems += report_problems
        for where, text in report.templates() if report is not None else ():
            for m in PLACEHOLDER.finditer(text):
                if m.group(1) not in sc.units:
                    self.problem(f"{{{m.group(1)}.{m.group(2)}}}: no unit named {m.group(1)!r} "
                                 f"(units: {', '.join(sc.units)})", "report", *where)
        return report

    def recorded(self, report: ReportSpec | None) -> list[Port]:
        """The recorded ports: the scenario's outputs, the report's variables, the report's optional variables
        where the unit has them."""
        recorded: list[Port] = []
        if self.sc.outputs == "all":  # every output the master can exchange (no Binary, clocks, arrays)
            recorded = [(n, v.name) for n, d in self.descriptions.items() for v in d.outputs()
                        if _not_exchanged(v) is None]
        else:
            for k, ref in enumerate(self.sc.outputs):
                p = self.port(ref, "output", "outputs", k, also=("local",))  # a local is recorded only when named
                if p is not None and p not in recorded:
                    recorded.append(p)
        for key, ref in report.variables() if report is not None else ():
            p = self.port(ref, "output", "report", *key)
            if p is not None and p not in recorded:
                recorded.append(p)
        for ref in report.optional_variables() if report is not None else ():  # recorded where the unit has them
            var = self.descriptions[ref.unit].variables.get(ref.name) if ref.unit in self.descriptions else None
            if (var is not None and var.causality in ("output", "local") and _not_exchanged(var) is None
                    and (ref.unit, ref.name) not in recorded):
                recorded.append((ref.unit, ref.name))
        return recorded

    def limits(self) -> dict[Port, float]:
        """The ``limits.max_abs`` bounds by port (numbers only)."""
        limits: dict[Port, float] = {}
        for text, limit in self.sc.limits.max_abs.items():
            p = self.port(VariableRef.parse(text), "output", "limits", "max_abs", text)
            if p is not None and self.descriptions[p[0]].variables[p[1]].fmi_type == "String":
                self.problem(f"{text} is a String: max_abs needs a number", "limits", "max_abs", text)
            elif p is not None:
                limits[p] = limit
        return limits

    # -- the system as a whole ----------------------------------------------------------------------------
    def check_system(self, links: list[Link], watched: list[Port]) -> None:
        """The unit order lists every unit, no algebraic loop (when all else is fine), the executor can run it."""
        sc, loaded, descriptions = self.sc, self.loaded, self.descriptions
        order = sc.simulation.order
        if order is not None and sorted(order) != sorted(sc.units):
            self.problem(f"must list every unit once: {', '.join(sc.units)}", "simulation", "order")
        if len(descriptions) == len(sc.units) and not self.problems:
            try:
                propagation_order(descriptions, links)
            except AlgebraicLoopError as exc:
                self.problem(str(exc), "connections")
        if sc.simulation.executor == "native" and len(descriptions) == len(sc.units):
            text = _native_problem(loaded, descriptions, links, watched)
            if text is not None:
                self.problem(text, "simulation", "executor")

    def check_result_size(self, n_recorded: int) -> None:
        text = result_size_problem(self.sc.simulation, n_recorded, Path(self.sc.results.dir))
        if text is not None:
            self.problem(text, "simulation", "stop_time")


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
    resolved = {v.name: start_value(v) for v in desc.variables.values()
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
