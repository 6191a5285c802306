"""SSP 1.0 packages: export any scenario to ``.ssp`` and load an ``.ssp`` as a runnable scenario.

Package layout written by :func:`export_ssp`::

    SystemStructure.ssd          ssd:SystemStructureDescription (SSP 1.0)
    resources/<Model>.fmu        every FMU the scenario uses (once per file)
    resources/<unit>.ssv         ssv:ParameterSet with the scenario's parameter values of a unit, named
                                 after the scenario (the same name in every set)
    resources/<record>           data files named with ``!data`` (ground-motion records)

The SSD holds one ``ssd:System`` with a ``ssd:Component`` per unit (``source`` =
``resources/<Model>.fmu``), its ``ssd:Connectors`` (every input, output and parameter of
the FMU, with its kind and ``ssc:Real unit``), the connections, the units' definitions
(``ssd:Units``) and ``ssd:DefaultExperiment`` (start and stop time). What SSP 1.0 has no
element for travels in annotations of type ``org.mre-cosim.*`` that other tools ignore:

* ``org.mre-cosim.scenario`` (in DefaultExperiment): every scenario setting besides the
  units, connections and times, as JSON (communication step, algorithm, stepping order,
  input rule, recorded outputs, report roles, limits, results folder, description);
* ``org.mre-cosim.connection`` (on a Connection): ``delayed="true"``;
* ``com.opensimulationplatform`` (on a Component, when the scenario sets ``units.NAME.step``):
  ``<osp:StepSizeHint value="0.001"/>``, the unit's own step [s], as the Open Simulation Platform
  writes it (libcosim steps the unit every value/step base steps, its decimation factor);
* ``org.mre-cosim.unit`` (on a Component, only when the scenario chose them):
  ``<mre:Interface name="model-exchange" relativeTolerance="1e-08"/>``, the FMU interface
  the unit runs and its solver's relative tolerance;
* ``org.mre-cosim.data-file`` (on an ssv:Parameter): the String value is a file of the
  package, a path relative to the package root (``resources/kobe.csv``), and
  ``<mre:DataFile kind="record"/>`` its kind (the scenario's tag: ``!record`` files are
  checked before a run). A tool that does not know the annotation passes the string on
  unchanged, which works when it runs from the extracted package's root folder.

:func:`load_ssp` extracts a package into a folder, validates the SSD and parameter sets
against the SSP 1.0 schemas fmpy ships, checks every reference (FMU files, parameter
sets, data files, connection endpoints against the declared connectors and the FMUs'
variables) and returns a :class:`LoadedSsp`, a :class:`~orchestration.master.scenario.LoadedScenario`
whose problems point at lines of the SSD or SSV files. ``system.resolve`` and
``session.run_plan`` take it like one loaded from YAML.

A package is untrusted input: it is extracted within the archive limits of
:func:`~orchestration.master.safe_archive.safe_extract` (size, entry count, no entry outside
the folder, no links), XML entities are not expanded, values must parse and be finite,
and the settings annotation may set only :data:`SETTINGS_KEYS` (not the units,
connections or name, which the SSD gives), with ``results.dir`` a relative path inside
the working folder.

The command-line tool is ``orchestration/ssp.py`` (``export`` and ``check``).
"""

from __future__ import annotations

import json
import math
import shutil
import sys
import tempfile
import weakref
import zipfile
from pathlib import Path, PurePosixPath
from typing import Any, BinaryIO

from lxml import etree
from pydantic import ValidationError

from mre_common.atomic_files import atomic_write
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.fmu_description import FmuFormatError, read_description
from orchestration.master.resolve import SystemPlan
from orchestration.master.safe_archive import ArchiveError, safe_extract
from orchestration.master.scenario import LoadedScenario, Scenario, validation_problems
from orchestration.master.unit import INTEGER_RANGES
from orchestration.master.yaml_source import DataFile, Lines, apply_override, resolved

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
MRE = "urn:mre-cosim:ssp:1"
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"
NS = {"ssd": SSD, "ssc": SSC, "ssv": SSV, "mre": MRE, "osp": OSP}
OSP_ANNOTATION = "com.opensimulationplatform"  # libcosim's: <osp:StepSizeHint value="..."/>, a unit's own step [s]
SSD_FILE = "SystemStructure.ssd"
FMU_TYPE = "application/x-fmu-sharedlibrary"
SSV_TYPE = "application/x-ssp-parameter-set"
SETTINGS_ANNOTATION = "org.mre-cosim.scenario"
CONNECTION_ANNOTATION = "org.mre-cosim.connection"
UNIT_ANNOTATION = "org.mre-cosim.unit"
DATA_FILE_ANNOTATION = "org.mre-cosim.data-file"
VALUE_ANNOTATION = "org.mre-cosim.value"
"""On a String parameter: its value is an integer of the FMI type named (SSP 1.0's Integer is 32-bit)."""
XS_INT = (-(2**31), 2**31 - 1)
"""The range of SSP 1.0's ssv:Integer (xs:int)."""
CONNECTOR_KINDS = ("input", "output", "parameter", "calculatedParameter")
_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
SETTINGS_KEYS = {"format", "description", "simulation", "outputs", "results", "report", "limits"}
"""What the settings annotation may set (the SSD gives the name, units, connections and times)."""
SIMULATION_KEYS = {"step", "algorithm", "inputs", "order", "executor", "output_interval", "output_format"}
"""What it may set under ``simulation``."""
MAX_XML_BYTES = 64 << 20
"""Largest SSD or SSV file parsed."""
_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False, load_dtd=False)


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def schema_dir() -> Path:
    """The SSP 1.0 XML schemas shipped with fmpy."""
    import fmpy.ssp

    return Path(fmpy.ssp.__file__).resolve().parent / "schema"


