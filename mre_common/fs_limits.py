"""Names and paths measured the way the file system measures them: in bytes, against its own limits.

A name of 100 emoji is 100 characters but 400 bytes of UTF-8; Linux file systems allow 255
bytes per name (``NAME_MAX``) and 4096 per path (``PATH_MAX``). The limits are asked of the
file system that will hold the file (:func:`os.pathconf` on the nearest existing folder), with
the POSIX defaults where it cannot say. Each check returns a one-line problem or None.
"""

from __future__ import annotations

import os
from pathlib import Path

DEFAULT_NAME_MAX = 255  # bytes (Linux, most file systems)
DEFAULT_PATH_MAX = 4096  # bytes (Linux)


def _existing(folder: Path) -> Path:
    """The nearest existing ancestor of ``folder`` (itself if it exists)."""
    folder = Path(os.path.abspath(folder))
    while not os.path.exists(folder) and folder != folder.parent:  # False for a name beyond the limits
        folder = folder.parent
    return folder


def _limit(folder: Path, which: str, default: int) -> int:
    try:
        value = os.pathconf(_existing(folder), which)
    except (OSError, ValueError, AttributeError):  # not supported here (or not a POSIX system)
        return default
    return value if isinstance(value, int) and value > 0 else default


def name_max(folder: str | os.PathLike[str]) -> int:
    """Longest name [bytes] of an entry of ``folder`` on its file system."""
    return _limit(Path(folder), "PC_NAME_MAX", DEFAULT_NAME_MAX)


def path_max(folder: str | os.PathLike[str]) -> int:
    """Longest path [bytes] on the file system of ``folder``."""
    return _limit(Path(folder), "PC_PATH_MAX", DEFAULT_PATH_MAX)


def encoded_length(text: str) -> int:
    """Length [bytes] of a name as the file system stores it (UTF-8, undecodable bytes as they were)."""
    return len(os.fsencode(text))


def name_problem(name: str, folder: str | os.PathLike[str], reserve: int = 0) -> str | None:
    """Why ``name`` (plus ``reserve`` bytes added to it later, e.g. a time stamp) cannot name an entry of
    ``folder``, or None."""
    try:
        size = encoded_length(name)
    except UnicodeError:
        return f"{name!r} cannot be encoded for the file system"
    limit = name_max(folder)
    if size + reserve > limit:
        extra = f" (+{reserve} for the suffix added to it)" if reserve else ""
        return (f"name {name[:40]!r}{'...' if len(name) > 40 else ''} is {size} bytes{extra}: the file system "
                f"allows {limit} bytes per name ({len(name)} characters; a non-ASCII character takes 2-4 bytes)")
    return None


def path_problem(path: str | os.PathLike[str], reserve: int = 0) -> str | None:
    """Why ``path`` (and names of up to ``reserve`` bytes made inside it later) is beyond the file system's
    limits (any component longer than NAME_MAX, the whole longer than PATH_MAX), or None."""
    absolute = Path(os.path.abspath(path))
    try:
        parts = [encoded_length(p) for p in absolute.parts]
        total = encoded_length(str(absolute))
    except UnicodeError:
        return f"{str(path)[:80]!r} cannot be encoded for the file system"
    limit = name_max(absolute.parent)
    for part, size in zip(absolute.parts, parts, strict=True):
        if size > limit:
            return (f"{str(path)[:80]!r}: the component {part[:40]!r}... is {size} bytes; the file system allows "
                    f"{limit} bytes per name")
    longest = path_max(absolute.parent)
    if total + reserve >= longest:
        return (f"{str(path)[:80]!r}... is {total} bytes long{f' (+{reserve} for files inside)' if reserve else ''}; "
                f"the file system allows {longest - 1} bytes per path")
    return None


def writable_problem(path: str | os.PathLike[str]) -> str | None:
    """Why a file or folder at ``path`` cannot be created (an ancestor is not a folder, or the nearest existing
    folder is not writable), or None. Checked before any work, so that it is not lost at the end."""
    parent = Path(os.path.abspath(path)).parent
    existing = _existing(parent)
    if not existing.is_dir():
        return f"{str(path)[:80]!r} is below {str(existing)[:80]!r}, which is not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{str(path)[:80]!r} cannot be created: the folder {str(existing)[:80]!r} is not writable"
    return None


def plain_name_problem(name: object) -> str | None:
    """Why ``name`` cannot be one entry of a folder (a separator, NUL, ``.``/``..``, a leading dot, empty), or
    None. Its length is :func:`name_problem`'s."""
    if not isinstance(name, str) or not name:
        return f"{name!r} is not a name"
    if any(c in name for c in "/\\\x00") or name.startswith(".") or any(ord(c) < 32 for c in name):
        return (f"{name[:60]!r} must be a plain name (no '/', '\\', control characters, not starting with '.'): "
                "it names a folder")
    return None
