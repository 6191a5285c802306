"""FMU files: reading a model description (no binary loaded) and loading an FMU's library.

:func:`read_description` turns fmpy's model description of an FMI 2.0 or 3.0 FMU into the
master's :class:`~orchestration.master.unit.UnitDescription`; :func:`load_slave` extracts
an FMU and loads it as fmpy's ``FMU2Slave`` or ``FMU3Slave``.
"""

from __future__ import annotations

import shutil
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.errors import SimulationError
from orchestration.master.unit import UnitDescription, Variable

# FMI 3.0 type -> the master's type name (what scenario checks and connections understand)
_MASTER_TYPE = {"Float64": "Real", "Int32": "Integer", "Int64": "Integer", "Enumeration": "Enumeration",
                "Boolean": "Boolean", "String": "String"}

class FmuFormatError(ValueError):
    """A file that is not a usable FMI 2.0 or 3.0 co-simulation FMU."""


def read_description(path: Path, name: str) -> tuple[UnitDescription, Any]:
    """The interface of the FMU at ``path`` (no binary is loaded) and fmpy's model description."""
    from fmpy import read_model_description

    path = Path(path)
    if not path.is_file():
        raise FmuFormatError(f"{path}: no such FMU file")
    if not zipfile.is_zipfile(path):
        raise FmuFormatError(f"{path}: not an FMU (not a zip archive)")
    with zipfile.ZipFile(path) as z:
        if "modelDescription.xml" not in z.namelist():
            raise FmuFormatError(f"{path}: not an FMU (the zip has no modelDescription.xml)")
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # fmpy raises several kinds for broken XML
        raise FmuFormatError(f"{path}: unreadable modelDescription.xml: {exc}") from None
    if md.fmiVersion.startswith("3."):
        return describe_fmi3(path, name, md), md
    if md.fmiVersion != "2.0":
        raise FmuFormatError(f"{path}: FMI {md.fmiVersion} FMU; this master runs FMI 2.0 and 3.0 co-simulation FMUs")
    if md.coSimulation is None:
        raise FmuFormatError(f"{path}: model-exchange-only FMU; this master needs co-simulation")
    return _description(name, md, lambda v: v.type), md


def _description(name: str, md: Any, master_type: Callable[[Any], str]) -> UnitDescription:
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
        )
    deps: dict[str, tuple[str, ...] | None] = {}
    for out in md.outputs:
        deps[out.variable.name] = (
            None if out.dependencies is None else tuple(d.name for d in out.dependencies if d.causality == "input")
        )
    return UnitDescription(name, variables, deps, md.coSimulation.modelIdentifier, md.fmiVersion)


def load_slave(slave_class: Any, path: Path, md: Any, name: str, start_time: float) -> tuple[str, Any]:
    """Extract an FMU and load its library as fmpy's ``slave_class`` (FMU2Slave or FMU3Slave)."""
    from fmpy import extract

    directory = None
    try:
        directory = extract(str(path))
        slave = slave_class(guid=md.guid, unzipDirectory=directory,
                            modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    except Exception as exc:
        if directory is not None:
            shutil.rmtree(directory, ignore_errors=True)
        raise SimulationError(f"cannot load FMU {path}: {exc}", unit=name, time=start_time) from exc
    return directory, slave


def describe_fmi3(path: Path, name: str, md: Any) -> UnitDescription:
    """The interface of an FMI 3.0 FMU from fmpy's model description; refuses non-co-simulation FMUs."""
    if md.coSimulation is None:
        kinds = [k for k, v in (("model exchange", md.modelExchange), ("scheduled execution", md.scheduledExecution))
                 if v is not None]
        only = " and ".join(kinds) if kinds else "no interface"
        raise FmuFormatError(f"{path}: FMI 3.0 FMU without Co-Simulation ({only} only); "
                             "this master needs co-simulation")
    return _description(name, md, lambda v: f"{v.type} array" if v.dimensions else _MASTER_TYPE.get(v.type, v.type))


@dataclass
class ValueBuffer:
    vrs: Any
    buf: Any
    view: np.ndarray
    n: int
