"""The build removes pythonfmu 0.7's use-after-free exit hook from every FMU's Linux binary.

The bug (see components/build/exit_fix.py) corrupts the heap at process exit in a few
per cent of runs, so its presence is checked on the binary (independently of the fix's
own reader, with the ELF tables read here) and, where valgrind exists, on a live exit.
"""

from __future__ import annotations

import io
import os
import shutil
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from elftools.elf.elffile import ELFFile

from components.build.exit_fix import HOOK_SYMBOL, ExitHookError, has_exit_hook, remove_exit_hook

if not sys.platform.startswith("linux"):
    pytest.skip("the exit hook is in pythonfmu's Linux binary", allow_module_level=True)


@pytest.fixture(scope="module")
def upstream() -> bytes:
    import pythonfmu

    path = Path(pythonfmu.__file__).parent / "resources" / "binaries" / "linux64" / "libpythonfmu-export.so"
    return path.read_bytes()


def _tables(data: bytes) -> tuple[dict, dict, list]:
    """(dynamic tags, symtab name -> address, [(file offset, r_offset, addend)] of .rela.dyn)."""
    elf = ELFFile(io.BytesIO(data))
    tags = {t.entry.d_tag: t.entry.d_val for t in elf.get_section_by_name(".dynamic").iter_tags()}
    symbols = {s.name: s["st_value"] for s in elf.get_section_by_name(".symtab").iter_symbols()}
    rela = elf.get_section_by_name(".rela.dyn")
    relocs = [(rela["sh_offset"] + k * rela["sh_entsize"], r["r_offset"], r["r_addend"])
              for k, r in enumerate(rela.iter_relocations())]
    return tags, symbols, relocs


def _fini_targets(data: bytes) -> list[int]:
    tags, _, relocs = _tables(data)
    start, size = tags["DT_FINI_ARRAY"], tags["DT_FINI_ARRAYSZ"]
    by_address = {offset: addend for _, offset, addend in relocs}
    return [by_address[a] for a in range(start, start + size, 8)]


def test_pythonfmu_0_7_binary_runs_its_exit_hook(upstream):
    _, symbols, _ = _tables(upstream)
    assert _fini_targets(upstream) == [symbols["__do_global_dtors_aux"], symbols[HOOK_SYMBOL]]
    assert has_exit_hook(upstream)


def test_the_fix_drops_only_the_hook_slot(upstream):
    fixed = remove_exit_hook(upstream)
    _, symbols, _ = _tables(fixed)
    assert _fini_targets(fixed) == [symbols["__do_global_dtors_aux"]]
    assert not has_exit_hook(fixed)
    changed = [k for k, (a, b) in enumerate(zip(upstream, fixed, strict=True)) if a != b]
    assert len(changed) >= 1 and changed[-1] - changed[0] < 8  # one 8-byte field
    assert remove_exit_hook(fixed) == fixed  # idempotent


def test_other_binaries_pass_through_unchanged(fmu_dir):
    with zipfile.ZipFile(fmu_dir / "MreIsolatorC.fmu") as z:  # plain C, not pythonfmu
        c_binary = z.read("binaries/linux64/MreIsolatorC.so")
    assert remove_exit_hook(c_binary) == c_binary
    assert remove_exit_hook(b"not an ELF file") == b"not an ELF file"


def test_an_unexpected_layout_is_refused_not_guessed(upstream):
    # Swap the two .fini_array slots: the hook is then not the last one.
    tags, _, relocs = _tables(upstream)
    slots = [(at, addend) for at, offset, addend in relocs
             if tags["DT_FINI_ARRAY"] <= offset < tags["DT_FINI_ARRAY"] + tags["DT_FINI_ARRAYSZ"]]
    (first_at, first), (second_at, second) = sorted(slots)
    swapped = bytearray(upstream)
    struct.pack_into("<q", swapped, first_at + 16, second)  # r_addend of an Elf64_Rela
    struct.pack_into("<q", swapped, second_at + 16, first)
    with pytest.raises(ExitHookError, match="must be its last slot"):
        remove_exit_hook(bytes(swapped), "swapped.so")


@pytest.mark.slow
def test_every_built_fmu_is_free_of_the_hook(fmu_dir):
    checked = 0
    for fmu in sorted(fmu_dir.glob("*.fmu")):
        with zipfile.ZipFile(fmu) as z:
            for name in z.namelist():
                if name.startswith("binaries/linux64/"):
                    data = z.read(name)
                    assert not has_exit_hook(data), f"{fmu.name}: {name}"
                    checked += b"finalizePythonInterpreter" in data
    assert checked >= 4  # the pythonfmu units were among them


EXIT_SCRIPT = """
import sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
for path in sys.argv[1:]:
    md = read_model_description(path)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), instanceName="x",
                      modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.freeInstance()
    slave.freeLibrary()
"""


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind not installed")
def test_exit_after_freeing_every_unit_touches_no_freed_memory(fmu_dir, tmp_path):
    fmus = [str(fmu_dir / f"{m}.fmu") for m in ("GroundMotionSource", "ShearBuilding", "MreIsolator",
                                                 "SosmCurrentController")]
    log = tmp_path / "valgrind.txt"
    proc = subprocess.run(["valgrind", f"--log-file={log}", sys.executable, "-c", EXIT_SCRIPT, *fmus],
                          capture_output=True, text=True, timeout=600, env={**os.environ, "PYTHONMALLOC": "malloc"})
    assert proc.returncode == 0, proc.stderr
    text = log.read_text()
    assert "finalizePythonInterpreter" not in text and "onLibraryUnload" not in text
