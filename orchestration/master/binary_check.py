"""Checks, before anything runs, that an FMU holds a library this process can load (ELF checks on Linux).

Nothing is extracted or loaded: the library must be in the archive and, on Linux, be an ELF
shared object for this interpreter's machine and word size whose segments lie within the file.
"""

from __future__ import annotations

import os
import struct
import sys
import zipfile
from pathlib import Path
from typing import Any

from orchestration.master.fmu_description import FmuFormatError, model_identifier, open_fmu


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
        with open_fmu(Path(path)) as z:
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
