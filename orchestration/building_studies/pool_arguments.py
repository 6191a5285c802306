"""The batch pool's command-line options, shared by the study tools (study.py, tune.py, ida.py)."""

from __future__ import annotations

import argparse


def add_pool_arguments(parser: argparse.ArgumentParser) -> None:
    """--scheduler and --workers."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on an existing Dask cluster (e.g. tcp://10.0.0.5:8786; default: the environment "
                             "variable DASK_SCHEDULER_ADDRESS, else a local cluster)")
    parser.add_argument("--workers", type=int, help="local cluster: worker processes (default: the study's "
                                                    "'workers', else one per core)")
