"""Shared fixtures: FMUs built once per test session into a temporary folder, record paths."""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parent.parent
if str(PROJECT) not in sys.path:
    sys.path.insert(0, str(PROJECT))

SHARED_RECORDS = PROJECT.parent / "shared" / "ground_motions"

# The native executor's compiled kernel goes to a per-session folder (also for the CLI runs
# the tests start), so the tests need no writable home folder.
if "MRE_COSIM_CACHE" not in os.environ:
    os.environ["MRE_COSIM_CACHE"] = tempfile.mkdtemp(prefix="mre-cosim-cache-")
    atexit.register(shutil.rmtree, os.environ["MRE_COSIM_CACHE"], ignore_errors=True)


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    """All project FMUs, freshly built into a temporary folder."""
    from components.build import ensure_built

    dest = tmp_path_factory.mktemp("fmus")
    ensure_built(dest, force=True)
    return dest


def shared_record(name: str) -> Path:
    """A record of ../shared/ground_motions; the calling test is skipped if it is not there."""
    path = SHARED_RECORDS / name
    if not path.is_file():
        pytest.skip(f"ground-motion record not found: {path}")
    return path


@pytest.fixture(scope="session")
def elcentro() -> Path:
    return shared_record("elcentro_1940_ns.csv")


@pytest.fixture(scope="session")
def kobe() -> Path:
    return shared_record("kobe_1995_jma_ns.csv")
