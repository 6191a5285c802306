"""Check a plant-sample file: ``python -m orchestration.identification.check_plants FILE [--i-max A]``.

Exit 0 and a one-line summary when every sample is a usable BoucWenIsolator coefficient set; exit 2 naming the
file, the sample and the coefficient otherwise (a missing or extra coefficient, a value that is not a finite
number, beta + gamma <= 0, a force that does not rise with displacement on [0, i_max]).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from components.identification.plant_samples import PlantSampleError, load_plant_samples


def main(argv: list[str] | None = None) -> int:
    """Check the file; returns the exit code."""
    parser = argparse.ArgumentParser(prog="check_plants", description="Check a plant-sample file.")
    parser.add_argument("file", type=Path)
    parser.add_argument("--i-max", type=float, default=3.0, help="largest current the samples must hold [A]")
    args = parser.parse_args(argv)
    try:
        _, samples = load_plant_samples(args.file, args.i_max)
    except PlantSampleError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.file}: {len(samples)} sampled plants, every coefficient present and in its domain")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
