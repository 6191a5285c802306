"""FMU files: reading a model description (no binary loaded) and loading an FMU's library.

:func:`read_description` turns fmpy's model description of an FMI 2.0 or 3.0 FMU into the
master's :class:`~orchestration.master.unit.UnitDescription`; :func:`check_binary` checks,
before anything runs, that the FMU holds a loadable library for this platform;
:func:`load_slave` extracts an FMU and loads it as fmpy's ``FMU2Slave``, ``FMU2Model`` or ``FMU3Slave``.

Interfaces (:data:`INTERFACES`): FMI 2.0 FMUs run as co-simulation or as model exchange
(:class:`~orchestration.master.me_unit.MeUnit`); FMI 3.0 FMUs as co-simulation only. A unit
runs as the scenario's ``interface`` asks, else as co-simulation when the FMU has it, else
as model exchange (:func:`run_interface`).

Archives are bounded (:func:`check_archive`, also used for SSP packages): at most
:data:`MAX_ENTRIES` entries and :data:`MAX_UNPACKED_BYTES` uncompressed, no entry that is a
link or would land outside the extraction folder, and a model description of at most
:data:`MAX_DESCRIPTION_BYTES`; :func:`safe_extract` extracts under the same limits.
"""

from __future__ import annotations

import os
import shutil
import stat
import struct
import sys
import tempfile
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

MAX_ENTRIES = 10_000
"""Most entries an FMU or SSP archive may have."""
UNPACKED_ENV = "MRE_COSIM_MAX_UNPACKED_MB"
"""Environment variable: the most an FMU or SSP archive may unpack to [MiB] (default 256)."""


def _unpacked_limit() -> int:
    try:
        return max(1, int(float(os.environ.get(UNPACKED_ENV, "256")) * 2**20))
    except (ValueError, OverflowError):
        return 256 << 20


MAX_UNPACKED_BYTES = _unpacked_limit()
"""Most bytes an FMU or SSP archive may unpack to (256 MiB unless MRE_COSIM_MAX_UNPACKED_MB says otherwise)."""
MAX_DESCRIPTION_BYTES = 64 << 20
"""Largest modelDescription.xml read (64 MiB)."""


INTERFACES = ("co-simulation", "model-exchange")
"""How a unit can run: the FMU's Co-Simulation or its Model Exchange interface."""


class FmuFormatError(ValueError):
    """A file that is not a usable FMI 2.0 (co-simulation or model exchange) or FMI 3.0 co-simulation FMU."""


class ArchiveError(ValueError):
    """A zip archive (FMU or SSP package) that is refused: too large, too many entries, or escaping paths."""


def _unsafe_name(name: str) -> str | None:
    """Why an archive entry name may not be extracted, or None."""
    if "\\" in name or "\x00" in name:
        return "a backslash or NUL in the name"
    if name.startswith("/") or (len(name) > 1 and name[1] == ":"):
        return "an absolute path"
    if ".." in name.split("/"):
        return "'..' in the path"
    return None


def check_archive(z: zipfile.ZipFile, path: Path | str, max_bytes: int | None = None,
                  max_entries: int | None = None) -> int:
    """ArchiveError unless every entry may be extracted within the limits (default: the module's); returns the
    unpacked size."""
    max_bytes = MAX_UNPACKED_BYTES if max_bytes is None else max_bytes
    max_entries = MAX_ENTRIES if max_entries is None else max_entries
    infos = z.infolist()
    if len(infos) > max_entries:
        raise ArchiveError(f"{path}: {len(infos):,} entries, more than the {max_entries:,} allowed")
    total = 0
    for info in infos:
        why = _unsafe_name(info.filename)
        if why is None and stat.S_ISLNK(info.external_attr >> 16):
            why = "a symbolic link"
        if why is not None:
            raise ArchiveError(f"{path}: entry {info.filename!r} is refused ({why})")
        total += info.file_size
    if total > max_bytes:
        raise ArchiveError(f"{path}: unpacks to {total:,} bytes, more than the {max_bytes:,} allowed "
                           f"({UNPACKED_ENV} sets the limit in MiB)")
    return total


