"""Per-user cache folders that trust nothing they find: private, owned, never through a symlink, verified.

A cache folder (the FMU extractions and file copies of a study's workers in the temporary
folder, ``$MRE_COSIM_CACHE`` with the compiled kernels and the results kept across studies)
is used only if it is a real folder (not a symbolic link), owned by this user, with no
permission for group or others (mode 0700, as :func:`private_folder` creates it). Every
entry is checked against a content manifest (:func:`write_manifest`, :func:`manifest_problem`:
the SHA-256 and size of each file, written when the entry was made) before it is used; a
damaged entry is removed and made again, with a one-line note on stderr naming the cache
(:func:`note`). Entries are made under a temporary name and renamed into place, so
concurrent writers each see a whole entry or none.

Threat model: another local user (a shared temporary folder) must not be able to plant or
alter an entry; this user's own files are trusted as any code they run is. No secret key
is kept, so the manifest guards against damage (truncation, a crash, a full disk), and the
folder's owner and mode against others.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path

from mre_common.hashing import file_sha256

MANIFEST = ".mre-cosim-manifest.json"
"""The content manifest of a folder entry: {relative path: [size, SHA-256]} of every regular file."""
_NOTED: set[str] = set()


class CacheUnusable(OSError):
    """A cache folder that cannot be trusted or used (a symlink, another owner, open to others, a file)."""


def note(cache: str | os.PathLike[str], text: str) -> None:
    """One line on stderr about a cache, naming it (each distinct line once per process)."""
    line = f"note: cache {cache}: {text}"
    if line not in _NOTED:
        _NOTED.add(line)
        print(line, file=sys.stderr, flush=True)


def _uid() -> int | None:
    return os.getuid() if hasattr(os, "getuid") else None


def folder_problem(path: str | os.PathLike[str]) -> str | None:
    """Why an existing ``path`` is not a private cache folder of this user, or None (checked with lstat: a
    symbolic link is never followed)."""
    try:
        st = os.lstat(path)
    except OSError as exc:
        return f"cannot be examined ({exc.strerror or exc})"
    if stat.S_ISLNK(st.st_mode):
        return "is a symbolic link (never followed)"
    if not stat.S_ISDIR(st.st_mode):
        return "is not a folder"
    uid = _uid()
    if uid is not None and st.st_uid != uid:
        return f"belongs to user id {st.st_uid}, not to this user ({uid})"
    if uid is not None and st.st_mode & 0o077:
        return f"has mode {stat.S_IMODE(st.st_mode):04o}: open to other users (0700 expected)"
    return None


def _in_temp(path: Path) -> bool:
    """Whether ``path`` is directly in the temporary folder (where this project's cache names are its own)."""
    return Path(os.path.abspath(path)).parent == Path(os.path.abspath(tempfile.gettempdir()))


def _replace_own_stray(path: Path) -> None:
    """A file or symbolic link of this user's at one of this project's cache names in the temporary folder (a
    leftover, or made by this user): removed (noted), so the folder can be made. Anything of another user's,
    or outside the temporary folder (a user's own link from ``~/.cache`` to another disk), is left alone."""
    try:
        st = os.lstat(path)
    except OSError:
        return
    if stat.S_ISDIR(st.st_mode) or st.st_uid != _uid() or not _in_temp(path):
        return
    note(path, f"was a {'symbolic link' if stat.S_ISLNK(st.st_mode) else 'file'} of this user's, not a folder: "
               "removed (never followed) and made a private folder")
    try:
        os.unlink(path)
    except FileNotFoundError:  # a concurrent process removed it first
        pass
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:  # and made the folder: checked by the caller
        pass


def _make_private(path: Path) -> None:
    """An own cache folder with a mode other than 0700: readable by others only (an older version made it
    so), it is closed (chmod 0700) as it is; writable by others, whatever is in it may have been planted, so it
    is emptied first (noted). A symlink or a folder of another user is left alone (:func:`folder_problem`)."""
    try:
        st = os.lstat(path)
    except OSError:
        return
    uid = _uid()
    if uid is None or not stat.S_ISDIR(st.st_mode) or st.st_uid != uid or not st.st_mode & 0o077:
        return
    if st.st_mode & 0o022:
        note(path, f"had mode {stat.S_IMODE(st.st_mode):04o} (others could write into it): emptied and made private")
        remove_entry(path)
        os.mkdir(path, 0o700)
    else:
        os.chmod(path, 0o700)


def private_folder(path: str | os.PathLike[str]) -> Path:
    """``path`` as a private cache folder of this user: created with mode 0700 if absent (its parents as
    needed), else checked (:func:`folder_problem`; an own folder open to others is first made private,
    :func:`_make_private`). :class:`CacheUnusable` names the folder and why not."""
    path = Path(path)
    try:
        os.makedirs(path.parent, exist_ok=True)
        os.mkdir(path, 0o700)
    except FileExistsError:
        try:
            _replace_own_stray(path)
            _make_private(path)
        except OSError as exc:
            raise CacheUnusable(f"cache {path}: cannot be made private ({exc.strerror or exc})") from None
    except OSError as exc:
        raise CacheUnusable(f"cache {path}: cannot be created ({exc.strerror or exc})") from None
    problem = folder_problem(path)
    if problem is not None:
        raise CacheUnusable(f"cache {path} {problem}")
    return path


_FALLBACKS: dict[str, Path] = {}


def fallback_folder(path: str | os.PathLike[str], why: str) -> Path:
    """A fresh private folder for this process when the cache at ``path`` cannot be used (noted once, naming
    it and why; removed when the process exits): the process works without sharing, never inside the
    untrusted folder."""
    key = os.fspath(path)
    if key not in _FALLBACKS:
        import atexit

        folder = Path(tempfile.mkdtemp(prefix="mre-cosim-cache-"))
        owner = os.getpid()

        def remove() -> None:  # by the process that made it only (a forked child inherits the handler)
            if os.getpid() == owner:
                shutil.rmtree(folder, ignore_errors=True)

        atexit.register(remove)
        _FALLBACKS[key] = folder
        note(path, f"{why}; not used (this process caches in {folder} instead)")
    return _FALLBACKS[key]


def trusted_folder(path: str | os.PathLike[str]) -> Path:
    """:func:`private_folder`, or on :class:`CacheUnusable` a :func:`fallback_folder` (never an error)."""
    try:
        return private_folder(path)
    except CacheUnusable as exc:
        return fallback_folder(path, str(exc).removeprefix(f"cache {path} ").removeprefix(f"cache {path}: "))


def _tree(folder: Path) -> dict[str, list]:
    """{relative path: [size, SHA-256]} of the regular files under ``folder`` (the manifest left out);
    ValueError for a symbolic link or anything but a file or a folder."""
    out: dict[str, list] = {}
    for dirpath, dirnames, filenames in os.walk(folder, followlinks=False):
        for name in [*dirnames, *filenames]:
            full = Path(dirpath) / name
            st = os.lstat(full)
            rel = full.relative_to(folder).as_posix()
            if stat.S_ISDIR(st.st_mode):
                continue
            if not stat.S_ISREG(st.st_mode):
                raise ValueError(f"{rel} is not a regular file")
            if rel != MANIFEST:
                out[rel] = [st.st_size, file_sha256(full)]
    return out


def write_manifest(folder: str | os.PathLike[str], source: str = "") -> None:
    """Write the content manifest of an entry made in ``folder`` (``source``: e.g. the archive's SHA-256)."""
    folder = Path(folder)
    data = {"source": source, "files": _tree(folder)}
    (folder / MANIFEST).write_text(json.dumps(data, sort_keys=True), encoding="utf-8")


def manifest_problem(folder: str | os.PathLike[str], source: str = "") -> str | None:
    """Why an entry does not hold what its manifest says (missing, changed, extra or non-regular files, another
    ``source``), or None."""
    folder = Path(folder)
    problem = folder_problem(folder) if folder.is_symlink() else None
    if problem is not None:
        return problem
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
        files = data["files"]
        if data.get("source", "") != source:
            return f"made from {str(data.get('source'))[:20]}..., not from {source[:20]}..."
        found = _tree(folder)
    except FileNotFoundError:
        return "has no manifest"
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return f"cannot be verified ({exc})"
    if found != files:
        changed = sorted(set(found) ^ set(files)) or sorted(k for k in found if found[k] != files.get(k))
        return f"does not match its manifest ({', '.join(changed[:3])}{' ...' if len(changed) > 3 else ''})"
    return None


def remove_entry(path: str | os.PathLike[str]) -> None:
    """Remove a cache entry (a folder, a file or a link) without following a link; renamed aside first so that
    no concurrent reader sees half of it."""
    path = Path(path)
    aside = path.with_name(f".{path.name}.removed.{os.getpid()}")
    try:
        os.rename(path, aside)
    except FileNotFoundError:
        return
    except OSError:
        aside = path
    if aside.is_dir() and not aside.is_symlink():
        shutil.rmtree(aside, ignore_errors=True)
    else:
        aside.unlink(missing_ok=True)
