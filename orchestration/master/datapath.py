"""The data-directory search path for files a scenario names with a data tag (``!record``).

Order: the ``--data-dir`` option(s), then the folders in the environment variable
``MRE_COSIM_DATA`` (``os.pathsep``-separated), then the application's default folders
(the project's shipped records), and last the scenario file's own folder. Absolute paths
are used as they are.
"""

from __future__ import annotations

import os
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
    """Absolute path of a data file; FileNotFoundError lists every place searched."""
    candidate = Path(name).expanduser()
    tried: list[Path] = []
    if candidate.is_absolute():
        tried.append(candidate)
    else:
        tried += [folder / candidate for folder in search_path(data_dirs, defaults)]
        if relative_to is not None:
            tried.append(relative_to / candidate)
    for path in tried:
        if path.is_file():
            try:
                return path.resolve()
            except (RuntimeError, OSError):
                return Path(os.path.abspath(path))
    listing = "; ".join(str(p) for p in tried)
    raise FileNotFoundError(
        f"data file {name!r} not found (searched: {listing}). "
        f"Give a folder with --data-dir or the {ENV_VAR} environment variable."
    )
