"""The figure options every drawing tool takes: ``--dpi N`` (the PNG's resolution) and ``--format svg pdf``.

``run.py``, ``study.py``, ``ida.py`` and ``compare.py`` share them (:func:`add_figure_arguments`), so they
accept the same values (:class:`~orchestration.master.figure_files.FigureFiles`); a bad one is exit 2
naming the option, before anything is written (:func:`figure_files`).
"""

from __future__ import annotations

import argparse

from mre_common.guard import UsageError
from orchestration.master.figure_files import DPI_RANGE, VECTOR_FORMATS, FigureFiles


def add_figure_arguments(parser: argparse.ArgumentParser, dpi: int | None = None,
                         formats: tuple[str, ...] = (), default_note: str = "each figure's own") -> None:
    """Add ``--dpi`` and ``--format`` (defaults ``dpi``, ``formats``) to ``parser``."""
    low, high = DPI_RANGE
    parser.add_argument("--dpi", type=int, default=dpi, metavar="N",
                        help=f"PNG resolution, {low} to {high} dots per inch (default {dpi or default_note})")
    parser.add_argument("--format", dest="formats", nargs="+", choices=VECTOR_FORMATS, default=list(formats),
                        help="vector formats written beside each PNG (default: "
                             f"{' '.join(formats) if formats else 'none'})")


def figure_files(args: argparse.Namespace) -> FigureFiles:
    """The figure options of parsed arguments; a ``--dpi`` out of range is a
    :class:`~mre_common.guard.UsageError` naming it (exit 2; argparse refuses a ``--dpi`` that is not a whole
    number and an unknown ``--format`` itself, also exit 2)."""
    files = FigureFiles(args.dpi, tuple(dict.fromkeys(args.formats or ())))
    low, high = DPI_RANGE
    if files.problem() is not None:
        raise UsageError(f"--dpi {args.dpi}: give {low} to {high} dots per inch")
    return files
