"""Remove pythonfmu 0.7's use-after-free exit hook from the Linux binary of an FMU.

pythonfmu 0.7's ``libpythonfmu-export.so`` keeps a static ``std::shared_ptr<PyState>``
and also registers ``onLibraryUnload`` in ``.fini_array``; that hook assigns ``nullptr``
to the same shared pointer. At process exit glibc runs the C++ static destructors
(``__cxa_atexit``) *before* ``_dl_fini`` runs ``.fini_array``, so by then the pointer's
control block is already freed and the hook decrements a counter inside freed heap
memory. The process usually survives; about one exit in fifty aborts later with
"corrupted double-linked list" (measured before this fix: 4 of 240 interrupted Kobe runs,
5 of 200 two-second runs). valgrind shows the invalid read in ``finalizePythonInterpreter`` called from
``_dl_fini``. The library is never actually unloaded by ``dlclose`` (it has
``STB_GNU_UNIQUE`` symbols), so every process that frees a pythonfmu instance and then
exits is exposed, whichever tool hosts the FMU.

The hook is redundant on Linux: the static destructor it races with already releases
the shared pointer (and, in a host without Python, finalizes the interpreter). So the
build drops it: the hook is the last ``.fini_array`` slot, and shortening
``DT_FINI_ARRAYSZ`` by one slot leaves ``__do_global_dtors_aux`` (the static
destructors) as the only fini function. Nothing else in the binary changes.
"""

from __future__ import annotations

import io
import struct

HOOK_SYMBOL = "_ZN12_GLOBAL__N_115onLibraryUnloadEv"  # (anonymous namespace)::onLibraryUnload()
MARKER_SYMBOL = "finalizePythonInterpreter"  # exported by the affected pythonfmu library


class ExitHookError(ValueError):
    """The binary has pythonfmu's exit hook but not in the layout this fix understands."""


def fini_functions(data: bytes) -> list[int]:
    """Addresses of the functions in a shared object's ``.fini_array``, in slot order."""
    return _fini_functions(_elf(data))


def has_exit_hook(data: bytes) -> bool:
    """True if the shared object would still run pythonfmu's ``onLibraryUnload`` at exit."""
    elf = _elf(data)
    hook = _symbol_value(elf, HOOK_SYMBOL)
    return hook is not None and hook in _fini_functions(elf)


def remove_exit_hook(data: bytes, name: str = "binary") -> bytes:
    """The shared object without pythonfmu's exit hook; other binaries come back unchanged."""
    from elftools.common.exceptions import ELFError

    if not data.startswith(b"\x7fELF"):
        return data
    try:
        elf = _elf(data)
        if _symbol_value(elf, MARKER_SYMBOL, table=".dynsym") is None:
            return data  # not the affected pythonfmu library
        hook = _symbol_value(elf, HOOK_SYMBOL)
        functions = _fini_functions(elf)
    except ELFError as exc:
        raise ExitHookError(f"{name}: unreadable ELF file: {exc}") from exc
    if hook is None:
        raise ExitHookError(f"{name}: pythonfmu library without a symbol table; cannot locate its exit hook")
    if hook not in functions:
        return data  # already fixed (or a pythonfmu without the hook)
    if functions[-1] != hook or functions.count(hook) != 1 or elf.elfclass != 64 or not elf.little_endian:
        raise ExitHookError(f"{name}: unexpected .fini_array layout {[hex(f) for f in functions]}; "
                            f"the exit hook {hex(hook)} must be its last slot")
    dynamic = elf.get_section_by_name(".dynamic")
    for k, tag in enumerate(dynamic.iter_tags()):
        if tag.entry.d_tag == "DT_FINI_ARRAYSZ":
            offset = dynamic["sh_offset"] + k * dynamic["sh_entsize"] + 8  # d_val of an Elf64_Dyn
            patched = bytearray(data)
            struct.pack_into("<Q", patched, offset, tag.entry.d_val - 8)
            return bytes(patched)
    raise ExitHookError(f"{name}: no DT_FINI_ARRAYSZ entry")  # unreachable: the array was found


def _elf(data: bytes):
    from elftools.elf.elffile import ELFFile

    return ELFFile(io.BytesIO(data))


def _fini_functions(elf) -> list[int]:
    dynamic = elf.get_section_by_name(".dynamic")
    tags = {tag.entry.d_tag: tag.entry.d_val for tag in dynamic.iter_tags()} if dynamic is not None else {}
    start, size = tags.get("DT_FINI_ARRAY"), tags.get("DT_FINI_ARRAYSZ")
    if start is None or not size:
        return []
    slot = elf.elfclass // 8
    relocated = {}
    for section in elf.iter_sections():
        if section["sh_type"] == "SHT_RELA":
            for rel in section.iter_relocations():
                if start <= rel["r_offset"] < start + size and rel["r_info_sym"] == 0:
                    relocated[rel["r_offset"]] = rel["r_addend"]
    return [relocated.get(start + k * slot, 0) for k in range(size // slot)]


def _symbol_value(elf, symbol: str, table: str = ".symtab") -> int | None:
    section = elf.get_section_by_name(table)
    if section is None:
        return None
    found = section.get_symbol_by_name(symbol)
    return found[0]["st_value"] if found else None
