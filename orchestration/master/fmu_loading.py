"""Loading an FMU's library: the archive extracted (within limits) and opened with fmpy.

By default every load extracts the archive into a fresh temporary folder, removed when the
unit is freed (:func:`release`). A process that hosts one run and then exits (the batch
layer's child per run, :mod:`orchestration.batch.child`) may call :func:`share_extractions`:
each FMU is then extracted once per machine into ``<root>/<SHA-256 of the archive>/`` and
loaded from there by every later run. Instances are still created fresh in each run; a second
load of the same archive while the first is loaded in this process (two units of one FMU)
gets a folder of its own, so no two instances share a library's global state.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from mre_common.hashing import versioned_sha256
from mre_common.private_cache import (
    fallback_folder,
    manifest_problem,
    note,
    remove_entry,
    trusted_folder,
    write_manifest,
)
from orchestration.master.errors import SimulationError
from orchestration.master.fmu_description import model_identifier, open_fmu
from orchestration.master.safe_archive import safe_extract

_SHARED_ROOT: Path | None = None  # see share_extractions
_IN_USE: set[str] = set()  # shared extraction folders loaded in this process
_FALLEN_BACK: set[Path] = set()  # private folders this process extracts into because the shared one failed


def share_extractions(root: Path | str | None) -> None:
    """Extract each FMU once under ``root`` (by the archive's SHA-256) and load it from there; None: a fresh
    temporary folder per load (the default). For processes that host one run each."""
    global _SHARED_ROOT
    _SHARED_ROOT = None if root is None else Path(root)


_archive_sha256 = versioned_sha256  # (path, size, mtime_ns) -> the archive's SHA-256, hashed once per version


def _extract_entry(root: Path, target: Path, path: Path, source: str) -> None:
    """Extract the archive into ``target`` with its manifest, renamed into place whole (a concurrent process
    never sees half of it; of two, the first rename wins and the other's copy is dropped)."""
    staging = tempfile.mkdtemp(prefix=".extract-", dir=root)
    try:
        with open_fmu(Path(path)) as z:
            safe_extract(z, staging, path)
        write_manifest(staging, source)
        try:
            os.rename(staging, target)
        except OSError:  # another process put it there first: verified by the caller
            if not os.path.lexists(target):
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _shared_folder(path: Path) -> str:
    """The FMU's extraction under the shared root, extracted now if it is not there yet.

    The root must be this user's private folder (mode 0700, owned, not a symlink; else this process extracts
    into a folder of its own, with a note), and an entry is used only if its files match the manifest written
    when it was extracted, which names the archive's SHA-256; a damaged entry is extracted again, with a note
    naming the cache (:mod:`mre_common.private_cache`)."""
    global _SHARED_ROOT
    assert _SHARED_ROOT is not None
    root = trusted_folder(_SHARED_ROOT)
    if root != _SHARED_ROOT:
        _SHARED_ROOT = root  # noted once; later loads of this process go there directly
    st = os.stat(path)
    sha = _archive_sha256(str(Path(path).resolve()), st.st_size, st.st_mtime_ns)
    target = root / sha
    for _attempt in range(2):
        if not os.path.lexists(target):
            try:
                _extract_entry(root, target, path, sha)
            except OSError as exc:  # a read-only or full cache: extract where this process may (noted)
                if root in _FALLEN_BACK:
                    raise
                _SHARED_ROOT = fallback_folder(root, f"cannot be written ({exc.strerror or exc})")
                _FALLEN_BACK.add(_SHARED_ROOT)
                return _shared_folder(path)
        problem = manifest_problem(target, sha)
        if problem is None:
            return str(target)
        note(root, f"extraction {sha[:16]}... {problem}: extracting it again")
        remove_entry(target)
    raise SimulationError(f"the FMU extraction cache {root} keeps giving a damaged copy of {path}: remove it")


def release(directory: str | None, abandoned: bool = False) -> None:
    """A loaded FMU's folder no longer used: a temporary one removed, a shared one kept for later runs.

    ``abandoned``: its library stays loaded with an instance never freed (after a Fatal status); a shared
    folder then stays taken, so no later load in this process shares that library's state."""
    if directory is None:
        return
    if directory in _IN_USE:
        if not abandoned:
            _IN_USE.discard(directory)
    else:
        shutil.rmtree(directory, ignore_errors=True)


def load_slave(slave_class: Any, path: Path, md: Any, name: str, start_time: float,
               interface: str = "co-simulation") -> tuple[str, Any]:
    """Extract an FMU and load the library of its ``interface`` as fmpy's ``slave_class`` (FMU2Slave, FMU2Model or
    FMU3Slave); its folder and the slave (give the folder to :func:`release` when the unit is freed)."""
    directory = None
    try:
        shared = _shared_folder(Path(path)) if _SHARED_ROOT is not None else None
        if shared is not None and shared not in _IN_USE:
            directory = shared
            _IN_USE.add(directory)
        else:
            directory = tempfile.mkdtemp(prefix="cosim_fmu_")
            with open_fmu(Path(path)) as z:
                safe_extract(z, directory, path)
        slave = slave_class(guid=md.guid, unzipDirectory=directory,
                            modelIdentifier=model_identifier(md, interface), instanceName=name)
    except Exception as exc:
        release(directory)
        raise SimulationError(f"cannot load FMU {path}: {exc}", unit=name, time=start_time) from exc
    return directory, slave
