"""A checked plan that travels to a worker with no shared file system, and the content key of a job.

The client checks every scenario (:func:`orchestration.engine_hooks.plan_scenario`) and sends the
:class:`~orchestration.master.resolve.SystemPlan` together with the bytes of the FMUs and
data files it names, each identified by its SHA-256. A worker writes each file once into a
content-addressed cache (``<temp>/mre-cosim-files/<sha256>/<original name>``), checking
the SHA-256 of the bytes it received, and runs the plan with its paths pointing there
(:func:`relocate`). File bytes go through :meth:`BatchPool.share <orchestration.batch.pool.BatchPool.share>`:
each worker fetches a file once, whatever the number of jobs that use it.

:func:`job_key` names a job by its content: the resolved scenario (parameters, connections,
recorded variables, limits, time grid and algorithm), the SHA-256 of every FMU and data
file, the job's own inputs, and the code version (:func:`code_version`). A study stores each
result under that key, so ``--resume`` recomputes exactly what is missing or changed.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import tempfile
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from mre_common.atomic_files import atomic_write_bytes
from mre_common.hashing import cached_file_sha256
from mre_common.private_cache import fallback_folder, folder_problem, note, remove_entry, trusted_folder
from mre_common.project_paths import PROJECT_DIR
from orchestration.master.resolve import SystemPlan

# The code that decides any job's numbers: the engine (its folder: also the C sources it compiles) and every
# project module the job plumbing imports. A study adds its job module (``module:<name>``: that module and all it
# imports, orchestration.batch.code_sources) through ``job_key(..., sources=...)``.
CODE_SOURCES = ("orchestration/master", "module:orchestration.batch.jobs", "module:orchestration.batch.portable")
PACKAGE = "mre-cosim"


class FileCorrupted(ValueError):
    """Bytes received for a file do not have the SHA-256 the client computed."""


@dataclass(frozen=True)
class FileRef:
    """A file a job needs: its SHA-256 (hex) and original name."""

    sha256: str
    name: str


file_sha256 = cached_file_sha256  # SHA-256 (hex) of a file, computed once per (path, size, modification time)


@dataclass(frozen=True)
class PortablePlan:
    """A plan as checked on the client, and the file behind each path it names."""

    plan: SystemPlan
    files: dict[str, FileRef]  # client path -> file

    @property
    def shas(self) -> set[str]:
        return {ref.sha256 for ref in self.files.values()}


def portable(plan: SystemPlan) -> PortablePlan:
    """The plan with a FileRef for every FMU and data file it names."""
    paths = [*plan.fmu_paths.values(), *plan.data_files.values()]
    return PortablePlan(plan, {str(p): FileRef(file_sha256(p), Path(p).name) for p in paths})


def file_bytes(plans: list[PortablePlan]) -> dict[str, Path]:
    """SHA-256 -> one client path, for every file the plans need (what to share with the workers)."""
    out: dict[str, Path] = {}
    for pp in plans:
        for path, ref in pp.files.items():
            out.setdefault(ref.sha256, Path(path))
    return out


def cache_root() -> Path:
    """The worker's content-addressed file cache: this user's private folder (mode 0700, owned, not a symlink;
    else a folder of this process's own, with a note: :func:`mre_common.private_cache.trusted_folder`)."""
    global _CACHE_ROOT
    wanted = Path(tempfile.gettempdir()) / f"mre-cosim-files-{os.getuid() if hasattr(os, 'getuid') else 'user'}"
    if _CACHE_ROOT is None or _CACHE_ROOT[0] != wanted:
        _CACHE_ROOT = (wanted, trusted_folder(wanted))
    return _CACHE_ROOT[1]


_CACHE_ROOT: tuple[Path, Path] | None = None  # (the folder wanted, the folder used)


def local_copy(ref: FileRef, data: bytes) -> Path:
    """The cached copy of a file on this machine, written once (atomically) after checking its SHA-256; a copy
    found there is used only if it is a regular file (not a link) with that SHA-256, else written again (noted)."""
    root = cache_root()
    target = root / ref.sha256 / ref.name
    if os.path.lexists(target):
        if not target.is_symlink() and target.is_file() and file_sha256(target) == ref.sha256:
            return target
        note(root, f"{ref.sha256[:16]}.../{ref.name} is not the file of that SHA-256: writing it again")
        remove_entry(target)
    if hashlib.sha256(data).hexdigest() != ref.sha256:
        raise FileCorrupted(f"{ref.name}: received bytes do not match SHA-256 {ref.sha256}")
    folder = target.parent
    if os.path.lexists(folder) and folder_problem(folder) is not None:
        note(root, f"{folder.name}: {folder_problem(folder)}: made again")
        remove_entry(folder)
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        atomic_write_bytes(target, data, mode=0o600)  # this user's cache: readable by this user only
    except OSError as exc:  # a read-only or full cache: this process keeps its copies elsewhere (noted)
        global _CACHE_ROOT
        if _CACHE_ROOT is None or _CACHE_ROOT[1] != root:
            raise
        _CACHE_ROOT = (_CACHE_ROOT[0], fallback_folder(root, f"cannot be written ({exc.strerror or exc})"))
        return local_copy(ref, data)
    return target


def relocate(pp: PortablePlan, data: dict[str, bytes], parameters: dict[str, dict[str, Any]] | None = None
             ) -> tuple[SystemPlan, dict[str, str]]:
    """The plan with its files in this machine's cache; also {local path: client path}.

    ``data`` maps SHA-256 to bytes; ``parameters`` (unit -> name -> value) are set on top
    of the plan's (values the checks already accepted, e.g. another ``ground.scale``).
    """
    local = {client: str(local_copy(ref, data[ref.sha256])) for client, ref in pp.files.items()}
    plan = pp.plan
    params = copy.deepcopy(plan.parameters)
    for dotted, path in plan.data_files.items():
        unit, _, name = dotted.partition(".")
        params[unit][name] = local[str(path)]
    for unit, values in (parameters or {}).items():
        params[unit].update(values)
    moved = replace(plan, fmu_paths={u: Path(local[str(p)]) for u, p in plan.fmu_paths.items()},
                    data_files={k: Path(local[str(p)]) for k, p in plan.data_files.items()}, parameters=params)
    return moved, {v: k for k, v in local.items()}


CODE_VERSION_ENV = "MRE_COSIM_CODE_VERSION"


def installed_version() -> str:
    """The installed ``mre-cosim`` distribution's version, or ``unknown``."""
    from importlib import metadata

    try:
        return metadata.version(PACKAGE)
    except metadata.PackageNotFoundError:
        return "unknown"


@lru_cache(maxsize=16)
def code_version(sources: tuple[str, ...] = ()) -> str:
    """Package version and a SHA-256 over the sources that decide a job's numbers: CODE_SOURCES and ``sources``
    (paths relative to the project, files or folders, or ``module:<name>``: the project files that module imports,
    :func:`orchestration.batch.code_sources.import_closure`).

    ``MRE_COSIM_CODE_VERSION`` pins it instead: to resume a study across an edit you know
    changes no number (at your own risk; the tests use it while others edit the checkout).
    """
    if os.environ.get(CODE_VERSION_ENV):
        return os.environ[CODE_VERSION_ENV]

    from orchestration.batch.code_sources import expand

    h = hashlib.sha256()
    for entry in expand((*CODE_SOURCES, *sources)):
        root = PROJECT_DIR / entry
        files = sorted(root.rglob("*")) if root.is_dir() else [root]
        for f in files:
            if f.is_file() and f.suffix in (".py", ".c", ".h") and "__pycache__" not in f.parts:
                h.update(f.relative_to(PROJECT_DIR).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return f"{installed_version()}+{h.hexdigest()[:16]}"


def plan_content(pp: PortablePlan) -> dict[str, Any]:
    """What decides a plan's results, with every file named by its SHA-256 instead of its path."""
    plan = pp.plan
    by_path = {path: ref.sha256 for path, ref in pp.files.items()}
    params = {u: {k: (f"sha256:{by_path[str(plan.data_files[f'{u}.{k}'])]}" if f"{u}.{k}" in plan.data_files else v)
                  for k, v in sorted(values.items())} for u, values in sorted(plan.parameters.items())}
    return {
        "fmus": {u: by_path[str(p)] for u, p in sorted(plan.fmu_paths.items())},
        "parameters": params,
        "links": sorted([list(link.source), list(link.target), link.delayed] for link in plan.links),
        "recorded": [list(p) for p in plan.recorded],
        "limits": sorted([list(p), v] for p, v in plan.limits.items()),
        "simulation": plan.loaded.scenario.simulation.model_dump(mode="json"),
        "interfaces": {u: [spec.interface, spec.relative_tolerance]
                       for u, spec in sorted(plan.loaded.scenario.units.items())},
    }


def job_key(kind: str, content: dict[str, Any], sources: tuple[str, ...] = ()) -> str:
    """SHA-256 (hex, 32 digits) of a job's kind, content and the code version (``sources``: see code_version)."""
    text = json.dumps({"kind": kind, "code": code_version(tuple(sources)), "content": content}, sort_keys=True,
                      default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:32]
