"""From a scenario to a runnable system: FMUs found (and, through a hook, built), everything checked up front.

:func:`resolve` reads every FMU's model description (no binary is loaded), resolves data
files through the data path, and checks parameters, connections, recorded variables,
limits and loops against the descriptions. All problems are collected into one
ScenarioError, each with the file, line and key it comes from.

Before anything runs it also checks that every FMU holds a library for this platform
that can be loaded (:func:`~orchestration.master.fmu_file.check_binary`), that a String
parameter whose description starts with its quoted choices (``'sosm' or 'passive'``) is
set to one of them, and that the recorded results fit on disk
(:func:`~orchestration.master.scenario.result_size_problem`).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.datapath import find_data_file
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.fmi_status import LogRecord
from orchestration.master.fmu3_unit import Fmu3Unit
from orchestration.master.fmu_file import FmuFormatError, check_binary, read_description
from orchestration.master.fmu_unit import FmuUnit
from orchestration.master.graph import AlgebraicLoopError, Link, Port, propagation_order
from orchestration.master.report import PLACEHOLDER
from orchestration.master.scenario import LoadedScenario, Scenario, VariableRef, result_size_problem
from orchestration.master.unit import (
    EXCHANGED_TYPES,
    INTEGER_RANGES,
    UnitDescription,
    Variable,
    exchange_kind,
    value_range,
)
from orchestration.master.yaml_source import DataFile

_QUOTED = r"""(?:'[^'\n]*'|"[^"\n]*")"""
_CHOICES = re.compile(rf"^\s*(?:one of:?\s*)?({_QUOTED}(?:\s*(?:,|\bor\b|\|)\s*{_QUOTED})+)")


def declared_choices(description: str) -> tuple[str, ...]:
    """The values a String variable accepts when its description starts with them quoted, e.g.
    ``'sosm' or 'passive' (constant current)``; empty when it declares none."""
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

    def create_units(self, on_log: Callable[[str, LogRecord], None] | None = None) -> list[FmuUnit | Fmu3Unit]:
        """Fresh FMU units in declaration order (nothing is instantiated yet); FMI 3.0 FMUs as Fmu3Unit, units run as
        model exchange (the scenario's ``interface``, or an FMU without co-simulation) as MeUnit."""
        from orchestration.master.me_unit import MeUnit, runs_as_model_exchange

        units: list[FmuUnit | Fmu3Unit] = []
        for name, desc in self.descriptions.items():
            spec, args = self.loaded.scenario.units[name], (name, self.fmu_paths[name], self.parameters[name], on_log)
            if runs_as_model_exchange(self.fmu_paths[name], spec.interface):
                units.append(MeUnit(*args, relative_tolerance=spec.relative_tolerance))
            else:
                units.append((Fmu3Unit if desc.fmi_version.startswith("3.") else FmuUnit)(*args))
        return units

    def create_algorithm(self, units: list[FmuUnit]) -> CouplingAlgorithm:
        """The coupling algorithm for these units, as the scenario chose it."""
        sim = self.loaded.scenario.simulation
        return CouplingAlgorithm(units, self.links, self.recorded + list(self.limits), sim.algorithm, sim.order,
                                 sim.inputs)


@dataclass(frozen=True)
class ResolveHooks:
    """What an application adds to the engine's checks; the engine itself knows no FMU sources or file formats.

    ``prepare_fmu(path)`` may build or refresh an FMU before its description is read and
    returns a problem text or None; ``data_checks[kind](path)`` checks a data file named
    with ``!kind`` and returns a problem text or None; ``default_data_dirs`` are searched
    after ``--data-dir`` and ``MRE_COSIM_DATA``; ``provenance()`` says what made the run
    (package version, source revision) for the manifest.
    """

    prepare_fmu: Callable[[Path], str | None] | None = None
    data_checks: Mapping[str, Callable[[Path], str | None]] = field(default_factory=dict)
    default_data_dirs: tuple[Path, ...] = ()
    provenance: Callable[[], dict[str, Any]] | None = None


def _prepare(path: Path, hooks: ResolveHooks) -> str | None:
    if hooks.prepare_fmu is not None:
        return hooks.prepare_fmu(path)
    return None if path.is_file() else f"FMU file {path} does not exist"


