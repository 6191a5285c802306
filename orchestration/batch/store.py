"""Finished jobs of a study, one JSON file each under ``<study>/jobs/<key>.json``: what ``--resume`` reads.

A job's key is made from its content (:func:`orchestration.batch.portable.job_key`), so a
resumed study reuses exactly the results whose inputs and code are unchanged. Results of
jobs that ran and failed by themselves are kept (they would fail again); jobs lost with
their workers or cancelled are not, so a resume runs them.

Every stored result carries its content key and a SHA-256 checksum of its content: a file
that is not what the store wrote (edited by hand, truncated, of another key, not a JSON
object) is refused with :class:`StoreError` naming it, never used. :func:`open_for_resume`
checks a whole study folder before a ``--resume`` and claims it, so that two resumes of one
folder do not both compute.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mre_common.folder_claim import claim_folder, read_claim
from orchestration.master.runfolder import strict_json_data, write_json

KEPT_STATUSES = ("ok", "failed")
RESUME_MARKER = ".resume-claim"
"""The file a running ``--resume`` holds in its study folder (removed when it ends)."""


class StoreError(ValueError):
    """A stored result, or a study folder, that is not what the tool wrote (the message names the file)."""


def checksum(record: dict[str, Any]) -> str:
    """SHA-256 of a record's JSON (keys sorted; as it reads back from its file), without its ``checksum``."""
    body = json.loads(json.dumps({k: v for k, v in record.items() if k != "checksum"}, default=str))
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def stored_problem(path: Path, key: str) -> str | None:
    """Why the file of a stored result is not one the store wrote for ``key``, or None if it is."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except IsADirectoryError:
        return "a folder, not a stored result"
    except (OSError, UnicodeDecodeError) as exc:
        return f"cannot be read ({exc.strerror if isinstance(exc, OSError) and exc.strerror else exc})"
    except ValueError as exc:
        return f"not JSON ({exc})"
    if not isinstance(data, dict):
        return f"a JSON {type(data).__name__}, not a stored result"
    if data.get("key") != key:
        return f"holds the result of key {str(data.get('key'))[:80]!r}, not of {key!r} (its name)"
    if data.get("status") not in KEPT_STATUSES or not isinstance(data.get("ok"), bool):
        return "has no valid status"
    if data.get("checksum") != checksum(data):
        return "its checksum does not match its content (edited after it was stored?)"
    return None


@dataclass(frozen=True)
class StoredResult:
    """One finished job as a study's ``jobs/`` keeps it: its label, how it ended, the job's value if ``ok``.

    ``value`` is the job's own plain data (each study types it: ``case_jobs.CosimResult``, ...); ``reused_from``
    names the store across studies a result was copied from. :meth:`to_json` is what :meth:`ResultStore.put`
    is given, :meth:`from_json` reads back what :meth:`ResultStore.get` returns."""

    label: str
    ok: bool
    status: str
    value: Any = None
    error: str | None = None
    wall_time_s: float | None = None
    worker: str | None = None
    reused_from: str | None = None

    def to_json(self) -> dict[str, Any]:
        out = {"label": self.label, "ok": self.ok, "status": self.status, "value": self.value, "error": self.error,
               "wall_time_s": self.wall_time_s, "worker": self.worker}
        return out if self.reused_from is None else {**out, "reused_from": self.reused_from}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> StoredResult:
        return cls(label=d.get("label", d.get("key", "")), ok=bool(d["ok"]), status=d["status"], value=d.get("value"),
                   error=d.get("error"), wall_time_s=d.get("wall_time_s"), worker=d.get("worker"),
                   reused_from=d.get("reused_from"))


class ResultStore:
    """The ``jobs/`` folder of a study."""

    def __init__(self, study_folder: Path) -> None:
        self.folder = Path(study_folder) / "jobs"
        self.folder.mkdir(parents=True, exist_ok=True)

    def _path(self, key: str) -> Path:
        return self.folder / f"{key}.json"

    def get(self, key: str, strict: bool = True) -> dict[str, Any] | None:
        """The stored result of a job, or None if absent. A file that is not a result the store wrote
        for this key raises :class:`StoreError` naming it (``strict=False``: is taken as absent)."""
        path = self._path(key)
        if not path.exists() and not path.is_symlink():
            return None
        problem = stored_problem(path, key)
        if problem is not None:
            if not strict:
                return None
            raise StoreError(f"{path}: {problem}; delete it to compute that job again")
        return json.loads(path.read_text(encoding="utf-8"))

    def put(self, key: str, record: dict[str, Any]) -> bool:
        """Store a result (atomically, with its key and checksum) if its status is worth keeping; True if stored."""
        if record.get("status") not in KEPT_STATUSES:
            return False
        data = strict_json_data({k: v for k, v in record.items() if k != "checksum"})  # as it reads back
        data["key"] = key
        write_json(self._path(key), {**data, "checksum": checksum(data)})
        return True

    def keys(self) -> set[str]:
        return {p.stem for p in self.folder.glob("*.json")}

    def problems(self) -> list[str]:
        """Every entry of ``jobs/`` that is not a result the store wrote, one line each naming it."""
        return jobs_problems(self.folder)


class SharedResultStore(ResultStore):
    """Results kept across studies in this user's cache (``$MRE_COSIM_CACHE/results/jobs``): the folder must be
    private (mode 0700, owned, not a symlink: :mod:`mre_common.private_cache`); an entry is used only if it is
    what the store wrote for its key (its content key names the job's inputs and code, its checksum its
    content), else removed and computed again, with a note naming the cache; a result that cannot be kept
    (a read-only or full cache) is noted, never an error."""

    def __init__(self, cache: Path) -> None:
        from mre_common.private_cache import private_folder

        self.folder = private_folder(private_folder(Path(cache)) / "jobs")

    def get(self, key: str, strict: bool = False) -> dict[str, Any] | None:
        from mre_common.private_cache import note, remove_entry

        path = self._path(key)
        if not os.path.lexists(path):
            return None
        problem = "is a symbolic link" if path.is_symlink() else stored_problem(path, key)
        if problem is None:
            try:
                return json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                problem = f"cannot be read ({exc})"
        note(self.folder, f"{path.name} {problem}: not used (removed; computed again where needed)")
        remove_entry(path)
        return None

    def put(self, key: str, record: dict[str, Any]) -> bool:
        from mre_common.private_cache import note

        try:
            return super().put(key, record)
        except OSError as exc:
            note(self.folder, f"cannot keep a result ({exc.strerror or exc}); it is computed again next time")
            return False


def open_shared_store(cache: Path) -> SharedResultStore | None:
    """:class:`SharedResultStore` at ``cache``, or None with a note naming it if it cannot be used."""
    from mre_common.private_cache import note

    try:
        return SharedResultStore(cache)
    except OSError as exc:
        note(cache, f"{str(exc).removeprefix(f'cache {cache}').strip(' :')}; results are not kept across studies")
        return None


def jobs_problems(jobs: Path) -> list[str]:
    """Every entry of a ``jobs/`` folder that is not a result the store wrote, one line each naming it."""
    out = []
    for path in sorted(jobs.iterdir()):
        if path.name.startswith(".") and path.name.endswith(".tmp"):
            continue  # an atomic write interrupted: never renamed, never read
        if path.suffix != ".json":
            out.append(f"{path}: not a stored result (unexpected file in {jobs})")
            continue
        problem = stored_problem(path, path.stem)
        if problem is not None:
            out.append(f"{path}: {problem}")
    return out


STAMP_RESERVE = len("-20261202T063000Z-999")
"""Bytes a run folder's name gets after the study's name (UTC time stamp, numeric suffix)."""
INSIDE_RESERVE = 160
"""Bytes kept for the paths a study writes inside its folder (runs/<record>-<strategy>/timeseries.csv, ...)."""


def folder_problems(name: str, output: Path, out: Path | None) -> list[tuple[str, str]]:
    """(key, problem) for a study folder the file system cannot hold, checked in bytes against its own limits:
    the study's ``name`` (+ time stamp) inside ``output``, or the ``--out`` path, with room for the files inside."""
    from mre_common.fs_limits import name_problem, path_problem, plain_name_problem

    found = []
    if out is not None:
        problem = path_problem(out, INSIDE_RESERVE)
        if problem:
            found.append(("--out", problem))
        return found
    problem = plain_name_problem(name) or name_problem(name, output, STAMP_RESERVE)
    if problem:
        found.append(("name", problem))
    problem = path_problem(output, INSIDE_RESERVE + STAMP_RESERVE + len(os.fsencode(name)))
    if problem:
        found.append(("output", problem))
    return found


