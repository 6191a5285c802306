"""Compare runs: ``python orchestration/compare.py RUN_A RUN_B [RUN ...] [--out DIR]`` (``mre-cosim compare``).

Prints the peaks of the first run's report roles (base displacement, drifts, floor accelerations,
current, isolator force, ground acceleration) for every run, with each later run's change against the
first; variables a run lacks are named and left out. With ``--out DIR`` it also writes ``peaks.csv`` and
one overlay figure per role (a grid of panels, a line style per run) as PNG at ``--dpi`` and as SVG or PDF
(``--format``). Peaks come from each run's ``summary.json`` (every step), the overlays from its
``timeseries.csv`` (:mod:`orchestration.run_comparison`).

Exit codes: 0 success; 2 a folder that is not a run, no variable in common, or an output folder that
exists and is not empty (nothing written); 3 internal error (a bug; the traceback is in the log file
named); 130 interrupted.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mre_common.guard import quiet_interrupts  # standard library only: installed before any other import

if __name__ == "__main__":
    quiet_interrupts()

import argparse

from orchestration.cli import EPILOG_COMMON, EXIT_OK, UsageError, invoked_as, run_tool

EXIT_CODES = ("exit codes: 0 success; 2 a folder that is not a run, no variable in common, or an output folder "
              "that is not empty (nothing written); " + EPILOG_COMMON)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=invoked_as("compare.py"), description="Compare run folders: peaks and "
                                     "overlays of their report roles.", epilog=EXIT_CODES)
    parser.add_argument("runs", type=Path, nargs="+", metavar="RUN", help="run folders (run.py's), the first is the "
                        "reference")
    parser.add_argument("--out", type=Path, help="write peaks.csv and the overlay figures here (a new or empty "
                        "folder)")
    parser.add_argument("--format", dest="formats", nargs="+", choices=("svg", "pdf"), default=["svg"],
                        help="vector formats written beside the PNG (default: svg)")
    parser.add_argument("--dpi", type=int, default=150, help="PNG resolution (default 150)")
    return parser.parse_args(argv)


def _compare(argv: list[str] | None) -> int:
    from orchestration.run_comparison import ComparisonError, compared, figures, labelled, read_run, table, write_csv
    from orchestration.tool_files import check_input, check_output_folder, write_new_folder

    args = parse_args(argv)
    if len(args.runs) < 2:
        raise UsageError("give at least two run folders")
    if not 10 <= args.dpi <= 1200:
        raise UsageError(f"--dpi {args.dpi}: give 10 to 1200 dots per inch")
    out: Path | None = args.out
    if out is not None:
        check_output_folder(out)
    for folder in args.runs:
        check_input(folder, "folder")
    try:
        runs = labelled([read_run(folder) for folder in args.runs])
        rows, notes = compared(runs)
        if out is not None:
            for r in runs:
                r.series()  # every results file read before anything is written
    except ComparisonError as exc:
        raise UsageError(str(exc)) from None
    if not rows:
        raise UsageError("the runs have no report variable in common: " + "; ".join(notes or ["none has roles"]))
    print(table(runs, rows))
    for note in notes:
        print(f"not compared: {note}")
    if out is None:
        return EXIT_OK

    def write(folder: Path, written: list[Path]) -> None:
        figures(runs, rows, folder, ("png", *args.formats), args.dpi, written)
        write_csv(runs, rows, folder / "peaks.csv")  # last: a folder with peaks.csv is complete
        written.append(folder / "peaks.csv")

    written = write_new_folder(out, write)
    print(f"compared: {out} ({len(written)} files)")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Compare run folders from the command line; returns the exit code."""
    return run_tool(_compare, argv, "compare.py")


if __name__ == "__main__":
    raise SystemExit(main())
