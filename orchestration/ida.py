"""Incremental dynamic analysis and fragility: ``python orchestration/ida.py scenarios/ida.yaml``.

Each record component of a suite, scaled to each intensity level, for each strategy, on
the Dask batch pool; see :mod:`orchestration.ida_study.ida_run` for the study folder it writes.
Exit codes: 0 every run ended; 1 some runs failed or were lost, or the study was
interrupted (the report lists them); 2 configuration error or unreachable scheduler
(nothing computed, nothing written); 3 internal error (a bug; the traceback is in the log
file named); 130 interrupted before the study started (nothing written).
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mre_common.guard import quiet_interrupts  # standard library only: installed before any other import

if __name__ == "__main__":
    quiet_interrupts()  # Ctrl-C or SIGTERM while starting: one line, exit 130, no traceback

from orchestration.cli import EPILOG_COMMON, run_tool, with_epilog

EPILOG = ("exit codes: 0 every run ended; 1 some runs failed or were lost, or the study was interrupted (the "
          "report lists them); 2 configuration error or unreachable scheduler (nothing written); " + EPILOG_COMMON)


def _ida(argv: list[str] | None) -> int:
    from orchestration.ida_study.ida_run import main as ida_main

    return with_epilog(ida_main, argv, EPILOG)


def main(argv: list[str] | None = None) -> int:
    """Run an IDA study from the command line; returns the exit code."""
    return run_tool(_ida, argv, "ida.py")


if __name__ == "__main__":
    raise SystemExit(main())
