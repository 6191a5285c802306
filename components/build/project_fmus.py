"""Every FMU the project builds: build all of them, or one on demand before a run.

``python -m components.build [--dest FOLDER] [--force] [--storeys N ...]`` builds all FMUs;
:func:`ensure_fmu` is the hook the command-line tools give the master, so that a scenario
naming one of the project's FMUs in ``fmus/`` gets it built when it is missing or stale.
The folder is :func:`mre_common.project_paths.fmu_dir`: the checkout's ``fmus/`` when it is
writable, else (an installed package) ``fmus/<version>`` in the per-user cache folder
(``$MRE_COSIM_CACHE``, default ``~/.cache/mre-cosim``).
Exit codes of the command: 0 built (or up to date); 1 a build failed (e.g. no C
compiler); 2 bad arguments or an unusable ``--dest`` (nothing written); 3 internal error
(a bug; the traceback is in the log file named); 130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from components.build.c_isolator import ensure_c_isolator, is_c_isolator
from components.build.model_description import DEFAULT_FMU_DIR, BuildError
from components.build.pythonfmu_units import build, discover, is_stale, known_fmu
from mre_common.guard import EPILOG_COMMON, EXIT_FAILED, EXIT_OK, UsageError, guarded

EPILOG = ("exit codes: 0 built or up to date; 1 a build failed (e.g. no C compiler); 2 bad arguments or an "
          "unusable --dest (nothing written); " + EPILOG_COMMON)
MAX_STOREYS = 100


def ensure_built(dest: Path = DEFAULT_FMU_DIR, force: bool = False, storeys: tuple[int, ...] = ()) -> list[Path]:
    """Build every FMU that is missing or older than its sources; returns all FMU paths."""
    paths = []
    for source in discover(storeys):
        fmu = dest / source.fmu_name
        if force or is_stale(source, fmu):
            build(source, dest)
        paths.append(fmu)
    paths.append(ensure_c_isolator(dest, force))
    return paths


def ensure_fmu(path: Path) -> str | None:
    """Build the FMU if the project builds it and it is missing or stale; returns a problem text or None."""
    path = Path(path)
    if is_c_isolator(path):
        try:
            ensure_c_isolator(path.parent)
        except BuildError as exc:
            return f"cannot build {path.name}: {exc}"
        return None
    source = known_fmu(path)
    if source is None:
        return None if path.is_file() else f"FMU file {path} does not exist"
    if is_stale(source, path):
        try:
            build(source, path.parent)
        except BuildError as exc:
            return f"cannot build {path.name}: {exc}"
    return None


def _usable_dest(dest: Path) -> None:
    """UsageError unless ``dest`` is (or can become) a writable folder; creates nothing."""
    for folder in (dest, *dest.parents):
        if folder.exists():
            if not folder.is_dir():
                raise UsageError(f"--dest {dest}: {folder} is a file, not a folder (nothing written)")
            if not os.access(folder, os.W_OK | os.X_OK):
                raise UsageError(f"--dest {dest}: {folder} is not writable (nothing written)")
            return


def _build(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(prog="python -m components.build",
                                     description=f"Build the project's FMUs into {DEFAULT_FMU_DIR}.", epilog=EPILOG)
    parser.add_argument("--dest", type=Path, default=DEFAULT_FMU_DIR, help=f"output folder (default {DEFAULT_FMU_DIR})")
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    parser.add_argument(
        "--storeys", type=int, nargs="*", default=[],
        help="also build building variants (ShearBuilding, OpenSeesBuilding) with N storeys",
    )
    args = parser.parse_args(argv)
    bad = [n for n in args.storeys if not 1 <= n <= MAX_STOREYS]
    if bad:
        parser.error(f"--storeys: each N must be between 1 and {MAX_STOREYS}, got {bad}")
    _usable_dest(args.dest)
    try:
        paths = ensure_built(args.dest, args.force, tuple(args.storeys))
    except BuildError as exc:
        print(f"error: build failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except OSError as exc:
        where = exc.filename or args.dest
        raise UsageError(f"--dest {args.dest}: cannot write {where}: {exc.strerror or exc}") from None
    for path in paths:
        print(path)
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """``python -m components.build``; returns the exit code."""
    return guarded(_build, argv, "python -m components.build")

