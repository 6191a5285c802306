"""FMU model descriptions: what a unit declares, read without loading any binary.

:func:`read_description` turns fmpy's model description of an FMI 2.0 or 3.0 FMU into the
master's :class:`~orchestration.master.unit.UnitDescription`. :func:`open_fmu` opens an FMU's
zip within the limits of :mod:`orchestration.master.safe_archive`, with a model description of
at most :data:`MAX_DESCRIPTION_BYTES`.

Interfaces (:data:`INTERFACES`): FMI 2.0 FMUs run as co-simulation or as model exchange
(:class:`~orchestration.master.fmi2_me_unit.MeUnit`); FMI 3.0 FMUs as co-simulation only. A unit
runs as the scenario's ``interface`` asks, else as co-simulation when the FMU has it, else
as model exchange (:func:`run_interface`).
"""

from __future__ import annotations

import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from orchestration.master.safe_archive import ArchiveError, check_archive
from orchestration.master.unit import UnitDescription, Variable

# FMI 3.0 type -> the master's type name (what scenario checks and connections understand)
_MASTER_TYPE = {"Float64": "Real", "Int32": "Integer", "Int64": "Integer", "Enumeration": "Enumeration",
                "Boolean": "Boolean", "String": "String"}

MAX_DESCRIPTION_BYTES = 64 << 20
"""Largest modelDescription.xml read (64 MiB)."""
INTERFACES = ("co-simulation", "model-exchange")
"""How a unit can run: the FMU's Co-Simulation or its Model Exchange interface."""


class FmuFormatError(ValueError):
    """A file that is not a usable FMI 2.0 (co-simulation or model exchange) or FMI 3.0 co-simulation FMU."""


def open_fmu(path: Path) -> zipfile.ZipFile:
    """The FMU's zip, checked by :func:`~orchestration.master.safe_archive.check_archive`; FmuFormatError otherwise."""
    if not path.is_file():
        raise FmuFormatError(f"{path}: no such FMU file" if not path.exists() else f"{path}: not a regular file")
    try:
        z = zipfile.ZipFile(path)
    except Exception:  # BadZipFile, OSError, ValueError, EOFError, ...: not a readable zip
        raise FmuFormatError(f"{path}: not an FMU (not a zip archive)") from None
    try:
        check_archive(z, path)
        if "modelDescription.xml" not in z.namelist():
            raise FmuFormatError(f"{path}: not an FMU (the zip has no modelDescription.xml)")
        size = z.getinfo("modelDescription.xml").file_size
        if size > MAX_DESCRIPTION_BYTES:
            raise FmuFormatError(f"{path}: modelDescription.xml is {size:,} bytes, more than the "
                                 f"{MAX_DESCRIPTION_BYTES:,} allowed")
    except ArchiveError as exc:
        z.close()
        raise FmuFormatError(f"{exc}; not extracted") from None
    except BaseException:
        z.close()
        raise
    return z


def declared_interfaces(md: Any) -> tuple[str, ...]:
    """The interfaces (of :data:`INTERFACES`) a model description declares."""
    return tuple(kind for kind, element in zip(INTERFACES, (md.coSimulation, md.modelExchange), strict=True)
                 if element is not None)


def run_interface(md: Any, requested: str | None = None) -> str:
    """The interface a unit runs as: ``requested``, else co-simulation when the FMU has it, else model exchange.

    FmuFormatError when the FMU cannot run that way (the interface is not declared, or model
    exchange of an FMI 3.0 FMU) or declares neither interface.
    """
    declared = declared_interfaces(md)
    if requested is not None and requested not in INTERFACES:
        raise FmuFormatError(f"unknown interface {requested!r} (choices: {', '.join(INTERFACES)})")
    if not declared:
        raise FmuFormatError("the FMU declares neither Co-Simulation nor Model Exchange")
    chosen = requested or declared[0]
    if chosen not in declared:
        raise FmuFormatError(f"interface {chosen} requested, but the FMU has {' and '.join(declared)} only")
    if chosen == "model-exchange" and md.fmiVersion.startswith("3."):
        raise FmuFormatError("FMI 3.0 model exchange is not supported (FMI 3.0 FMUs run as co-simulation; "
                             "model exchange: FMI 2.0)")
    return chosen


def model_identifier(md: Any, interface: str | None = None) -> str:
    """The model identifier (library name) of the interface the unit runs as (:func:`run_interface`)."""
    element = md.modelExchange if run_interface(md, interface) == "model-exchange" else md.coSimulation
    return element.modelIdentifier


