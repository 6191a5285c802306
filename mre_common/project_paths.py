"""Where the project's code, shipped scenarios and built FMUs are: in a source checkout and when installed.

One place for the locations every layer needs (``components`` may not import ``orchestration``):

* :data:`CODE_DIR` (also :data:`PROJECT_DIR`): the folder holding the packages ``components``,
  ``orchestration`` and ``mre_common``: the checkout's top level, or ``site-packages`` when installed.
* :data:`SOURCE_TREE`: True in a checkout (``pyproject.toml`` and ``scenarios/`` beside the packages),
  as with ``pip install -e .`` or ``python orchestration/run.py``.
* :data:`DATA_DIR`: the folder holding ``scenarios/`` (records, plants, structures): the checkout's
  top level, else the copy ``pip install .`` puts in ``<prefix>/share/mre-cosim`` (the
  ``[tool.setuptools.data-files]`` of ``pyproject.toml``); :data:`SCENARIOS_DIR` and
  :data:`RECORDS_DIR` are in it.
* :data:`SCENARIO_FMU_DIR`: the folder the shipped scenarios name their FMUs in (``../fmus/`` from
  ``scenarios/``). :func:`fmu_dir` is where those FMUs are built: that same folder in a writable
  checkout, else a per-user cache folder, ``$MRE_COSIM_CACHE/fmus/<version>`` (default
  ``~/.cache/mre-cosim/fmus/<version>``); :func:`build_location` maps a scenario's FMU path there.

Standard library only (and :mod:`mre_common.c_compile` for the cache folder's name).
"""

from __future__ import annotations

import os
import subprocess
from functools import lru_cache
from importlib import metadata
from pathlib import Path

DISTRIBUTION = "mre-cosim"
"""The distribution name (``pip install .`` installs it; :func:`package_version` reads its metadata)."""

CODE_DIR = Path(__file__).resolve().parent.parent
PROJECT_DIR = CODE_DIR  # the name the modules used before; a checkout's top level or site-packages
SOURCE_TREE = (CODE_DIR / "pyproject.toml").is_file() and (CODE_DIR / "scenarios").is_dir()
SHARE_SUBDIR = ("share", "mre-cosim")  # where [tool.setuptools.data-files] puts scenarios/ under the prefix


def _installed_data_dir() -> Path | None:
    """``<prefix>/share/mre-cosim`` of the installed distribution (found through its file list, so a
    ``--user`` or ``--prefix`` install is found too), or None if not installed with its data."""
    try:
        files = metadata.distribution(DISTRIBUTION).files or []
    except metadata.PackageNotFoundError:
        return None
    for entry in files:
        parts = entry.parts
        for i in range(len(parts) - 2):
            if parts[i:i + 3] == (*SHARE_SUBDIR, "scenarios"):
                located = Path(str(metadata.distribution(DISTRIBUTION).locate_file(Path(*parts[:i + 2]))))
                if (located / "scenarios").is_dir():
                    return located.resolve()
    return None


DATA_DIR = CODE_DIR if SOURCE_TREE else (_installed_data_dir() or CODE_DIR)
SCENARIOS_DIR = DATA_DIR / "scenarios"
RECORDS_DIR = SCENARIOS_DIR / "records"
SCENARIO_FMU_DIR = DATA_DIR / "fmus"


def package_version() -> str:
    """The installed distribution's version (``importlib.metadata``), ``unknown`` if it is not installed."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "unknown"


def _writable(folder: Path) -> bool:
    """Whether ``folder`` is, or can be made as, a writable folder (the first existing ancestor decides)."""
    for candidate in (folder, *folder.parents):
        if candidate.exists():
            return candidate.is_dir() and os.access(candidate, os.W_OK | os.X_OK)
    return False


def cache_fmu_dir() -> Path:
    """The per-user FMU folder: ``<cache>/fmus/<version>`` (cache: :func:`mre_common.c_compile.cache_dir`)."""
    from mre_common.c_compile import cache_dir

    return cache_dir() / "fmus" / package_version()


@lru_cache(maxsize=1)
def fmu_dir() -> Path:
    """Where the project's FMUs are built: the checkout's ``fmus/`` when it is writable, else the cache folder.

    An installed package never writes into its own installation (the per-user cache instead), so
    ``pip uninstall`` leaves nothing behind there and a read-only installation works.
    """
    if SOURCE_TREE and _writable(SCENARIO_FMU_DIR):
        return SCENARIO_FMU_DIR
    try:
        return cache_fmu_dir()
    except OSError:  # no cache folder can be named (no home folder, no $MRE_COSIM_CACHE): a build says so
        return SCENARIO_FMU_DIR


def build_location(path: Path) -> Path:
    """Where a scenario's FMU path is built and read: a file in :data:`SCENARIO_FMU_DIR` is the file of the same
    name in :func:`fmu_dir`; any other path is itself."""
    path = Path(path)
    target = fmu_dir()
    if target == SCENARIO_FMU_DIR or Path(os.path.abspath(path)).parent != Path(os.path.abspath(SCENARIO_FMU_DIR)):
        return path
    return target / path.name


def shipped_scenario(name: str) -> Path | None:
    """The shipped scenario named ``name`` (``kobe`` is ``scenarios/kobe.yaml``), or None.

    Only a bare name (no folder, no suffix) that is no file in the current folder is looked up, so
    neither a file of the user's nor a mistyped path of theirs ever runs a shipped file instead.
    """
    if not name or "\0" in name or os.sep in name or "/" in name or Path(name).suffix:
        return None
    try:
        if os.path.lexists(name):
            return None
    except (OSError, ValueError):
        return None
    path = SCENARIOS_DIR / f"{name}.yaml"
    return path if path.is_file() else None


def shipped_scenarios() -> list[str]:
    """The names of the shipped scenario files (``mre-cosim run NAME`` runs one)."""
    return sorted(p.stem for p in SCENARIOS_DIR.glob("*.yaml")) if SCENARIOS_DIR.is_dir() else []


def git(*args: str) -> str | None:
    """``git ARGS`` run in the checkout (its stdout, stripped), or None when it fails or this is no checkout."""
    if not SOURCE_TREE:
        return None
    try:
        done = subprocess.run(["git", *args], cwd=CODE_DIR, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


if __name__ == "__main__":  # python -m mre_common.project_paths: where things are
    print(f"code:      {CODE_DIR}{' (source checkout)' if SOURCE_TREE else ''}")
    print(f"scenarios: {SCENARIOS_DIR}")
    print(f"FMUs:      {fmu_dir()}")
    print(f"shipped:   {' '.join(shipped_scenarios())}")