def check_folder(name: str, output: Path, out: Path | None, lines: dict, study_file: Path) -> None:
    """:func:`folder_problems` as a ScenarioError (each with the key's file and line), before anything is written."""
    from orchestration.master.errors import Problem, ScenarioError
    from orchestration.master.yaml_source import locate

    problems = []
    for key, message in folder_problems(name, output, out):
        file, line = ("command line", None) if key == "--out" else locate(lines, (key,))
        problems.append(Problem(message, key, file or str(study_file), line))
    if problems:
        raise ScenarioError(problems)


def _alive(info: dict[str, Any] | None) -> bool:
    """Whether the process of a claim's record may still be running (this machine: its pid exists)."""
    if info is None or info.get("host") != socket.gethostname() or not isinstance(info.get("pid"), int):
        return info is not None
    try:
        os.kill(info["pid"], 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def open_for_resume(folder: Path, record_file: str, tool: str) -> tuple[ResultStore, Path]:
    """Check a study folder for ``--resume`` and claim it: its store and the claim's marker (remove it when done).

    StoreError (naming the file) for a folder that is not one the tool wrote -- not a folder,
    read-only, without ``record_file``, ``jobs`` not a folder, a stored result not written by the
    store -- or one another resume is running in. A claim left by a process that no longer runs
    on this machine is taken over.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise StoreError(f"{folder}: {'not a folder' if folder.exists() else 'does not exist'}")
    if not (folder / record_file).is_file():
        raise StoreError(f"{folder / record_file}: missing or not a file: not a study folder {tool} wrote")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StoreError(f"{folder}: cannot write into it (read-only?)")
    jobs = folder / "jobs"
    if jobs.is_symlink() or (jobs.exists() and not jobs.is_dir()):
        raise StoreError(f"{jobs}: not a folder (it holds the stored results)")
    if jobs.is_dir() and not os.access(jobs, os.W_OK | os.X_OK):
        raise StoreError(f"{jobs}: cannot write into it (read-only?)")
    try:  # checked before the claim: a folder refused is left exactly as it was
        problems = jobs_problems(jobs) if jobs.is_dir() else []
    except OSError as exc:
        raise StoreError(f"{jobs}: cannot be read ({exc.strerror or exc})") from None
    if problems:
        more = f" (and {len(problems) - 5} more)" if len(problems) > 5 else ""
        raise StoreError("stored results that the tool did not write (delete them to compute those jobs "
                         "again):\n  " + "\n  ".join(problems[:5]) + more)
    info = {"tool": tool, "pid": os.getpid(), "host": socket.gethostname(), "time": time.time()}
    for _attempt in range(2):
        try:
            marker = claim_folder(folder, RESUME_MARKER, info)
            break
        except FileExistsError:
            held = read_claim(folder, RESUME_MARKER)
            if _alive(held):
                who = f"process {held.get('pid')} on {held.get('host')}" if held else "another process"
                raise StoreError(f"{folder}: another --resume ({who}) is running in it; if it is not, delete "
                                 f"{folder / RESUME_MARKER}") from None
            (folder / RESUME_MARKER).unlink(missing_ok=True)  # left by a process that has ended
        except OSError as exc:
            raise StoreError(f"{folder}: cannot claim it ({exc.strerror or exc})") from None
    else:
        raise StoreError(f"{folder}: another --resume claimed it at the same moment")
    try:
        store = ResultStore(folder)
    except OSError as exc:
        marker.unlink(missing_ok=True)
        raise StoreError(f"{jobs}: cannot be created ({exc.strerror or exc})") from None
    return store, marker