def read_description(path: Path, name: str, interface: str | None = None) -> tuple[UnitDescription, Any]:
    """The interface of the FMU at ``path`` run as ``interface`` (default: :func:`run_interface`; no binary is
    loaded) and fmpy's model description."""
    from fmpy import read_model_description

    path = Path(path)
    open_fmu(path).close()
    from fmpy.model_description import ValidationError

    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # fmpy raises several kinds for broken XML, some of them Python internals
        reason = structure_problem(path) or _fmpy_reason(exc)
        raise FmuFormatError(f"{path}: unreadable modelDescription.xml: {reason}") from None
    # What kind of FMU first (a clearer message than the schema's), then fmpy's validation.
    if md.fmiVersion != "2.0" and not md.fmiVersion.startswith("3."):
        raise FmuFormatError(f"{path}: FMI {md.fmiVersion} FMU; this master runs FMI 2.0 (co-simulation or model "
                             "exchange) and FMI 3.0 co-simulation FMUs")
    if md.coSimulation is None and md.fmiVersion.startswith("3."):
        return describe_fmi3(path, name, md), md  # refuses it, saying which kind it is
    try:
        run_interface(md, interface)
    except FmuFormatError as exc:
        raise FmuFormatError(f"{path}: {exc}") from None
    try:
        read_model_description(str(path), validate=True)
    except ValidationError as exc:  # the schema and fmpy's checks (duplicate names, references, ...)
        problems = [str(p).strip() for p in getattr(exc, "problems", [])] or [str(exc).strip()]
        shown = "; ".join(problems[:5]) + (f"; and {len(problems) - 5} more" if len(problems) > 5 else "")
        raise FmuFormatError(f"{path}: invalid modelDescription.xml ({len(problems)} problem"
                             f"{'s' if len(problems) != 1 else ''}): {shown}") from None
    except Exception as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise FmuFormatError(f"{path}: invalid modelDescription.xml: {reason}") from None
    if md.fmiVersion.startswith("3."):
        return describe_fmi3(path, name, md), md
    return _description(name, md, lambda v: v.type, model_identifier(md, interface)), md


def _description(name: str, md: Any, master_type: Callable[[Any], str], identifier: str) -> UnitDescription:
    """The master's view of fmpy's model description: variables (typed by ``master_type``) and dependencies."""
    variables = {}
    for v in md.modelVariables:
        variables[v.name] = Variable(
            name=v.name,
            vr=v.valueReference,
            type=master_type(v),
            causality=v.causality,
            variability=v.variability,
            unit=v.unit or (v.declaredType.unit if v.declaredType is not None else None),
            start=v.start,
            description=v.description or "",
            declared_type=v.type,
            items=tuple((i.name, int(i.value)) for i in getattr(v.declaredType, "items", None) or ()
                        if i.value is not None),
            min_value=_bound(v, "min"),
            max_value=_bound(v, "max"),
        )
    deps: dict[str, tuple[str, ...] | None] = {}
    for out in md.outputs:
        deps[out.variable.name] = (
            None if out.dependencies is None else tuple(d.name for d in out.dependencies if d.causality == "input")
        )
    return UnitDescription(name, variables, deps, identifier, md.fmiVersion)


def describe_fmi3(path: Path, name: str, md: Any) -> UnitDescription:
    """The interface of an FMI 3.0 FMU from fmpy's model description; refuses non-co-simulation FMUs."""
    if md.coSimulation is None:
        kinds = [k for k, v in (("model exchange", md.modelExchange), ("scheduled execution", md.scheduledExecution))
                 if v is not None]
        only = " and ".join(kinds) if kinds else "no interface"
        raise FmuFormatError(f"{path}: FMI 3.0 FMU without Co-Simulation ({only} only); "
                             "this master runs FMI 3.0 FMUs as co-simulation (model exchange: FMI 2.0 only)")
    return _description(name, md, lambda v: f"{v.type} array" if v.dimensions else _MASTER_TYPE.get(v.type, v.type),
                        md.coSimulation.modelIdentifier)


def _bound(v: Any, which: str) -> float | None:
    """A variable's declared ``min`` or ``max`` (its own, else its declared type's) as a number, or None."""
    text = getattr(v, which, None)
    if text is None and v.declaredType is not None:
        text = getattr(v.declaredType, which, None)
    try:
        return None if text is None else float(text)
    except (TypeError, ValueError):
        return None


_INTERNAL = (AttributeError, TypeError, IndexError, KeyError, NameError, UnboundLocalError)


