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
from orchestration.figure_options import add_figure_arguments, figure_files

EXIT_CODES = ("exit codes: 0 success; 2 a folder that is not a run, no variable in common, or an output folder "
              "that is not empty (nothing written); " + EPILOG_COMMON)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=invoked_as("compare.py"), description="Compare run folders: peaks and "
                                     "overlays of their report roles.", epilog=EXIT_CODES)
    parser.add_argument("runs", type=Path, nargs="+", metavar="RUN", help="run folders (run.py's), the first is the "
                        "reference")
    parser.add_argument("--out", type=Path, help="write peaks.csv and the overlay figures here (a new or empty "
                        "folder)")
    add_figure_arguments(parser, dpi=150, formats=("svg",))
    args = parser.parse_args(argv)
    args.figure_files = figure_files(args)
    return args


def _compare(argv: list[str] | None) -> int:
    from orchestration.run_comparison import ComparisonError, compared, figures, labelled, read_run, table, write_csv
    from orchestration.tool_files import check_input, check_output_folder, write_new_folder

    args = parse_args(argv)
    if len(args.runs) < 2:
        raise UsageError("give at least two run folders")
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
        figures(runs, rows, folder, args.figure_files, written)
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
