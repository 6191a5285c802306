"""How a figure is written to files: a PNG at a chosen resolution and, on request, SVG or PDF beside it.

Every tool that draws (a run's report, the studies, ``compare``) writes through :func:`save_figure`, so the
options agree: ``dpi`` a whole number in :data:`DPI_RANGE`, ``formats`` among :data:`VECTOR_FORMATS`. Each file
goes to a temporary name and is renamed (whole or absent); the vector files carry no date, so the same figure
gives the same bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

VECTOR_FORMATS = ("svg", "pdf")
"""Formats written beside the PNG on request."""
DPI_RANGE = (10, 1200)
"""Smallest and largest PNG resolution accepted [dots per inch]."""
RUN_DPI = 110
"""A run's PNG resolution unless one is asked for [dots per inch]."""
_NO_DATE = {"svg": {"Date": None}, "pdf": {"CreationDate": None}}


@dataclass(frozen=True)
class FigureFiles:
    """The files of each figure: the PNG at ``dpi`` (None: the figure's own default) and each of ``formats``."""

    dpi: int | None = None
    formats: tuple[str, ...] = ()

    def problem(self) -> str | None:
        """What is wrong with these options (``dpi`` out of range or not whole, an unknown format), or None."""
        low, high = DPI_RANGE
        if self.dpi is not None and (isinstance(self.dpi, bool) or not isinstance(self.dpi, int)
                                     or not low <= self.dpi <= high):
            return f"dpi {self.dpi!r}: give a whole number of dots per inch from {low} to {high}"
        unknown = [f for f in self.formats if f not in VECTOR_FORMATS]
        if unknown:
            return (f"format {', '.join(map(repr, unknown))}: give {' or '.join(VECTOR_FORMATS)} (the PNG is always "
                    "written)")
        return None


PNG_ONLY = FigureFiles()
"""The default: each figure as a PNG at its own resolution, nothing beside it."""


def save_figure(fig: Any, path: Path, files: FigureFiles, default_dpi: int, tight: bool = True,
                made: list[Path] | None = None) -> list[Path]:
    """Write ``fig`` as ``path`` (a ``.png``) and as each of ``files.formats`` beside it; the files written (also
    appended to ``made`` one by one, as each is written).

    ``default_dpi`` is the figure's resolution when ``files.dpi`` is None; ``tight`` crops the figure to what is
    drawn (matplotlib's ``bbox_inches="tight"``). The figure stays open.
    """
    path = Path(path)
    extra = {"bbox_inches": "tight"} if tight else {}
    made = [] if made is None else made
    start = len(made)
    import matplotlib

    for ext in ("png", *files.formats):
        target = path.with_suffix(f".{ext}")
        tmp = target.with_name(f".{target.name}.tmp.{ext}")
        with matplotlib.rc_context({"svg.hashsalt": target.name}):  # the SVG's ids: the same each time
            fig.savefig(tmp, dpi=files.dpi or default_dpi, format=ext, metadata=_NO_DATE.get(ext), **extra)
        tmp.replace(target)
        made.append(target)
    return made[start:]
