"""Run folders: never overwritten, every file written atomically (temporary file, then rename)."""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Sequence
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np


class RunFolderExists(FileExistsError):
    """The chosen output folder exists and is not empty."""


def new_run_folder(base: Path, name: str, explicit: Path | None = None) -> Path:
    """Create and return a fresh run folder.

    With ``explicit`` (``--out``), that folder is used if it does not exist or is empty;
    otherwise ``base/<name>-<UTC timestamp>`` with a numeric suffix if taken.
    """
    if explicit is not None:
        explicit = Path(explicit)
        if explicit.exists() and (not explicit.is_dir() or any(explicit.iterdir())):
            raise RunFolderExists(f"{explicit} exists and is not empty: choose another --out (nothing was written)")
        explicit.mkdir(parents=True, exist_ok=True)
        return explicit
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    base.mkdir(parents=True, exist_ok=True)
    for k in range(1000):
        folder = base / (f"{name}-{stamp}" if k == 0 else f"{name}-{stamp}-{k}")
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        return folder
    raise RunFolderExists(f"no free run folder name under {base}")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _atomic(path: Path, write) -> None:
    """Write through a temporary file in the same folder, then rename: a file is whole or absent."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", newline="") as f:
            write(f)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json(path: Path, data: Any) -> None:
    """Write JSON atomically."""
    _atomic(path, lambda f: json.dump(data, f, indent=2, default=str))


def write_text(path: Path, text: str) -> None:
    """Write text atomically."""
    _atomic(path, lambda f: f.write(text))


def write_timeseries(path: Path, time: np.ndarray, names: Sequence[str], data: np.ndarray) -> None:
    """CSV with a ``time`` column first, then one column per variable (12 significant digits)."""
    row = ",".join(["%.12g"] * (len(names) + 1)) + "\n"

    def write(f):
        f.write(",".join(["time", *names]) + "\n")
        block = np.column_stack([time, data]).tolist()
        for start in range(0, len(block), 20000):
            f.write("".join(row % tuple(r) for r in block[start : start + 20000]))

    _atomic(path, write)


def sha256(path: Path) -> str:
    """SHA-256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def package_versions(names: Sequence[str] = ("fmpy", "pythonfmu", "numpy", "scipy", "matplotlib", "pydantic",
                                             "PyYAML")) -> dict[str, str]:
    """Installed versions of the packages a run depends on."""
    out = {}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out