def _fmpy_reason(exc: BaseException) -> str:
    """fmpy's message for a broken description, unless it is a Python internal (then only that it is malformed)."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, _INTERNAL) or not text or "int()" in text or "invalid literal" in text:
        return "malformed (fmpy could not read it)"
    return text


_FMI2_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
_FMI3_TYPES = ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
               "Boolean", "String", "Binary", "Enumeration", "Clock")


def _is_int(text: str | None) -> bool:
    try:
        int(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return True


def structure_problem(path: Path) -> str | None:
    """What is structurally wrong in an FMU's modelDescription.xml, naming the element and attribute, or None.

    Checks what fmpy's reader assumes without saying so: ``fmiVersion`` on the root, a
    ``ModelVariables`` element, each variable's ``name`` and integer ``valueReference``, one type
    element per FMI 2.0 ``ScalarVariable``, integer ``index`` and ``dependencies`` in
    ``ModelStructure`` that point at a variable, and integer ``BaseUnit`` exponents.
    """
    from lxml import etree  # type: ignore[import-untyped]  # lxml ships no type information (lxml-stubs apart)

    try:
        with zipfile.ZipFile(path) as z:
            raw = z.read("modelDescription.xml")
        parser = etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False)
        root = etree.fromstring(raw, parser)
    except Exception as exc:  # not XML at all: lxml's message names the line
        return f"not well-formed XML: {str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__}"
    text = _root_problem(root)
    if text is not None:
        return text
    fmi2 = root.get("fmiVersion") == "2.0"
    variables = [el for el in root.find("ModelVariables") if isinstance(el.tag, str)]
    return (_variables_problem(variables, fmi2) or _model_structure_problem(root, variables, fmi2)
            or _base_unit_problem(root))


def _at(el: Any) -> str:
    return f"line {el.sourceline}"


def _root_problem(root: Any) -> str | None:
    """The root element, its FMI version and its ModelVariables."""
    if root.tag != "fmiModelDescription":
        return f"the root element is <{root.tag}>, not <fmiModelDescription>"
    version = root.get("fmiVersion")
    if version is None:
        return "<fmiModelDescription> has no fmiVersion attribute"
    if version != "2.0" and not version.startswith("3."):
        return f"FMI {version} FMU (fmiVersion={version!r}); this master runs FMI 2.0 and FMI 3.0 FMUs"
    if root.find("ModelVariables") is None:
        return "no <ModelVariables> element"
    return None


def _variables_problem(variables: list[Any], fmi2: bool) -> str | None:
    """Each variable's name, integer valueReference and type element."""
    for k, el in enumerate(variables, 1):
        kind = "ScalarVariable" if fmi2 else el.tag
        if el.get("name") is None:
            return f"<{kind}> number {k} ({_at(el)}) has no name attribute"
        if not _is_int(el.get("valueReference")):
            return (f"<{kind} name={el.get('name')!r}> ({_at(el)}): valueReference "
                    f"{el.get('valueReference')!r} is not an integer")
        if fmi2:
            types = [c for c in el if isinstance(c.tag, str) and c.tag in _FMI2_TYPES]
            if len(types) != 1:
                return (f"<ScalarVariable name={el.get('name')!r}> ({_at(el)}) has {len(types)} type elements "
                        f"(exactly one of {', '.join(_FMI2_TYPES)} is needed)")
        elif el.tag not in _FMI3_TYPES:
            return f"<{el.tag}> ({_at(el)}) is not an FMI 3.0 variable element"
    return None


_STRUCTURE_ELEMENTS = ("Unknown", "Output", "ContinuousStateDerivative", "ClockedState", "InitialUnknown",
                       "EventIndicator")


def _model_structure_problem(root: Any, variables: list[Any], fmi2: bool) -> str | None:
    """ModelStructure's references (FMI 2.0 index, FMI 3.0 valueReference) and dependencies point at variables."""
    n = len(variables)
    by_vr = {el.get("valueReference") for el in variables}
    key = "index" if fmi2 else "valueReference"

    def names_no_variable(ref: str) -> bool:
        return (not _is_int(ref) or not 1 <= int(ref) <= n) if fmi2 else ref not in by_vr

    structure = root.find("ModelStructure")
    for el in structure.iter() if structure is not None else ():
        if not isinstance(el.tag, str) or el.tag == "ModelStructure" or (el.getparent() is structure and fmi2):
            continue
        if el.tag not in _STRUCTURE_ELEMENTS:
            continue
        ref = el.get(key)
        if not _is_int(ref):
            return f"<{el.tag}> in <ModelStructure> ({_at(el)}): {key} {ref!r} is not an integer"
        if names_no_variable(ref):
            there = f" (there are {n})" if fmi2 else ""
            return f"<{el.tag} {key}=\"{ref}\"> ({_at(el)}) points at no variable{there}"
        bad = [d for d in (el.get("dependencies") or "").split() if not _is_int(d) or names_no_variable(d)]
        if bad:
            return f"<{el.tag}> ({_at(el)}): dependencies {bad[0]!r} is not the {key} of a variable"
    return None


def _base_unit_problem(root: Any) -> str | None:
    """Integer BaseUnit exponents."""
    for el in root.iter("BaseUnit"):
        for name, value in el.attrib.items():
            if name not in ("factor", "offset") and not _is_int(value):
                return f"<BaseUnit {name}={value!r}> ({_at(el)}): the exponent must be an integer"
    return None
