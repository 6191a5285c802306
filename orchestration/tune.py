"""Tune the SOSM gains of a study: ``python orchestration/tune.py scenarios/case_study.yaml --force``.

Writes the study's gains file (``scenarios/sosm_gains.yaml``); see
:mod:`orchestration.case_study.tuning`. A study file with a ``strategy_tuning:`` section instead tunes the
strategies it lists alike and writes their tuned entries as a strategy file
(:mod:`orchestration.case_study.strategy_tuner`). Exit codes: 0 written; 1 no finite objective (nothing
written); 2 configuration error or the
gains file exists without ``--force`` (nothing written); 3 internal error (a bug; the
traceback is in the log file named); 130 interrupted (nothing written).
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

EPILOG = ("exit codes: 0 gains file written; 1 the tuning found no finite objective (nothing written); "
          "2 configuration error, or the gains file exists without --force "
          "(nothing written); " + EPILOG_COMMON)


def _tune(argv: list[str] | None) -> int:
    from orchestration.case_study.strategy_tuner import declares_tuning
    from orchestration.case_study.strategy_tuner import main as strategies_main
    from orchestration.case_study.tuning import main as tune_main

    return with_epilog(strategies_main if declares_tuning(argv) else tune_main, argv, EPILOG)


def _errors() -> tuple[type[BaseException], ...]:
    from orchestration.building_studies.in_process_model import NotMonolithic

    return NotMonolithic, OSError  # the gains file is written atomically: a failed write leaves nothing


def main(argv: list[str] | None = None) -> int:
    """Tune the gains from the command line; returns the exit code."""
    return run_tool(_tune, argv, "tune.py", _errors)


if __name__ == "__main__":
    raise SystemExit(main())
