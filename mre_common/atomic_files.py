"""Atomic file writes: a temporary file in the target's folder, then :func:`os.replace`.

A reader (another process, a later run, a crash) sees the old file or the whole new one,
never half of it; on any error the old file stays and the temporary file is removed.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any


def current_umask() -> int:
    """The process's file-creation mask, read without changing it where the OS allows.

    Linux: from ``/proc/self/status``; elsewhere the classic set-and-restore (which briefly
    sets the mask to 0 for every thread of the process).
    """
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | os.PathLike[str], write_fn: Callable[[IO[Any]], Any], *, binary: bool = False,
                 encoding: str = "utf-8", mode: int | None = None) -> None:
    """Write ``path`` through ``write_fn(file)`` atomically.

    ``write_fn`` gets the temporary file open for writing (bytes if ``binary``, else text in
    ``encoding`` without newline translation). ``mode``: the file's permission bits
    (default ``0o666`` less the umask, as a plain ``open`` would give). The temporary file
    is ``.<name>.<random>.tmp`` in the same folder; it is removed on any error (also
    KeyboardInterrupt), and ``path`` then keeps its old content.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with (os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding=encoding, newline="")) as f:
            write_fn(f)
        os.chmod(tmp, (0o666 & ~current_umask()) if mode is None else mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, mode: int | None = None) -> None:
    """Write bytes atomically (see :func:`atomic_write`)."""
    atomic_write(path, lambda f: f.write(data), binary=True, mode=mode)


def atomic_write_text(path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8",
                      mode: int | None = None) -> None:
    """Write text atomically, newlines as given (see :func:`atomic_write`)."""
    atomic_write(path, lambda f: f.write(text), encoding=encoding, mode=mode)