def resolve(loaded: LoadedScenario, data_dirs: tuple[Path, ...] = (), hooks: ResolveHooks | None = None) -> SystemPlan:
    """Check a loaded scenario against its FMUs; raises ScenarioError listing every problem."""
    hooks = hooks or ResolveHooks()
    sc = loaded.scenario
    problems: list[Problem] = []
    descriptions: dict[str, UnitDescription] = {}
    fmu_paths: dict[str, Path] = {}
    parameters: dict[str, dict[str, Any]] = {}
    data_files: dict[str, Path] = {}

    for name in sc.units:
        path = loaded.fmu_path(name)
        fmu_paths[name] = path
        looping = path.is_symlink() and not path.exists()
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

    for name, spec in sc.units.items():
        parameters[name] = {}
        desc = descriptions.get(name)
        for pname, value in spec.parameters.items():
            if isinstance(value, DataFile):
                try:
                    found = find_data_file(value.name, data_dirs, loaded.base_dir("units", name, "parameters", pname),
                                           hooks.default_data_dirs)
                except FileNotFoundError as exc:
                    problems.append(loaded.problem(str(exc), "units", name, "parameters", pname))
                    continue
                check = hooks.data_checks.get(value.kind)
                text = check(found) if check is not None else None
                if text is not None:
                    problems.append(loaded.problem(text, "units", name, "parameters", pname))
                    continue
                data_files[f"{name}.{pname}"] = found
                value = str(found)
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
            text = _choice_problem(var, value)
            if text is not None:
                problems.append(loaded.problem(text, "units", name, "parameters", pname))
                continue
            parameters[name][pname] = value

    def port(ref: VariableRef, causality: str, *key: Any) -> Port | None:
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
        if var.causality != causality:
            problems.append(loaded.problem(f"{ref} is {var.causality}, expected {causality}", *key))
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
        if vs.unit and vd.unit and vs.unit != vd.unit:
            problems.append(loaded.problem(f"unit mismatch: {conn.source} is in {vs.unit}, {conn.target} in {vd.unit}",
                                           "connections", k))
            continue
        if dst in driven:
            problems.append(loaded.problem(f"{conn.target} is already driven by connections[{driven[dst]}]",
                                           "connections", k))
            continue
        driven[dst] = k
        links.append(Link(src, dst, conn.delayed))

    for name, desc in descriptions.items():
        for var in desc.inputs():
            if (name, var.name) not in driven and var.start is None and var.name not in parameters[name]:
                problems.append(loaded.problem(f"input {var.name!r} is not connected and has no start value",
                                               "units", name))

    for where, text in _report_templates(sc):
        for m in PLACEHOLDER.finditer(text):
            if m.group(1) not in sc.units:
                problems.append(loaded.problem(f"{{{m.group(1)}.{m.group(2)}}}: no unit named {m.group(1)!r} "
                                               f"(units: {', '.join(sc.units)})", "report", *where))

    recorded: list[Port] = []
    if sc.outputs == "all":  # every output the master can exchange (FMI 3.0 Binary, clocks, arrays are left out)
        recorded = [(n, v.name) for n, d in descriptions.items() for v in d.outputs() if _not_exchanged(v) is None]
    else:
        for k, ref in enumerate(sc.outputs):
            p = port(ref, "output", "outputs", k)
            if p is not None and p not in recorded:
                recorded.append(p)
    for key, refs in (("report", sc.report.variables()),):
        for ref in refs:
            p = port(ref, "output", key)
            if p is not None and p not in recorded:
                recorded.append(p)
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

    text = result_size_problem(sc.simulation, len(recorded), Path(sc.results.dir))
    if text is not None:
        problems.append(loaded.problem(text, "simulation", "stop_time"))

    if problems:
        raise ScenarioError(problems)
    provenance = hooks.provenance() if hooks.provenance is not None else {}
    return SystemPlan(loaded, fmu_paths, descriptions, parameters, links, recorded, limits, data_files, provenance)


def _items(var: Variable) -> str:
    return ", ".join(f"{name} = {number}" for name, number in var.items)


def _report_templates(sc: Scenario) -> list[tuple[tuple[str, ...], str]]:
    """Every text in ``report`` that may name ``{unit.param}`` or ``unit.param``, with its key."""
    spec = sc.report
    out: list[tuple[tuple[str, ...], str]] = [(("caption",), spec.caption)]
    for key, text in spec.labels.items():
        out += [(("labels", key), text), (("labels", key), "{" + key.split("=", 1)[0] + "}")]
    out += [(("displacement_limits", label), "{" + ref + "}") for label, ref in spec.displacement_limits.items()
            if isinstance(ref, str)]
    return out