_SCHEMAS: dict[str, etree.XMLSchema] = {}


def schema_errors(root: etree._Element, schema_file: str) -> list[tuple[int | None, str]]:
    """(line, message) for every violation of an SSP schema (empty when valid)."""
    if schema_file not in _SCHEMAS:
        _SCHEMAS[schema_file] = etree.XMLSchema(etree.parse(str(schema_dir() / schema_file)))
    schema = _SCHEMAS[schema_file]
    if schema.validate(root):
        return []
    return [(e.line, e.message) for e in schema.error_log]


# -- export -------------------------------------------------------------------------------------


def _unique_names(paths: list[Path]) -> dict[Path, str]:
    """File name in resources/ per distinct source file (suffixed where names collide)."""
    names: dict[Path, str] = {}
    taken: set[str] = set()
    for path in paths:
        if path in names:
            continue
        stem, suffix, k = path.stem, path.suffix, 1
        name = path.name
        while name in taken:
            k += 1
            name = f"{stem}_{k}{suffix}"
        taken.add(name)
        names[path] = name
    return names


def _annotation(parent: etree._Element, prefix: str, kind: str) -> etree._Element:
    annotations = parent.find(_q(prefix, "Annotations"))  # one Annotations element holds them all
    if annotations is None:
        annotations = etree.SubElement(parent, _q(prefix, "Annotations"))
    return etree.SubElement(annotations, _q("ssc", "Annotation"), type=kind)


def _settings(scenario: Scenario) -> dict[str, Any]:
    """The scenario's settings SSP has no element for (JSON-ready): everything but units and connections."""
    def compact(value: Any) -> Any:  # variable references as "unit.variable", as in YAML
        if isinstance(value, dict):
            if set(value) == {"unit", "name"}:
                return f"{value['unit']}.{value['name']}"
            return {k: compact(v) for k, v in value.items()}
        if isinstance(value, list):
            return [compact(v) for v in value]
        return value

    settings = compact(scenario.model_dump(mode="json", exclude={"name", "units", "connections"}))
    if scenario.report is not None:  # only what the scenario set: an application's defaults are its own to fill in
        settings["report"] = compact(scenario.report.model_dump(mode="json", exclude_unset=True))
    for key in ("start_time", "stop_time"):  # in DefaultExperiment
        settings["simulation"].pop(key)
    return {"format": 1, **settings}


def _unit_definitions(plan: SystemPlan, used: set[str]) -> dict[str, Any]:
    """Unit name -> fmpy BaseUnit (or None) from the FMUs' UnitDefinitions."""
    from fmpy import read_model_description

    found: dict[str, Any] = {}
    for path in set(plan.fmu_paths.values()):
        for unit in read_model_description(str(path), validate=False).unitDefinitions:
            if unit.name in used:
                found.setdefault(unit.name, unit.baseUnit)
    for name in used:
        found.setdefault(name, None)
    return found


def _write_units(parent: etree._Element, prefix: str, definitions: dict[str, Any]) -> None:
    if not definitions:
        return
    units = etree.SubElement(parent, _q(prefix, "Units"))
    for name in sorted(definitions):
        unit = etree.SubElement(units, _q("ssc", "Unit"), name=name)
        base = definitions[name]
        attrs = {}
        if base is not None:
            for key in ("kg", "m", "s", "A", "K", "mol", "cd", "rad"):
                if getattr(base, key):
                    attrs[key] = str(getattr(base, key))
            if base.factor != 1.0:
                attrs["factor"] = repr(float(base.factor))
            if base.offset != 0.0:
                attrs["offset"] = repr(float(base.offset))
        etree.SubElement(unit, _q("ssc", "BaseUnit"), attrs)


