"""Claim an output folder by creating a marker file in it exclusively (``O_CREAT | O_EXCL``).

Of two processes claiming the same folder exactly one succeeds (the file system decides);
the marker holds a small JSON record (tool, pid, time, ...) that later says who wrote the folder.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any


def claim_folder(folder: str | os.PathLike[str], marker: str, info: Mapping[str, Any]) -> Path:
    """Create ``folder/marker`` exclusively and write ``info`` into it as JSON; the marker's path.

    Raises FileExistsError if the marker exists already (another claimant has the folder),
    another OSError if it cannot be created or written; after a failed write the marker is
    removed again, so the folder is left unclaimed.
    """
    path = Path(folder) / marker
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(dict(info), f)
    except BaseException:
        path.unlink(missing_ok=True)
        raise
    return path


def read_claim(folder: str | os.PathLike[str], marker: str) -> dict[str, Any] | None:
    """The JSON record of a folder's marker, or None (absent, unreadable or not a JSON object)."""
    try:
        data = json.loads((Path(folder) / marker).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None
