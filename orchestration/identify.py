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
replace; 130 interrupted (nothing written).
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from components.identification.config import ConfigError, load_config
from components.identification.generalized import GeneralizationError
from components.identification.pipeline import run
from components.identification.report import summary_text
from components.identification.testdata import TestDataError


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="identify.py", description="Identify the MRE isolator models (paper section 3).",
        epilog="exit codes: 0 done (non-converged identifications are reported); 1 some did not converge and "
               "--strict was given; 2 configuration or data error, or an output folder it may not replace "
               "(nothing written); 130 interrupted (nothing written)")
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
    args = parser.parse_args(argv)
    # SIGTERM unwinds like Ctrl-C, so the staging folder of an unfinished run is removed
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    try:
        cfg = load_config(args.config)
        out = args.out if args.out is not None else Path(cfg["output"])
        result = run(cfg, out, overwrite=args.overwrite, progress=not args.quiet)
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