def _parameter_set(plan: SystemPlan, unit: str, data_names: dict[str, str]) -> etree._Element:
    desc = plan.descriptions[unit]
    # One name for every unit's set (the scenario's): engines that pick parameter sets by name across
    # components (ecos: init(parameter_set=...)) then apply all of them.
    root = etree.Element(_q("ssv", "ParameterSet"), nsmap={"ssv": SSV, "ssc": SSC, "mre": MRE}, version="1.0",
                         name=plan.loaded.scenario.name)
    params = etree.SubElement(root, _q("ssv", "Parameters"))
    used: set[str] = set()
    for pname, value in plan.parameters[unit].items():
        var = desc.variables[pname]
        node = etree.SubElement(params, _q("ssv", "Parameter"), name=pname)
        key = f"{unit}.{pname}"
        if key in data_names:
            etree.SubElement(node, _q("ssv", "String"), value=f"resources/{data_names[key]}")
            ann = _annotation(node, "ssv", DATA_FILE_ANNOTATION)
            kind = plan.loaded.scenario.units[unit].parameters.get(pname)
            if isinstance(kind, DataFile):
                etree.SubElement(ann, _q("mre", "DataFile"), kind=kind.kind)
        elif var.type in ("Real", "Float32"):  # a Float32 value is exactly an xs:double
            attrs = {"value": repr(float(value))}
            if var.unit:
                attrs["unit"] = var.unit
                used.add(var.unit)
            etree.SubElement(node, _q("ssv", "Real"), attrs)
        elif var.type in INTEGER_RANGES or var.type in ("Integer", "Enumeration"):
            if XS_INT[0] <= int(value) <= XS_INT[1]:
                etree.SubElement(node, _q("ssv", "Integer"), value=str(int(value)))
            else:  # SSP 1.0 has no 64-bit integer: the digits as a String, the FMI type in an annotation
                etree.SubElement(node, _q("ssv", "String"), value=str(int(value)))
                etree.SubElement(_annotation(node, "ssv", VALUE_ANNOTATION), _q("mre", "Value"), type=var.fmi_type)
        elif var.type == "Boolean":
            etree.SubElement(node, _q("ssv", "Boolean"), value="true" if value else "false")
        else:
            etree.SubElement(node, _q("ssv", "String"), value=_xml_text(str(value), f"units.{unit}.parameters.{pname}"))
    _write_units(root, "ssv", _unit_definitions(plan, used) if used else {})
    return root


def _system_structure(plan: SystemPlan, fmu_names: dict[Path, str], with_ssv: set[str]) -> etree._Element:
    sc = plan.loaded.scenario
    nsmap = {"ssd": SSD, "ssc": SSC, "mre": MRE, "osp": OSP}
    root = etree.Element(_q("ssd", "SystemStructureDescription"), nsmap=nsmap, version="1.0", name=sc.name,
                         generationTool="mre-cosim orchestration/interop/ssp_package.py")
    system = etree.SubElement(root, _q("ssd", "System"), name=sc.name)
    if sc.description:
        system.set("description", _xml_text(sc.description, "description"))
    elements = etree.SubElement(system, _q("ssd", "Elements"))
    used: set[str] = set()
    for unit, desc in plan.descriptions.items():
        comp = etree.SubElement(elements, _q("ssd", "Component"), name=unit, type=FMU_TYPE,
                                source=f"resources/{fmu_names[plan.fmu_paths[unit]]}")
        connectors = etree.SubElement(comp, _q("ssd", "Connectors"))
        for var in desc.variables.values():
            if var.causality not in CONNECTOR_KINDS:
                continue
            conn = etree.SubElement(connectors, _q("ssd", "Connector"), name=var.name, kind=var.causality)
            if var.type == "Real":
                etree.SubElement(conn, _q("ssc", "Real"), {"unit": var.unit} if var.unit else {})
                if var.unit:
                    used.add(var.unit)
            elif var.type in ("Integer", "Boolean", "String"):
                etree.SubElement(conn, _q("ssc", var.type))
        if unit in with_ssv:
            bindings = etree.SubElement(comp, _q("ssd", "ParameterBindings"))
            etree.SubElement(bindings, _q("ssd", "ParameterBinding"), type=SSV_TYPE, source=f"resources/{unit}.ssv")
        spec = sc.units[unit]
        if spec.interface is not None or spec.relative_tolerance is not None:
            attrs = {"name": spec.interface} if spec.interface is not None else {}
            if spec.relative_tolerance is not None:
                attrs["relativeTolerance"] = repr(float(spec.relative_tolerance))
            etree.SubElement(_annotation(comp, "ssd", UNIT_ANNOTATION), _q("mre", "Interface"), attrs)
        if spec.step is not None:  # the unit's own step, as libcosim reads it (its decimation factor)
            etree.SubElement(_annotation(comp, "ssd", OSP_ANNOTATION), _q("osp", "StepSizeHint"),
                             value=repr(float(spec.step)))
    if sc.connections:
        connections = etree.SubElement(system, _q("ssd", "Connections"))
        for c in sc.connections:
            node = etree.SubElement(connections, _q("ssd", "Connection"), startElement=c.source.unit,
                                    startConnector=c.source.name, endElement=c.target.unit,
                                    endConnector=c.target.name)
            if c.delayed:
                ann = _annotation(node, "ssd", CONNECTION_ANNOTATION)
                etree.SubElement(ann, _q("mre", "Coupling"), delayed="true")
    _write_units(root, "ssd", _unit_definitions(plan, used))
    sim = sc.simulation
    experiment = etree.SubElement(root, _q("ssd", "DefaultExperiment"), startTime=repr(float(sim.start_time)),
                                  stopTime=repr(float(sim.stop_time)))
    ann = _annotation(experiment, "ssd", SETTINGS_ANNOTATION)
    etree.SubElement(ann, _q("mre", "Settings")).text = json.dumps(_settings(sc), indent=1)
    return root


