"""Shared fixtures: FMUs built once per test session into a temporary folder, record paths."""

from __future__ import annotations

import atexit
import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parent.parent
if str(PROJECT) not in sys.path:
    sys.path.insert(0, str(PROJECT))

RECORDS = PROJECT / "scenarios" / "records"  # the records the project ships

# The native executor's compiled kernel goes to a per-session folder (also for the CLI runs
# the tests start), so the tests need no writable home folder.
if "MRE_COSIM_CACHE" not in os.environ:
    os.environ["MRE_COSIM_CACHE"] = tempfile.mkdtemp(prefix="mre-cosim-cache-")
    atexit.register(shutil.rmtree, os.environ["MRE_COSIM_CACHE"], ignore_errors=True)


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    """All project FMUs, freshly built into a temporary folder."""
    from components.build.project_fmus import ensure_built

    dest = tmp_path_factory.mktemp("fmus")
    ensure_built(dest, force=True)
    return dest


def shipped_record(name: str) -> Path:
    """A record the project ships in scenarios/records (a missing one fails the test: it is part of the repository)."""
    path = RECORDS / name
    assert path.is_file(), f"ground-motion record missing from the repository: {path}"
    return path


@pytest.fixture(scope="session")
def elcentro() -> Path:
    return shipped_record("elcentro_1940_ns.csv")


@pytest.fixture(scope="session")
def kobe() -> Path:
    return shipped_record("kobe_1995_jma_ns.csv")


@pytest.fixture(autouse=True)
def _signals_not_ignored():  # every test: the Ctrl-C tests of several files need it
    """SIGINT and SIGTERM handled, not ignored, while a test runs: a runner started in the background
    (`cmd &`) ignores SIGINT, and the tools started by a Ctrl-C test would inherit that."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig, handler in saved.items():
        if handler is signal.SIG_IGN:
            signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL)
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)
