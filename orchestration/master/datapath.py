"""The data-directory search path for files a scenario names with a data tag (``!record``).

Order: the ``--data-dir`` option(s), then the folders in the environment variable
``MRE_COSIM_DATA`` (``os.pathsep``-separated), then the application's default folders
(the project's shipped records), and last the scenario file's own folder. Absolute paths
are used as they are.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Sequence
from pathlib import Path

ENV_VAR = "MRE_COSIM_DATA"


def search_path(data_dirs: Sequence[Path] = (), defaults: Sequence[Path] = ()) -> list[Path]:
    """Folders searched for data files, in order."""
    folders = [Path(d) for d in data_dirs]
    env = os.environ.get(ENV_VAR, "")
    folders += [Path(p) for p in env.split(os.pathsep) if p]
    folders += [Path(d) for d in defaults]
    return folders


def find_data_file(
    name: str,
    data_dirs: Sequence[Path] = (),
    relative_to: Path | None = None,
    defaults: Sequence[Path] = (),
) -> Path:
    """Absolute path of a data file (the first regular file on the search path).

    FileNotFoundError lists every place searched, or says what the paths found are when none is
    a regular file (a folder, a FIFO, a device); PermissionError when the file cannot be read.
    """
    candidate = Path(name).expanduser()
    tried: list[Path] = []
    if candidate.is_absolute():
        tried.append(candidate)
    else:
        tried += [folder / candidate for folder in search_path(data_dirs, defaults)]
        if relative_to is not None:
            tried.append(relative_to / candidate)
    others: list[str] = []
    for path in tried:
        try:
            info = path.stat()  # never opens it: a FIFO does not block
        except (OSError, ValueError):
            continue
        if not stat.S_ISREG(info.st_mode):
            others.append(f"{path} is {file_kind(info.st_mode)}")
            continue
        if not os.access(path, os.R_OK):
            raise PermissionError(f"data file {name!r}: {path} is not readable (permission denied)")
        try:
            return path.resolve()
        except (RuntimeError, OSError):
            return Path(os.path.abspath(path))
    if others:
        raise FileNotFoundError(f"data file {name!r} is not a regular file: {'; '.join(others)}")
    listing = "; ".join(str(p) for p in tried)
    raise FileNotFoundError(
        f"data file {name!r} not found (searched: {listing}). "
        f"Give a folder with --data-dir or the {ENV_VAR} environment variable."
    )


def file_kind(mode: int) -> str:
    """What a file that is not a regular one is, from its ``st_mode``: 'a folder', 'a FIFO', ..."""
    kinds = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
             (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    return next((text for test, text in kinds if test(mode)), "not a regular file")