def _xml_text(text: str, key: str) -> str:
    """``text`` if XML 1.0 can hold it; a ScenarioError naming ``key`` and the character otherwise."""
    bad = next((c for c in text if not _xml_char(c)), None)
    if bad is not None:
        raise ScenarioError([Problem(f"U+{ord(bad):04X} at character {text.index(bad) + 1} cannot be written to an "
                                     "SSP package (XML 1.0 has no such character)", key)])
    return text


def _xml_char(c: str) -> bool:
    """A character XML 1.0 allows (its Char production)."""
    o = ord(c)
    return o in (0x9, 0xA, 0xD) or 0x20 <= o <= 0xD7FF or 0xE000 <= o <= 0xFFFD or 0x10000 <= o <= 0x10FFFF


def _check_schema(root: etree._Element, schema_file: str, name: str) -> None:
    errors = schema_errors(root, schema_file)
    if errors:  # a bug in the exporter, not a user error
        raise RuntimeError(f"exported {name} violates {schema_file}: " + "; ".join(f"line {n}: {m}" for n, m in errors))


def export_ssp(plan: SystemPlan, dest: Path | str) -> Path:
    """Write a checked scenario as an SSP 1.0 package; returns its path.

    The FMUs and data files are copied into the package.
    """
    dest = Path(dest)
    fmu_names = _unique_names(list(plan.fmu_paths.values()))
    data_names_by_path = _unique_names(list(plan.data_files.values()))
    data_names = {key: data_names_by_path[p] for key, p in plan.data_files.items()}
    if set(fmu_names.values()) & set(data_names.values()):
        raise ScenarioError("a data file has the same name as an FMU; rename one of them")
    ssv = {unit: _parameter_set(plan, unit, data_names) for unit in plan.descriptions if plan.parameters[unit]}
    ssd = _system_structure(plan, fmu_names, set(ssv))
    _check_schema(ssd, "SystemStructureDescription.xsd", SSD_FILE)
    for unit, root in ssv.items():
        _check_schema(root, "SystemStructureParameterValues.xsd", f"{unit}.ssv")

    dest.parent.mkdir(parents=True, exist_ok=True)

    def write(f: BinaryIO) -> None:
        with zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr(SSD_FILE, etree.tostring(ssd, xml_declaration=True, encoding="UTF-8", pretty_print=True))
            for path, name in fmu_names.items():
                z.write(path, f"resources/{name}")
            for unit, root in ssv.items():
                z.writestr(f"resources/{unit}.ssv",
                           etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True))
            for path, name in data_names_by_path.items():
                z.write(path, f"resources/{name}")

    atomic_write(dest, write, binary=True)
    scripts = [f"{key} = resources/{data_names[key]}" for key, p in plan.data_files.items() if is_script(key, p)]
    if scripts:
        print(f"note: {dest.name} carries {'a script' if len(scripts) == 1 else 'scripts'} that a unit runs as code "
              f"whenever the package is run: {', '.join(scripts)}", file=sys.stderr, flush=True)
    return dest


# -- import -------------------------------------------------------------------------------------


class LoadedSsp(LoadedScenario):
    """A scenario loaded from an SSP package; ``workdir`` holds the extracted package."""

    def __init__(self, scenario: Scenario, path: Path, lines: Lines, raw: dict[str, Any], workdir: Path,
                 owned: bool) -> None:
        super().__init__(scenario, path, lines, raw)
        self.workdir = workdir
        self._cleanup = weakref.finalize(self, shutil.rmtree, workdir, True) if owned else None

    def cleanup(self) -> None:
        """Delete the extracted package if load_ssp created its folder (also done when collected)."""
        if self._cleanup is not None:
            self._cleanup()


