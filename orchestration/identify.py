"""Identify the MRE isolator models from shake-table tests (paper section 3).

Usage: ``python orchestration/identify.py scenarios/identification.yaml [--out DIR] [--overwrite]``

Writes Table 1 (identified parameters per condition), RMS error and run time per
condition for every identifier, Table 2 (generalized coefficients) with parameter files
for the isolator FMUs, and Fig. 6-12; see docs/identification.md. The output is built in a
staging folder next to ``--out`` and renamed into place when complete; ``--overwrite``
replaces only a folder this tool wrote (marker ``.mre-cosim-identification``). Exit codes: 0
done (identifications that did not converge are reported, with no parameters written for
them: a finding about the method, not a failure of the tool); 1 with ``--strict`` when
some did not converge; 2 bad configuration or input data, or an output folder it may not
replace; 3 internal error (a bug; the traceback is in the log file named); 130 interrupted
(nothing written).

Conditions can be identified in parallel (``--workers N``) on the batch pool
(:mod:`orchestration.batch.pool`), behind :func:`process_map`, a map-like function: the
identification (the application :mod:`orchestration.identification` over the fitting library
``components/identification``) only sees a map. Without ``--workers`` that happens only when
the FFOA work is large enough to pay for starting the pool (``ident_pipeline.PARALLEL_MIN_S``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
if __name__ == "__main__":
    # The conditions run in parallel processes, so one BLAS thread per process (set before
    # numpy loads; the workers inherit it): more threads only oversubscribe the cores, and on
    # a loaded machine made the joint fit's SVDs several times slower.
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

from mre_common.guard import quiet_interrupts  # standard library only: installed before any other import

if __name__ == "__main__":
    quiet_interrupts()  # Ctrl-C or SIGTERM during the imports below: one line, exit 130, no traceback

import argparse
import signal
from collections.abc import Callable, Sequence
from typing import Any

from components.identification.generalized import GeneralizationError
from components.identification.testdata import TestDataError
from orchestration.batch import default_workers
from orchestration.cli import EPILOG_COMMON, invoked_as, run_tool
from orchestration.figure_options import add_figure_arguments, figure_files
from orchestration.identification.ident_config import ConfigError, load_config
from orchestration.identification.ident_pipeline import PARALLEL_MIN_S, run
from orchestration.identification.ident_report import summary_text


def process_map(func: Callable[[Any], Any], items: Sequence[Any], workers: int) -> list[Any]:
    """``list(map(func, items))`` spread over up to ``workers`` processes of the batch pool.

    ``func`` must be a module-level function; items and results must pickle. Each item is
    one job of :func:`orchestration.batch.pool.map_values` (a local Dask cluster, one
    single-threaded worker process per CPU; the scheduler balances the jobs); results come
    back in the order of the items, and a failed job raises RuntimeError with its traceback.
    With one worker or one item, or without the pool, runs in this process.
    """
    items = list(items)
    n = min(workers, len(items))
    if n > 1:
        try:
            from orchestration.batch import BatchUnavailable, map_values
        except ImportError as exc:  # the batch pool's packages are missing
            print(f"note: identifying in one process (no parallel pool: {exc})", file=sys.stderr)
        else:
            try:
                return map_values(func, items, workers=n)
            except BatchUnavailable as exc:
                print(f"note: identifying in one process ({exc})", file=sys.stderr)
    return [func(item) for item in items]


def main(argv: list[str] | None = None) -> int:
    """Identify from the command line; returns the exit code (an unexpected error is exit 3 with a log)."""
    return run_tool(_identify, argv, "identify.py",
                    lambda: (ConfigError, TestDataError, GeneralizationError, OSError))  # OSError: unwritable --out


def check_config_file(path: Path) -> None:
    """ConfigError (exit 2) unless the configuration is a regular UTF-8 file of sane size and YAML structure
    (no FIFO or device, no deep nesting or alias bombs): checked before the identification reads it."""
    from orchestration.master.errors import ScenarioError
    from orchestration.master.yaml_source import parse_text, read_text_file

    try:
        parse_text(read_text_file(path, "identification file"), str(path))
    except ScenarioError as exc:
        raise ConfigError("; ".join(str(p) for p in exc.problems)) from None


def _identify(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(
        prog=invoked_as("identify.py"), description="Identify the MRE isolator models (paper section 3).",
        epilog="exit codes: 0 done (non-converged identifications are reported); 1 some did not converge and "
               "--strict was given; 2 configuration or data error, or an output folder it may not replace "
               "(nothing written); " + EPILOG_COMMON)
    parser.add_argument("config", type=Path, help="identification YAML (e.g. scenarios/identification.yaml)")
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (default: 'output' of the config)"
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing output folder written by this tool (it holds a .mre-cosim-identification "
        "marker); never the working directory, its ancestors, / or the home folder",
    )
    parser.add_argument("--quiet", "--no-progress", dest="quiet", action="store_true", help="no progress bar")
    parser.add_argument("--strict", action="store_true", help="exit 1 if any identification did not converge")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="identify the conditions in N processes of the batch pool (1 = in this "
                             "process; default: one per CPU, but only when the FFOA work is large enough to pay "
                             "for starting them, see docs/identification.md)")
    add_figure_arguments(parser, default_note="110")
    args = parser.parse_args(argv)
    files = figure_files(args)
    workers = default_workers() if args.workers is None else args.workers
    if workers < 1:
        parser.error("--workers must be >= 1")
    min_parallel_s = PARALLEL_MIN_S if args.workers is None else 0.0
    # SIGTERM unwinds like Ctrl-C, so the staging folder of an unfinished run is removed
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    check_config_file(args.config)
    try:
        cfg = load_config(args.config)
        out = args.out if args.out is not None else Path(cfg["output"])
        result = run(cfg, out, overwrite=args.overwrite, progress=not args.quiet,
                     map_fn=lambda func, items: process_map(func, items, workers), min_parallel_s=min_parallel_s,
                     files=files)
    except (ConfigError, TestDataError, GeneralizationError, FileExistsError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted; nothing written", file=sys.stderr)
        return 130
    print(summary_text(result, cfg))
    print(f"outputs written to {out}")
    if result.not_converged:
        print(
            f"note: {len(result.not_converged)} identification(s) did not converge; "
            "no parameters were written for them (see summary.md)",
            file=sys.stderr,
        )
        return 1 if args.strict else 0
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
