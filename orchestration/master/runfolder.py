"""Run folders: never overwritten, every file written atomically (temporary file, then rename)."""

from __future__ import annotations

import functools
import json
import math
import os
import uuid
from collections.abc import Sequence
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

from mre_common.atomic_files import atomic_write, atomic_write_text
from mre_common.folder_claim import claim_folder
from mre_common.fs_limits import name_problem, path_problem
from mre_common.hashing import file_sha256

STAMP_RESERVE = len("-20261202T063000Z-999")
"""Bytes a run folder's name gets after the scenario's name (UTC time stamp, numeric suffix)."""
INSIDE_RESERVE = len("/.timeseries.csv.incomplete.XXXXXXXX.tmp") + 16
"""Bytes kept for the longest name a run writes inside its folder."""


class RunFolderExists(FileExistsError):
    """The chosen output folder exists and is not empty (or another run has just claimed it)."""


class RunFolderUnusable(RunFolderExists):
    """The run folder cannot be created or written (a file as parent, read-only or missing file system).

    A subclass of :class:`RunFolderExists` so every caller that reports that one as a
    configuration error (exit 2, nothing written) reports this one the same way.
    """


RUN_MARKER = ".mre-cosim-run"
"""Written first into every run folder, with O_CREAT|O_EXCL: the atomic claim of the folder
(two runs given the same ``--out`` cannot both get it) and the probe that it is writable,
both before anything is simulated."""


def _claim(folder: Path, created: bool) -> None:
    """Create the marker exclusively; on failure remove a folder this run created and raise."""
    info = {"tool": "mre-cosim run", "pid": os.getpid(), "started": datetime.now(UTC).isoformat(),
            "run_id": uuid.uuid4().hex}
    try:
        claim_folder(folder, RUN_MARKER, info)  # on a failed write the marker is removed again
    except FileExistsError:
        raise RunFolderExists(
            f"{folder} exists and is not empty (claimed by another run): choose another --out (nothing was written)"
        ) from None
    except OSError as exc:
        _remove_created(folder, created)
        raise RunFolderUnusable(f"{folder}: cannot write the run folder ({_why(exc, folder)}); "
                                "choose another --out (nothing was written)") from None


def _why(exc: OSError, path: Path) -> str:
    """A short reason for a failed folder creation, naming a file that stands where a folder must be."""
    for parent in (path, *path.parents):
        try:
            if parent.exists() and not parent.is_dir():
                return f"{parent} is a file, not a folder"
        except OSError:  # a name beyond the file system's limits (ENAMETOOLONG), a loop: not a file standing there
            continue
    where = f"{exc.filename}: " if exc.filename and str(exc.filename) != str(path) else ""
    return where + (exc.strerror or str(exc))


def _missing_ancestors(path: Path) -> list[Path]:
    """The folders of ``path`` (itself included) that do not exist yet, deepest first."""
    missing = []
    for folder in (path, *path.parents):
        if os.path.lexists(folder):
            break
        missing.append(folder)
    return missing


def _remove_created(folder: Path, created: bool) -> None:
    if created:
        try:
            folder.rmdir()  # only ever an empty folder this run made itself
        except OSError:
            pass