def safe_extract(z: zipfile.ZipFile, target: Path | str, path: Path | str, max_bytes: int | None = None,
                 max_entries: int | None = None) -> None:
    """Extract every entry into ``target`` after :func:`check_archive`; never writes more than the sizes declared."""
    check_archive(z, path, max_bytes, max_entries)
    root = Path(target).resolve()
    for info in z.infolist():
        dest = root.joinpath(*[p for p in info.filename.split("/") if p])
        if dest != root and root not in dest.parents:
            raise ArchiveError(f"{path}: entry {info.filename!r} would land outside the extraction folder")
        if info.is_dir():
            dest.mkdir(parents=True, exist_ok=True)
            continue
        dest.parent.mkdir(parents=True, exist_ok=True)
        left = info.file_size
        with z.open(info) as src, open(dest, "wb") as out:
            while left > 0:
                chunk = src.read(min(1 << 20, left))
                if not chunk:
                    break
                out.write(chunk)
                left -= len(chunk)
        mode = (info.external_attr >> 16) & 0o777
        if mode:
            os.chmod(dest, mode | 0o600)


def _open_fmu(path: Path) -> zipfile.ZipFile:
    """The FMU's zip, checked by :func:`check_archive`; FmuFormatError otherwise."""
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
    _open_fmu(path).close()
    from fmpy.model_description import ValidationError

    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # fmpy raises several kinds for broken XML
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
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
        )
    deps: dict[str, tuple[str, ...] | None] = {}
    for out in md.outputs:
        deps[out.variable.name] = (
            None if out.dependencies is None else tuple(d.name for d in out.dependencies if d.causality == "input")
        )
    return UnitDescription(name, variables, deps, identifier, md.fmiVersion)


def load_slave(slave_class: Any, path: Path, md: Any, name: str, start_time: float,
               interface: str = "co-simulation") -> tuple[str, Any]:
    """Extract an FMU and load the library of its ``interface`` as fmpy's ``slave_class`` (FMU2Slave, FMU2Model or
    FMU3Slave)."""
    directory = None
    try:
        directory = tempfile.mkdtemp(prefix="mre_fmu_")
        with _open_fmu(Path(path)) as z:
            safe_extract(z, directory, path)
        slave = slave_class(guid=md.guid, unzipDirectory=directory,
                            modelIdentifier=model_identifier(md, interface), instanceName=name)
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
                             "this master runs FMI 3.0 FMUs as co-simulation (model exchange: FMI 2.0 only)")
    return _description(name, md, lambda v: f"{v.type} array" if v.dimensions else _MASTER_TYPE.get(v.type, v.type),
                        md.coSimulation.modelIdentifier)


@dataclass
class ValueBuffer:
    vrs: Any
    buf: Any
    view: np.ndarray
    n: int


def binary_path(md: Any, interface: str | None = None) -> str:
    """The archive path of the FMU's library for this platform (as fmpy loads it), for the interface it runs as."""
    import fmpy

    folder = fmpy.platform_tuple if md.fmiVersion.startswith("3.") else fmpy.platform
    return f"binaries/{folder}/{model_identifier(md, interface)}{fmpy.sharedLibraryExtension}"


