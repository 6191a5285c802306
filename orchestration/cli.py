"""What the command-line tools share: exit codes, one-line errors, crash logs (see :mod:`components.cli`).

:func:`run_tool` runs a tool's work with the engine's configuration errors
(``ScenarioError``, an unusable or taken run folder) reported as exit code 2, Ctrl-C
before anything is written as 130 and any unexpected error as a bug (exit code 3, the
traceback in a log file whose path is printed). Imports only the standard library at
start-up; the engine's error types are imported when an error needs classifying.
"""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Callable

from components.cli import (
    EPILOG_COMMON,
    EXIT_BUG,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    ErrorTypes,
    UsageError,
    guarded,
    quiet_interrupts,
)

__all__ = ["EPILOG_COMMON", "EXIT_BUG", "EXIT_FAILED", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "UsageError",
           "engine_errors", "quiet_interrupts", "run_tool", "with_epilog"]


def engine_errors() -> ErrorTypes:
    """The engine's user-reachable errors: a scenario that cannot run, a run folder that is taken or unusable."""
    from orchestration.master.errors import ScenarioError
    from orchestration.master.runfolder import RunFolderExists

    return ScenarioError, RunFolderExists


def run_tool(work: Callable[[list[str] | None], int], argv: list[str] | None, prog: str,
             extra_errors: Callable[[], ErrorTypes] | None = None) -> int:
    """``work(argv)`` with every outcome mapped to an exit code (:func:`components.cli.guarded`).

    ``extra_errors`` returns the tool's own user-reachable error types (besides the engine's).
    """
    def errors() -> ErrorTypes:
        return engine_errors() + (extra_errors() if extra_errors is not None else ())

    return guarded(work, argv, prog, errors)


def with_epilog(work: Callable[[list[str] | None], int], argv: list[str] | None, epilog: str) -> int:
    """``work(argv)``, printing ``epilog`` (the exit codes) after ``--help`` of a parser that has none."""
    try:
        return work(argv)
    except SystemExit as exc:
        args = sys.argv[1:] if argv is None else argv
        if exc.code in (0, None) and any(a in ("-h", "--help") for a in args):
            print("\n" + textwrap.fill(epilog, 79))
        raise