class _Reader:
    """Reads one extracted package, collecting problems with their file and line."""

    def __init__(self, ssp: Path, root_dir: Path) -> None:
        self.ssp = ssp
        self.dir = root_dir
        self.problems: list[Problem] = []
        self.lines: Lines = {}

    def label(self, member: str) -> str:
        return f"{self.ssp}!/{member}"

    def problem(self, message: str, key: str, member: str, node: etree._Element | None = None) -> None:
        self.problems.append(Problem(message, key, self.label(member), None if node is None else node.sourceline))

    def at(self, key: tuple[Any, ...], member: str, node: etree._Element) -> None:
        self.lines[key] = (self.label(member), node.sourceline)

    def member(self, reference: str) -> Path | None:
        """The extracted file a package-relative reference names, or None (no schemes, no escaping)."""
        if not reference or ":" in reference.split("/")[0]:
            return None
        rel = PurePosixPath(reference)
        if rel.is_absolute() or ".." in rel.parts:
            return None
        path = self.dir.joinpath(*rel.parts)
        try:
            return path if path.is_file() else None
        except (OSError, ValueError):  # a name too long for the file system (ENAMETOOLONG), a NUL: no member
            return None

    def parse(self, member: str, schema_file: str, key: str) -> etree._Element | None:
        path = self.member(member)
        if path is None:
            return None
        if path.stat().st_size > MAX_XML_BYTES:
            self.problems.append(Problem(f"{path.stat().st_size:,} bytes, more than the {MAX_XML_BYTES:,} an SSP "
                                         "XML file may have", key, self.label(member)))
            return None
        try:
            tree = etree.parse(str(path), _PARSER)
        except etree.XMLSyntaxError as exc:
            self.problems.append(Problem(f"not well-formed XML: {exc}", key, self.label(member), exc.lineno))
            return None
        if tree.docinfo.doctype:  # entities are never expanded here, and SSP files declare none
            self.problems.append(Problem("a document type declaration (<!DOCTYPE ...>) is not allowed in an SSP "
                                         "file", key, self.label(member), 1))
            return None
        root = tree.getroot()
        for line, message in schema_errors(root, schema_file):
            self.problems.append(Problem(f"{schema_file}: {message}", key, self.label(member), line))
        return root


def _annotation_of(node: etree._Element, prefix: str, kind: str) -> etree._Element | None:
    for ann in node.findall(f"{prefix}:Annotations/ssc:Annotation", NS):
        if ann.get("type") == kind:
            return ann
    return None


def _number(text: str | None, integer: bool = False) -> float | int:
    """A finite xs:double (or an xs:int); ValueError naming the text otherwise."""
    raw = (text or "").strip()
    try:
        value = int(raw) if integer else float(raw)
    except (ValueError, OverflowError):
        raise ValueError(f"{text!r} is not {'an integer' if integer else 'a number'}") from None
    if (integer and not XS_INT[0] <= value <= XS_INT[1]) or (not integer and not math.isfinite(value)):
        raise ValueError(f"{text!r} is out of range" if integer else f"{text!r} is not finite")
    return value


def _typed_value(node: etree._Element) -> tuple[str, Any] | None:
    """(kind, value) of an ssv:Parameter; ValueError for a value that does not parse."""
    for kind in (*_TYPES, "Binary"):
        value = node.find(f"ssv:{kind}", NS)
        if value is None:
            continue
        text = value.get("value", "")
        if kind == "Real":
            return kind, _number(text)
        if kind in ("Integer", "Enumeration"):
            return kind, (_number(text, integer=True) if kind == "Integer" else None)
        if kind == "Boolean":
            if text.strip() not in ("true", "false", "1", "0"):
                raise ValueError(f"{text!r} is not a boolean (true, false, 1 or 0)")
            return kind, text.strip() in ("true", "1")
        if kind == "String":
            return kind, text
        return kind, None
    return None


def _annotated_integer(text: str, ann: etree._Element) -> int:
    """The integer a String parameter with the value annotation holds; ValueError if it is none of its type."""
    tag = ann.find("mre:Value", NS)
    fmi_type = "" if tag is None else tag.get("type", "")
    if fmi_type not in INTEGER_RANGES:
        raise ValueError(f"the {VALUE_ANNOTATION} annotation names {fmi_type!r}, not an integer type "
                         f"({', '.join(INTEGER_RANGES)})")
    try:
        value = int(text.strip())
    except ValueError:
        raise ValueError(f"{text!r} is not an integer") from None
    low, high = INTEGER_RANGES[fmi_type]
    if not low <= value <= high:
        raise ValueError(f"{value} is outside {fmi_type}'s range [{low}, {high}]")
    return value


def _read_parameters(reader: _Reader, unit: str, comp: etree._Element) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for b, binding in enumerate(comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)):
        found = _bound_parameter_set(reader, unit, b, binding)
        if found is None:
            continue
        member, root = found
        prefix = binding.get("prefix", "")
        for p in root.findall("ssv:Parameters/ssv:Parameter", NS):
            name = p.get("name", "")
            if prefix and name.startswith(prefix):
                name = name[len(prefix):]
            pkey = ("units", unit, "parameters", name)
            reader.at(pkey, member, p)
            value = _parameter_value(reader, unit, name, member, p)
            if value is not _SKIPPED:
                params[name] = value
    return params


_SKIPPED = object()  # a parameter with a problem (reported): not read


