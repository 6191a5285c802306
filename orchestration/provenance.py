"""What made a result: this package's version and the source revision it ran from.

Written into every run's ``manifest.json`` (through the resolve hooks of
:mod:`orchestration.engine_hooks`) and into a study's ``study.json``.
"""

from __future__ import annotations

import subprocess
import tomllib
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

PROJECT_DIR = Path(__file__).resolve().parent.parent
PACKAGE = "mre-cosim"


def _git(*args: str) -> str | None:
    try:
        done = subprocess.run(["git", *args], cwd=PROJECT_DIR, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def package_version() -> str:
    """The version in ``pyproject.toml`` (the source that runs), else the installed distribution's."""
    try:
        with open(PROJECT_DIR / "pyproject.toml", "rb") as fh:
            return str(tomllib.load(fh)["project"]["version"])
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        pass
    try:
        return metadata.version(PACKAGE)
    except metadata.PackageNotFoundError:
        return "unknown"


@lru_cache(maxsize=1)
def provenance() -> dict[str, Any]:
    """Package name and version, git commit of the source and whether its code differs from that commit.

    ``commit`` is None outside a git checkout (an unpacked archive); ``dirty`` is None then.
    Only ``components/``, ``orchestration/``, ``scenarios/`` and ``pyproject.toml`` count for
    ``dirty``: run folders and notes in the checkout do not change a result.
    """
    commit = _git("rev-parse", "HEAD")
    status = _git("status", "--porcelain", "--", "components", "orchestration", "scenarios", "pyproject.toml")
    return {"package": PACKAGE, "version": package_version(), "commit": commit,
            "dirty": None if commit is None or status is None else bool(status)}
