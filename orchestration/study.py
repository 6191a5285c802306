"""Run a case study: ``python orchestration/study.py scenarios/case_study.yaml``.

Records x strategies, each a co-simulation through the master; see
:mod:`orchestration.case_study.case_run` for the study folder it writes. Exit codes: 0
every job succeeded; 1 some jobs failed or the study was interrupted (the report lists
them); 2 configuration error (nothing written); 3 internal error (a bug; the traceback is
in the log file named); 130 interrupted before the study started (nothing written).
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

EPILOG = ("exit codes: 0 every job succeeded; 1 some jobs failed or the study was interrupted (the report lists "
          "them); 2 configuration error (nothing written); " + EPILOG_COMMON)


def _study(argv: list[str] | None) -> int:
    from orchestration.building_studies.study_file import declares_section
    from orchestration.case_study.case_run import main as study_main
    from orchestration.ida_study.ida_config import BENCHMARK_KEY

    args = sys.argv[1:] if argv is None else argv
    if declares_section(args, BENCHMARK_KEY) and declares_section(args, "suite"):  # a suite benchmark (an IDA
        # file with benchmark:; a case study's benchmark: section has records, no suite)
        from orchestration.suite_benchmark.benchmark_run import main as benchmark_main

        return with_epilog(benchmark_main, argv, EPILOG)
    return with_epilog(study_main, argv, EPILOG)


def _errors() -> tuple[type[BaseException], ...]:
    from orchestration.building_studies.in_process_model import NotMonolithic

    return (NotMonolithic,)


def main(argv: list[str] | None = None) -> int:
    """Run a case study from the command line; returns the exit code."""
    return run_tool(_study, argv, "study.py", _errors)


if __name__ == "__main__":
    raise SystemExit(main())
