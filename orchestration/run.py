"""Run one co-simulation scenario: ``python orchestration/run.py scenarios/kobe.yaml``.

Writes a new run folder (never overwrites one): ``timeseries.csv``, ``summary.json``,
``manifest.json`` and PNG plots. Exit codes: 0 success, 1 simulation failure or
interruption (partial results written and marked incomplete), 2 scenario error
(nothing written).
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from orchestration.master.errors import ScenarioError
from orchestration.master.execution import StopRequest
from orchestration.master.runfolder import RunFolderExists
from orchestration.master.session import RunOutcome
from orchestration.project import run_scenario


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="run.py", description="Run a co-simulation scenario and write a run folder.",
        epilog="exit codes: 0 success; 1 simulation failure or interruption (partial results written, marked "
               "incomplete); 2 scenario error (nothing written). Relative paths are relative to the current folder.",
    )
    parser.add_argument("scenario", type=Path, help="scenario YAML file or SSP package (.ssp)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario key; UNIT.PARAM=VALUE sets a unit parameter "
                             "(e.g. --set controller.mode=passive)")
    parser.add_argument("--out", type=Path, help="run folder to create (must not exist or be empty)")
    parser.add_argument("--data-dir", dest="data_dirs", action="append", type=Path, default=[],
                        help="folder searched first for !record and !data files (repeatable)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    stop = StopRequest()

    def on_signal(signum, frame):
        stop.set(f"{signal.Signals(signum).name} received")

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        outcome: RunOutcome = run_scenario(
            args.scenario,
            overrides=tuple(args.overrides),
            out=args.out,
            data_dirs=tuple(args.data_dirs),
            plots=not args.no_plots,
            progress=not args.quiet,
            stop=stop,
        )
    except ScenarioError as exc:
        print(exc.report(), file=sys.stderr)
        return 2
    except RunFolderExists as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    warnings = sum(outcome.summary.get("unit_warnings", {}).values())
    if outcome.result.complete:
        print(f"run complete: {outcome.folder} ({warnings} unit warning{'s' if warnings != 1 else ''})")
        return 0
    print(f"run {outcome.result.status}: {outcome.result.error}", file=sys.stderr)
    print(f"partial results (marked incomplete): {outcome.folder}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    raise SystemExit(main())
