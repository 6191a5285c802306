"""A small tool's files: an input it reads, and the new output folder it writes (``compare``, ``verdict``).

Each problem is a :class:`~mre_common.guard.UsageError` (exit 2) naming the path, raised before anything is
written. :func:`write_new_folder` creates the output folder and, if writing fails, removes exactly the files
the tool wrote (and the folder if it made it), so that a folder is either complete or not there.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable
from pathlib import Path

from mre_common.fs_limits import path_problem, writable_problem
from mre_common.guard import UsageError

RESERVE = 64  # [bytes] the longest name a tool writes inside its output folder, with a temporary suffix


def input_problem(path: Path, kind: str = "file") -> str | None:
    """Why ``path`` cannot be read as a ``kind`` ("file" or "folder"): a name beyond the file system's limits,
    missing, or the other kind (a device or a pipe is neither), or None."""
    problem = path_problem(path)
    if problem:
        return problem
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        return f"{path}: {exc.strerror or exc}"
    if kind == "folder":
        return None if stat.S_ISDIR(mode) else f"{path} is not a folder"
    if stat.S_ISDIR(mode):
        return f"{path} is a folder, not a file"
    return None if stat.S_ISREG(mode) else f"{path} is not a regular file"


def check_input(path: Path, kind: str = "file") -> None:
    """:func:`input_problem` as a UsageError."""
    problem = input_problem(path, kind)
    if problem:
        raise UsageError(problem)


def check_output_folder(out: Path) -> None:
    """UsageError unless ``out`` can be a new output folder: names within limits, creatable, and absent or an
    empty folder (a folder with anything in it is the user's: nothing is written into it)."""
    problem = path_problem(out, RESERVE) or writable_problem(out)
    if problem:
        raise UsageError(f"--out {problem}; nothing written")
    try:
        taken = (out.exists() or out.is_symlink()) and (not out.is_dir() or out.is_symlink() or any(out.iterdir()))
    except OSError as exc:
        raise UsageError(f"--out {out}: {exc.strerror or exc}; nothing written") from None
    if taken:
        raise UsageError(f"--out {out}: exists and is not an empty folder; nothing written")


def write_new_folder(out: Path, write: Callable[[Path, list[Path]], None]) -> list[Path]:
    """Create ``out`` (checked by :func:`check_output_folder`) and call ``write(out, written)``, which appends each
    file to ``written`` as soon as it exists; on any failure those files, and ``out`` if this call made it and it
    is empty again, are removed and the error goes on. Returns the files written."""
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        write(out, written)
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
    return written