def _bound_parameter_set(reader: _Reader, unit: str, b: int,
                         binding: etree._Element) -> tuple[str, etree._Element] | None:
    """(package member, ssv:ParameterSet) of parameter binding ``b``; None after a problem reported."""
    key = f"units.{unit}.parameters"
    if binding.find("ssd:ParameterMapping", NS) is not None:
        reader.problem(f"component '{unit}': parameter mappings are not supported", key, SSD_FILE, binding)
        return None
    if binding.get("sourceBase", "SSD") != "SSD":
        reader.problem(f"component '{unit}': only parameter sets relative to the SSD are supported",
                       key, SSD_FILE, binding)
        return None
    source = binding.get("source")
    if source is not None:
        root = reader.parse(source, "SystemStructureParameterValues.xsd", key)
        if root is None and reader.member(source) is None:
            reader.problem(f"component '{unit}': parameter set '{source}' is not in the package",
                           key, SSD_FILE, binding)
        return None if root is None else (source, root)
    root = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
    if root is None:
        reader.problem(f"component '{unit}': parameter binding {b} has neither a source nor values",
                       key, SSD_FILE, binding)
        return None
    return SSD_FILE, root


def _parameter_value(reader: _Reader, unit: str, name: str, member: str, p: etree._Element) -> Any:
    """The value of parameter ``p`` (an integer of an annotated String, a DataFile, ...); _SKIPPED after a
    problem reported."""
    where = f"units.{unit}.parameters.{name}"
    try:
        typed = _typed_value(p)
    except ValueError as exc:
        reader.problem(f"component '{unit}', parameter '{name}': {exc}", where, member, p)
        return _SKIPPED
    if typed is None or typed[1] is None:
        kind = "no value" if typed is None else f"a {typed[0]} value"
        reader.problem(f"component '{unit}', parameter '{name}': {kind} is not supported", where, member, p)
        return _SKIPPED
    kind, value = typed
    typed_ann = _annotation_of(p, "ssv", VALUE_ANNOTATION) if kind == "String" else None
    if typed_ann is not None:
        try:
            return _annotated_integer(value, typed_ann)
        except ValueError as exc:
            reader.problem(f"component '{unit}', parameter '{name}': {exc}", where, member, p)
            return _SKIPPED
    ann = _annotation_of(p, "ssv", DATA_FILE_ANNOTATION) if kind == "String" else None
    if ann is None:
        return value
    path = reader.member(value)
    if path is None:
        reader.problem(f"component '{unit}', parameter '{name}': data file '{value}' is not in the package",
                       where, member, p)
        return _SKIPPED
    tag = ann.find("mre:DataFile", NS)
    return DataFile(str(path), "record" if tag is not None and tag.get("kind") == "record" else "data")


def _read_settings(reader: _Reader, ssd: etree._Element) -> tuple[dict[str, Any], dict[str, Any]]:
    """(simulation, other settings) from DefaultExperiment and the scenario annotation."""
    simulation: dict[str, Any] = {}
    settings: dict[str, Any] = {}
    experiment = ssd.find("ssd:DefaultExperiment", NS)
    if experiment is None:
        reader.problem("the SSD has no DefaultExperiment (start and stop time)", "simulation", SSD_FILE, ssd)
        return simulation, settings
    reader.at(("simulation",), SSD_FILE, experiment)
    for attr, key in (("startTime", "start_time"), ("stopTime", "stop_time")):
        if experiment.get(attr) is not None:
            try:
                simulation[key] = _number(experiment.get(attr))
            except ValueError as exc:
                reader.problem(f"DefaultExperiment {attr}: {exc}", f"simulation.{key}", SSD_FILE, experiment)
    ann = _annotation_of(experiment, "ssd", SETTINGS_ANNOTATION)
    node = None if ann is None else ann.find("mre:Settings", NS)
    if node is not None:
        try:
            settings = json.loads(node.text or "{}")
        except (json.JSONDecodeError, RecursionError) as exc:
            reason = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
            reader.problem(f"unreadable {SETTINGS_ANNOTATION} annotation: {reason}", "simulation", SSD_FILE, node)
            settings = {}
        if not isinstance(settings, dict) or not isinstance(settings.get("simulation", {}), dict):
            reader.problem(f"the {SETTINGS_ANNOTATION} annotation must be a JSON object", "simulation", SSD_FILE, node)
            settings = {}
        settings = _allowed_settings(reader, settings, node)
        for key, value in (settings.pop("simulation", None) or {}).items():
            if value is not None:
                simulation[key] = value
    return simulation, settings


