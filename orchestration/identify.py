"""Identify the MRE isolator models from shake-table tests (paper section 3).

Usage: ``python orchestration/identify.py scenarios/identification.yaml [--out DIR] [--overwrite]``

Writes Table 1 (identified parameters per condition), RMS error and run time per
condition for every identifier, Table 2 (generalized coefficients) with parameter files
for the isolator FMUs, and Fig. 6-12; see docs/identification.md. Exit codes: 0 all
identifications converged, 1 some did not (they are reported and no parameters are
written for them), 2 bad configuration or input data.
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
    parser = argparse.ArgumentParser(description="Identify the MRE isolator models (paper section 3).")
    parser.add_argument("config", type=Path, help="identification YAML (e.g. scenarios/identification.yaml)")
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (default: 'output' of the config)"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    # SIGTERM unwinds like Ctrl-C, so the staging folder of an unfinished run is removed
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    try:
        cfg = load_config(args.config)
        out = args.out if args.out is not None else Path(cfg["output"])
        result = run(cfg, out, overwrite=args.overwrite, progress=not args.no_progress)
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
            f"warning: {len(result.not_converged)} identification(s) did not converge; "
            "no parameters were written for them (see summary.md)",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
