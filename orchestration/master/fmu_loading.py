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

import hashlib
import os
import shutil
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Any

from orchestration.master.errors import SimulationError
from orchestration.master.fmu_description import model_identifier, open_fmu
from orchestration.master.safe_archive import safe_extract

_SHARED_ROOT: Path | None = None  # see share_extractions
_IN_USE: set[str] = set()  # shared extraction folders loaded in this process


def share_extractions(root: Path | str | None) -> None:
    """Extract each FMU once under ``root`` (by the archive's SHA-256) and load it from there; None: a fresh
    temporary folder per load (the default). For processes that host one run each."""
    global _SHARED_ROOT
    _SHARED_ROOT = None if root is None else Path(root)


@lru_cache(maxsize=256)
def _archive_sha256(path: str, size: int, mtime_ns: int) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _shared_folder(path: Path) -> str:
    """The FMU's extraction under the shared root, extracted now if it is not there yet (atomically: renamed
    into place whole, so a concurrent process never sees half of it)."""
    assert _SHARED_ROOT is not None
    st = os.stat(path)
    target = _SHARED_ROOT / _archive_sha256(str(Path(path).resolve()), st.st_size, st.st_mtime_ns)
    if not target.is_dir():
        _SHARED_ROOT.mkdir(parents=True, exist_ok=True)
        staging = tempfile.mkdtemp(prefix=".extract-", dir=_SHARED_ROOT)
        try:
            with open_fmu(Path(path)) as z:
                safe_extract(z, staging, path)
            try:
                os.rename(staging, target)
            except OSError:  # another process put it there first
                if not target.is_dir():
                    raise
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    return str(target)


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