def run_id(folder: Path) -> str | None:
    """The id written into the claim marker of a run folder (None if unreadable)."""
    try:
        return json.loads((Path(folder) / RUN_MARKER).read_text())["run_id"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def new_run_folder(base: Path, name: str, explicit: Path | None = None) -> Path:
    """Create, claim and return a fresh run folder, before anything is simulated.

    With ``explicit`` (``--out``), that folder is used if it does not exist or is empty;
    otherwise ``base/<name>-<UTC timestamp>`` with a numeric suffix if taken. The folder is
    claimed by creating :data:`RUN_MARKER` exclusively, so of two runs racing for the same
    ``--out`` exactly one gets it and the other raises :class:`RunFolderExists`; a folder
    that cannot be created or written raises :class:`RunFolderUnusable` naming the path.
    """
    if explicit is not None:
        return _explicit_folder(Path(os.path.abspath(explicit)))  # resolved now: a later os.chdir cannot move it
    return _stamped_folder(base, name)


def _explicit_folder(explicit: Path) -> Path:
    """``--out``: created (with its missing parents) or empty, then claimed; the parents this run created are
    removed again when it cannot be."""
    problem = path_problem(explicit, INSIDE_RESERVE)
    if problem:
        raise RunFolderUnusable(f"--out {problem}: choose a shorter --out (nothing was written)")
    parents = _missing_ancestors(explicit.parent)
    try:
        _claim(explicit, _made_or_empty(explicit))
    except RunFolderExists:
        for folder in parents:  # deepest first; only empty folders this run created
            _remove_created(folder, True)
        raise
    return explicit


def _made_or_empty(explicit: Path) -> bool:
    """Create ``explicit`` (True) or find it an empty folder (False); RunFolderExists/RunFolderUnusable else."""
    try:
        explicit.parent.mkdir(parents=True, exist_ok=True)
        try:
            explicit.mkdir()
            return True
        except FileExistsError:
            if not explicit.is_dir():
                raise RunFolderUnusable(f"{explicit} is a file, not a folder: choose another --out "
                                        "(nothing was written)") from None
            if any(explicit.iterdir()):
                raise RunFolderExists(
                    f"{explicit} exists and is not empty: choose another --out (nothing was written)"
                ) from None
            return False
    except RunFolderExists:
        raise
    except OSError as exc:
        raise RunFolderUnusable(f"{explicit}: cannot create the run folder ({_why(exc, explicit)}); "
                                "choose another --out (nothing was written)") from None


def _stamped_folder(base: Path, name: str) -> Path:
    """``base/<name>-<UTC timestamp>``, with a numeric suffix if taken, created and claimed."""
    if not name or any(c in name for c in "/\\\x00") or name.startswith("."):
        raise RunFolderUnusable(f"{name!r} cannot name a run folder inside {base}: a plain name is needed "
                                "(no '/' or '\\', not starting with '.'); nothing was written")
    base = Path(os.path.abspath(base))  # resolved now: a later os.chdir (a unit's script) cannot move it
    problem = name_problem(name, base, STAMP_RESERVE) or path_problem(base, INSIDE_RESERVE + STAMP_RESERVE
                                                                         + len(os.fsencode(name)))
    if problem:
        raise RunFolderUnusable(f"run folder {problem}: choose a shorter name or results.dir, or pass --out "
                                "(nothing was written)")
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    try:
        base.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunFolderUnusable(f"{base}: cannot create the results folder ({_why(exc, base)}); "
                                "set results.dir or pass --out (nothing was written)") from None
    for k in range(1000):
        folder = base / (f"{name}-{stamp}" if k == 0 else f"{name}-{stamp}-{k}")
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise RunFolderUnusable(f"{folder}: cannot create the run folder ({_why(exc, folder)}); "
                                    "set results.dir or pass --out (nothing was written)") from None
        _claim(folder, True)
        return folder
    raise RunFolderExists(f"no free run folder name under {base}")


NON_FINITE_KEY = "non_finite"
"""Key of a JSON object's list of the values written as null because they were not finite: {path: reason}."""


def _finite_only(value: Any, path: str, found: dict[str, str]) -> Any:
    """``value`` with every non-finite float replaced by None, each one's path and reason put in ``found``."""
    if isinstance(value, float) and not math.isfinite(value):
        found[path or "$"] = "not a number (nan)" if math.isnan(value) else f"infinite ({value})"
        return None
    if isinstance(value, dict):
        return {k: _finite_only(v, f"{path}.{k}" if path else str(k), found) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_only(v, f"{path}[{i}]", found) for i, v in enumerate(value)]
    if type(value).__module__ == "numpy" and hasattr(value, "item"):  # a NumPy scalar or array
        return _finite_only(value.tolist(), path, found)
    return value


def strict_json_data(data: Any) -> Any:
    """``data`` as strict JSON allows (RFC 8259: no NaN or Infinity): each non-finite number is written as null,
    and a top-level object lists it under :data:`NON_FINITE_KEY` with its reason."""
    found: dict[str, str] = {}
    clean = _finite_only(data, "", found)
    if found and isinstance(clean, dict):
        clean[NON_FINITE_KEY] = {**(clean.get(NON_FINITE_KEY) or {}), **found}
    return clean


def write_json(path: Path, data: Any) -> None:
    """Write strict JSON atomically (non-finite numbers as null with their reason: :func:`strict_json_data`)."""
    clean = strict_json_data(data)
    atomic_write(path, lambda f: json.dump(clean, f, indent=2, default=str, allow_nan=False))


def write_text(path: Path, text: str) -> None:
    """Write text atomically."""
    atomic_write_text(path, text)


sha256 = file_sha256  # the name orchestration.engine_hooks imports (mre_common.hashing holds the hasher)


def package_versions(names: Sequence[str] = ("fmpy", "pythonfmu", "numpy", "scipy", "matplotlib", "pydantic",
                                             "PyYAML")) -> dict[str, str]:
    """Installed versions of the packages a run depends on (read once per process: a study's
    forked children inherit them instead of scanning site-packages again for every run)."""
    return dict(_package_versions(tuple(names)))


@functools.cache
def _package_versions(names: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out