def _allowed_settings(reader: _Reader, settings: dict[str, Any], node: etree._Element) -> dict[str, Any]:
    """The settings the annotation may set; a problem for every other key and for a results folder outside."""
    out = {}
    for key, value in settings.items():
        if key not in SETTINGS_KEYS:
            reader.problem(f"the {SETTINGS_ANNOTATION} annotation may not set '{key}' (it may set: "
                           f"{', '.join(sorted(SETTINGS_KEYS - {'format'}))})", key, SSD_FILE, node)
            continue
        out[key] = value
    for key in list(out.get("simulation") or {}):
        if key not in SIMULATION_KEYS:
            reader.problem(f"the {SETTINGS_ANNOTATION} annotation may not set simulation.{key} (it may set: "
                           f"{', '.join(sorted(SIMULATION_KEYS))})", f"simulation.{key}", SSD_FILE, node)
            del out["simulation"][key]
    results = out.get("results")
    folder = results.get("dir") if isinstance(results, dict) else None
    if isinstance(folder, str):
        parts = PurePosixPath(folder.replace("\\", "/")).parts
        if not parts or PurePosixPath(folder).is_absolute() or folder.startswith(("~", "\\")) or ".." in parts \
                or ":" in folder:
            reader.problem(f"results.dir {folder!r} must be a relative folder inside the working folder "
                           "(no '..', not absolute)", "results.dir", SSD_FILE, node)
            del out["results"]
    return out


def _read_system(reader: _Reader, ssd: etree._Element) -> dict[str, Any]:
    system = ssd.find("ssd:System", NS)
    data: dict[str, Any] = {"name": ssd.get("name") or reader.ssp.stem, "units": {}, "connections": []}
    reader.at(("units",), SSD_FILE, system)
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        reader.problem("nested systems are not supported", "units", SSD_FILE, system)
    if system.find("ssd:Elements/ssd:SignalDictionaryReference", NS) is not None:
        reader.problem("signal dictionaries are not supported", "units", SSD_FILE, system)
    connectors: dict[str, dict[str, str]] = {}
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        unit = comp.get("name", "")
        reader.at(("units", unit), SSD_FILE, comp)
        if comp.get("type", FMU_TYPE) != FMU_TYPE:
            reader.problem(f"component '{unit}': type {comp.get('type')!r} is not an FMU", f"units.{unit}.fmu",
                           SSD_FILE, comp)
            continue
        connectors[unit] = {c.get("name"): c.get("kind") for c in comp.findall("ssd:Connectors/ssd:Connector", NS)}
        data["units"][unit] = _read_component(reader, unit, comp)
    for k, conn in enumerate(system.findall("ssd:Connections/ssd:Connection", NS)):
        connection = _read_connection(reader, k, conn, connectors)
        if connection is not None:
            data["connections"].append(connection)
    return data


def _read_component(reader: _Reader, unit: str, comp: etree._Element) -> dict[str, Any]:
    """The unit of an FMU component: its FMU, parameters and annotations; its connectors checked against the FMU."""
    key = f"units.{unit}.fmu"
    source = comp.get("source", "")
    path = reader.member(source)
    entry: dict[str, Any] = {"fmu": str(path) if path else source, "parameters": _read_parameters(reader, unit, comp)}
    ann = _annotation_of(comp, "ssd", UNIT_ANNOTATION)
    chosen = None if ann is None else ann.find("mre:Interface", NS)
    if chosen is not None:
        if chosen.get("name") is not None:
            entry["interface"] = chosen.get("name")
        if chosen.get("relativeTolerance") is not None:
            try:
                entry["relative_tolerance"] = _number(chosen.get("relativeTolerance"))
            except ValueError as exc:
                reader.problem(f"component '{unit}': relativeTolerance: {exc}", f"units.{unit}.relative_tolerance",
                               SSD_FILE, chosen)
    hint = _annotation_of(comp, "ssd", OSP_ANNOTATION)
    hint = None if hint is None else hint.find("osp:StepSizeHint", NS)
    if hint is not None:
        try:
            entry["step"] = _number(hint.get("value"))
        except ValueError as exc:
            reader.problem(f"component '{unit}': StepSizeHint: {exc}", f"units.{unit}.step", SSD_FILE, hint)
    if path is None:
        reader.problem(f"component '{unit}': FMU '{source}' is not in the package", key, SSD_FILE, comp)
        return entry
    try:
        desc, _ = read_description(path, unit, entry.get("interface"))
    except FmuFormatError as exc:
        reader.problem(f"component '{unit}': {exc}", key, SSD_FILE, comp)
        return entry
    for c in comp.findall("ssd:Connectors/ssd:Connector", NS):
        if c.get("name") not in desc.variables:
            reader.problem(f"component '{unit}': connector '{c.get('name')}' is not a variable of its FMU "
                           f"{source}", f"units.{unit}", SSD_FILE, c)
    return entry


