"""What the command-line tools share: exit codes, one-line errors, crash logs (see :mod:`mre_common.guard`).

:func:`run_tool` runs a tool's work with the engine's configuration errors
(``ScenarioError``, an unusable or taken run folder) reported as exit code 2, Ctrl-C
before anything is written as 130 and any unexpected error as a bug (exit code 3, the
traceback in a log file whose path is printed), and prints the units' warnings while a
run goes (:func:`show_unit_messages`), as every tool always has. Imports only the standard
library at start-up; the engine's error types are imported when an error needs classifying.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import textwrap
from collections.abc import Callable, Iterator

from mre_common.guard import (
    EPILOG_COMMON,
    EXIT_BUG,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    ErrorTypes,
    UsageError,
    guarded,
    invoked_as,
    quiet_interrupts,
    set_invoked_as,
)

__all__ = ["EPILOG_COMMON", "EXIT_BUG", "EXIT_FAILED", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "UsageError",
           "engine_errors", "invoked_as", "quiet_interrupts", "run_tool", "set_invoked_as", "show_unit_messages",
           "with_epilog"]


def engine_errors() -> ErrorTypes:
    """The engine's user-reachable errors: a scenario that cannot run, a run folder that is taken or unusable,
    an ``MRE_COSIM_*`` environment variable set to something meaningless."""
    from mre_common.env_settings import EnvSettingError
    from orchestration.master.errors import ScenarioError
    from orchestration.master.runfolder import RunFolderExists

    return ScenarioError, RunFolderExists, EnvSettingError


def run_tool(work: Callable[[list[str] | None], int], argv: list[str] | None, prog: str,
             extra_errors: Callable[[], ErrorTypes] | None = None) -> int:
    """``work(argv)`` with every outcome mapped to an exit code (:func:`mre_common.guard.guarded`).

    ``extra_errors`` returns the tool's own user-reachable error types (besides the engine's).
    """
    def errors() -> ErrorTypes:
        return engine_errors() + (extra_errors() if extra_errors is not None else ())

    with show_unit_messages():
        return guarded(work, argv, prog, errors)


class _UnitWarnings(logging.Handler):
    """Each unit warning the engine reports at WARNING level as one line on stderr, above a progress bar."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.addFilter(lambda record: record.levelno == logging.WARNING)

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            tqdm = sys.modules.get("tqdm")  # a progress bar is drawn only when tqdm was imported
            if tqdm is not None:
                tqdm.tqdm.write(text, file=sys.stderr)
            else:
                print(text, file=sys.stderr)
        except Exception:
            self.handleError(record)


@contextlib.contextmanager
def show_unit_messages() -> Iterator[None]:
    """While inside: the units' warnings (``mre_cosim.units``, WARNING level) printed to stderr, one per line.

    The engine prints nothing itself (:func:`orchestration.master.session.run_plan`); the
    command-line tools print a unit's first warnings as they come, above the progress bar.
    """
    logger = logging.getLogger("mre_cosim.units")  # orchestration.master.fmi_status.UNIT_LOGGER (not imported here)
    handler = _UnitWarnings()
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)


def with_epilog(work: Callable[[list[str] | None], int], argv: list[str] | None, epilog: str) -> int:
    """``work(argv)``, printing ``epilog`` (the exit codes) after ``--help`` of a parser that has none."""
    try:
        return work(argv)
    except SystemExit as exc:
        args = sys.argv[1:] if argv is None else argv
        if exc.code in (0, None) and any(a in ("-h", "--help") for a in args):
            print("\n" + textwrap.fill(epilog, 79))
        raise