def check_binary(path: Path, md: Any, interface: str | None = None) -> str | None:
    """Why the FMU's library for this platform (of the interface it runs as) cannot be loaded, or None; nothing is
    extracted or loaded.

    The library must be in the archive; on Linux it must be an ELF shared object for this
    interpreter's machine and word size whose segments lie within the file (a truncated,
    corrupt or foreign binary is found here, before any run folder exists).
    """
    try:
        member = binary_path(md, interface)
    except FmuFormatError as exc:
        return f"{path}: {exc}"
    try:
        with _open_fmu(Path(path)) as z:
            if member not in z.namelist():
                folders = sorted({n.split("/")[1] for n in z.namelist()
                                  if n.startswith("binaries/") and n.count("/") > 1})
                has = f" (it has binaries for: {', '.join(folders)})" if folders else " (it has no binaries)"
                return f"{path}: no library for this platform, {member}{has}"
            info = z.getinfo(member)
            if not sys.platform.startswith("linux"):
                return None
            with z.open(info) as f:
                head = f.read(64)
            ident = _elf_ident()
            problem = _elf_problem(head, info.file_size, ident)
            if problem is None:
                with z.open(info) as f:
                    problem = _elf_segments_problem(f, head, info.file_size)
                    while f.read(1 << 20):  # the rest, so that a damaged archive fails its CRC check here
                        pass
    except FmuFormatError as exc:
        return str(exc)
    except (OSError, zipfile.BadZipFile, EOFError, ValueError, NotImplementedError, struct.error) as exc:
        return f"{path}: cannot read {member}: {exc}"  # a damaged archive (bad CRC, unknown compression, ...)
    return None if problem is None else f"{path}: {member} is not a loadable library: {problem}"


_ELF_IDENT: tuple[int, int, int] | None = None


def _elf_ident() -> tuple[int, int, int]:
    """(class, byte order, machine) of the running interpreter's ELF executable."""
    global _ELF_IDENT
    if _ELF_IDENT is None:
        try:
            with open(os.path.realpath(sys.executable), "rb") as f:
                head = f.read(20)
            order = "<" if head[5] == 1 else ">"
            _ELF_IDENT = (head[4], head[5], struct.unpack(order + "H", head[18:20])[0])
        except (OSError, IndexError, struct.error):
            _ELF_IDENT = (2 if sys.maxsize > 2**32 else 1, 1 if sys.byteorder == "little" else 2, 0)
    return _ELF_IDENT


def _elf_problem(head: bytes, size: int, ident: tuple[int, int, int]) -> str | None:
    if len(head) < 52 or head[:4] != b"\x7fELF":
        return "not an ELF file" if size else "an empty file"
    if head[4] == 2 and len(head) < 64:
        return "a truncated ELF header"
    if (head[4], head[5]) != ident[:2]:
        return f"{'64' if head[4] == 2 else '32'}-bit ELF for another word size or byte order"
    order = "<" if head[5] == 1 else ">"
    e_type, machine = struct.unpack(order + "HH", head[16:20])
    if e_type != 3:
        return "not a shared object (ET_DYN)"
    if ident[2] and machine != ident[2]:
        return f"built for another processor (ELF machine {machine}, this one is {ident[2]})"
    return None


def _elf_segments_problem(f: Any, head: bytes, size: int) -> str | None:
    """Program headers and loadable segments must lie within the file (a truncated library fails here)."""
    order = "<" if head[5] == 1 else ">"
    if head[4] == 2:
        phoff, = struct.unpack(order + "Q", head[32:40])
        phentsize, phnum = struct.unpack(order + "HH", head[54:58])
        fmt, fields = order + "IIQQQQQQ", (2, 5)  # p_offset, p_filesz
    else:
        phoff, = struct.unpack(order + "I", head[28:32])
        phentsize, phnum = struct.unpack(order + "HH", head[42:46])
        fmt, fields = order + "IIIIIIII", (1, 4)
    if phnum == 0 or phentsize < struct.calcsize(fmt) or phoff + phnum * phentsize > size:
        return "its program headers are missing or lie beyond the end of the file (truncated?)"
    data = f.read(phoff + phnum * phentsize)
    loads = 0
    for k in range(phnum):
        entry = struct.unpack(fmt, data[phoff + k * phentsize: phoff + k * phentsize + struct.calcsize(fmt)])
        if entry[0] == 1:  # PT_LOAD
            loads += 1
            offset, filesz = entry[fields[0]], entry[fields[1]]
            if offset + filesz > size:
                return f"a loadable segment ends at byte {offset + filesz:,}, beyond the file's {size:,} (truncated?)"
    return None if loads else "no loadable segment"