def _read_connection(reader: _Reader, k: int, conn: etree._Element,
                     connectors: dict[str, dict[str, str]]) -> dict[str, Any] | None:
    """Connection ``k`` between two components' connectors; None after a problem reported."""
    reader.at(("connections", k), SSD_FILE, conn)
    ends = []
    text = (f"connection {k} ({conn.get('startElement')}.{conn.get('startConnector')} -> "
            f"{conn.get('endElement')}.{conn.get('endConnector')})")
    for side in ("start", "end"):
        element, connector = conn.get(f"{side}Element"), conn.get(f"{side}Connector")
        if element is None:
            reader.problem(f"{text}: connections to the system's own connectors are not supported",
                           f"connections.{k}", SSD_FILE, conn)
        elif element not in connectors:
            names = ", ".join(connectors) or "none"
            reader.problem(f"{text}: no component named '{element}' (components: {names})",
                           f"connections.{k}", SSD_FILE, conn)
        elif connector not in connectors[element]:
            reader.problem(f"{text}: component '{element}' has no connector '{connector}'",
                           f"connections.{k}", SSD_FILE, conn)
        else:
            ends.append(f"{element}.{connector}")
    if conn.find("ssc:*", NS) is not None:  # LinearTransformation, BooleanMappingTransformation, ...
        reader.problem(f"connection {k}: transformations are not supported", f"connections.{k}", SSD_FILE, conn)
        return None
    if len(ends) != 2:
        return None
    ann = _annotation_of(conn, "ssd", CONNECTION_ANNOTATION)
    coupling = None if ann is None else ann.find("mre:Coupling", NS)
    delayed = coupling is not None and coupling.get("delayed") == "true"
    return {"source": ends[0], "target": ends[1], "delayed": delayed}


def load_ssp(path: Path | str, overrides: tuple[str, ...] = (), workdir: Path | None = None) -> LoadedSsp:
    """Extract, validate and read an SSP package into a scenario. Raises ScenarioError with every problem.

    ``workdir``: folder to extract into (kept); by default a temporary folder deleted with
    the returned object (or by its ``cleanup()``).
    """
    path = resolved(path)
    if not path.is_file():
        raise ScenarioError(Problem("no such SSP file" if not path.exists() else "not a regular file", "", str(path)))
    if not zipfile.is_zipfile(path):
        raise ScenarioError(Problem("not an SSP package (not a zip archive)", "", str(path)))
    owned = workdir is None
    target = Path(tempfile.mkdtemp(prefix="mre_ssp_")) if owned else Path(workdir)
    try:
        try:
            with zipfile.ZipFile(path) as z:
                if SSD_FILE not in z.namelist():
                    raise ScenarioError(Problem(f"not an SSP package (no {SSD_FILE} at its root)", "", str(path)))
                safe_extract(z, target, path)
        except ArchiveError as exc:
            raise ScenarioError(Problem(str(exc))) from None
        except (zipfile.BadZipFile, EOFError, NotImplementedError, ValueError) as exc:
            raise ScenarioError(Problem(f"damaged SSP package: {exc}", "", str(path))) from None
        except OSError as exc:
            raise ScenarioError(Problem(f"cannot extract the package: {exc.strerror or exc}", "", str(path))) from None
        reader = _Reader(path, target.resolve())
        ssd = reader.parse(SSD_FILE, "SystemStructureDescription.xsd", "")
        if ssd is None or reader.problems:
            raise ScenarioError(reader.problems or Problem(f"cannot read {SSD_FILE}", "", str(path)))
        data = _read_system(reader, ssd)
        simulation, settings = _read_settings(reader, ssd)
        data["simulation"] = simulation
        settings.pop("format", None)
        data.update(settings)
        if reader.problems:
            raise ScenarioError(reader.problems)
        lines = reader.lines
        unit_names = set(data["units"])
        for assignment in overrides:
            apply_override(data, lines, assignment, unit_names)
        if "step" not in data["simulation"]:
            raise ScenarioError(Problem(
                f"the package gives no communication step (no {SETTINGS_ANNOTATION} annotation): "
                "give one with --set simulation.step=H", "simulation.step", reader.label(SSD_FILE)))
        try:
            scenario = Scenario.model_validate(data)
        except ValidationError as exc:
            raise ScenarioError(validation_problems(exc, lines, path, Scenario)) from None
    except BaseException:
        if owned:
            shutil.rmtree(target, ignore_errors=True)
        raise
    carried = carried_scripts(data)
    if carried:
        print(f"note: {path.name} carries {'a script' if len(carried) == 1 else 'scripts'} that a unit runs as Python "
              f"code with your rights, as any FMU's code runs: {', '.join(carried)}", file=sys.stderr, flush=True)
    return LoadedSsp(scenario, path, lines, data, target, owned)


SCRIPT_SUFFIXES = (".py", ".pyw", ".tcl", ".sh")
"""Data files that are code: a unit that takes one (an OpenSees model script) runs it."""


def is_script(key: str, path: str | Path) -> bool:
    """Whether a data file given at parameter ``key`` is a script a unit runs (by its name or its parameter's)."""
    return Path(str(path)).suffix.lower() in SCRIPT_SUFFIXES or key.rpartition(".")[2] == "script"


def carried_scripts(data: dict[str, Any]) -> list[str]:
    """``units.<u>.parameters.<p> = resources/<file>`` for each data file of a package's scenario that is a script."""
    out = []
    for unit, spec in (data.get("units") or {}).items():
        for name, value in ((spec or {}).get("parameters") or {}).items():
            if isinstance(value, DataFile) and is_script(f"{unit}.{name}", value.name):
                out.append(f"units.{unit}.parameters.{name} = resources/{Path(value.name).name}")
    return out
