"""Axis styles the studies' figures share: plain tick labels a reader can read at a glance, a line style and
marker per strategy, and a note in the legend where two strategies' curves coincide."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

COINCIDENT = 0.005
"""Two curves coincide when they differ nowhere by more than this share of the axis span (0.5 %)."""
_OTHER_STYLES = tuple((ls, m) for ls in ("-", "--", "-.", ":") for m in ("p", "*", "d", "8", "H"))
"""Line and marker of a strategy whose entry sets none, by its place in the study (markers no shipped entry uses)."""


def plain_log_axis(axis: Any) -> None:
    """A log axis (``ax.xaxis`` or ``ax.yaxis``) with plain numbers at 1, 2 and 5 per decade (``0.05``, ``0.1``,
    ``0.2``) and no minor labels: matplotlib's default labels every minor tick of a short decade as ``3×10⁰``, and
    neighbouring labels run into each other."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    (axis.axes.set_xscale if axis is axis.axes.xaxis else axis.axes.set_yscale)("log")
    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def few_ticks(axis: Any, n: int = 4) -> None:
    """At most ``n`` major ticks with compact labels (``1.5e-3`` style where needed), so that they never overlap."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    axis.set_major_locator(MaxNLocator(n))
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:.3g}"))


def strategy_style(strategy: str, order: Sequence[str] = (), style: Mapping[str, Any] | None = None
                   ) -> dict[str, Any]:
    """``ls``, ``marker`` and ``color`` for a strategy: what its entry's ``style`` sets (``line``: a named style or
    dashes, ``[]`` solid; ``marker``; ``color``), the rest by its place in ``order``."""
    k = list(order).index(strategy) if strategy in order else 0
    ls, marker = _OTHER_STYLES[k % len(_OTHER_STYLES)]
    out: dict[str, Any] = {"ls": ls, "marker": marker, "color": f"C{k % 10}"}
    style = style or {}
    line = style.get("line")
    if isinstance(line, list):
        out["ls"] = (0, tuple(line)) if line else "-"
    elif line is not None:
        out["ls"] = line
    out["marker"] = style.get("marker") or out["marker"]
    out["color"] = style.get("color") or out["color"]
    return out


def coincident(curves: Mapping[str, Any], spans: float | Sequence[float], tolerance: float = COINCIDENT
               ) -> list[tuple[str, str]]:
    """Pairs ``(earlier, later)`` of curves that coincide: of the same shape, and nowhere apart by more than
    ``tolerance`` of the axis span (``spans``: one, or one per column of a curve of points, e.g. (x span, y span)).
    A later curve is paired with the first earlier one it coincides with; curves with a NaN are not compared."""
    names = list(curves)
    values = {n: np.asarray(curves[n], dtype=float) for n in names}
    span = np.asarray(spans, dtype=float)
    pairs = []
    for k, later in enumerate(names):
        for earlier in names[:k]:
            a, b = values[earlier], values[later]
            if a.shape != b.shape or not a.size or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
                continue
            if np.all(np.abs(a - b) <= tolerance * span):
                pairs.append((earlier, later))
                break
    return pairs


def coincidence_note(earlier: str, later: str) -> str:
    """The legend's words for two curves that coincide (the later drawn over the earlier)."""
    return f"{earlier} coincides with {later}"


def legend_below(fig: Any, notes: Sequence[str], width: int = 110, **legend: Any) -> None:
    """One legend for the whole figure, under its panels, where it hides nothing and takes no width from them:
    every labelled line of every panel (once per label), then ``notes`` as entries without a line, each wrapped to
    ``width`` characters. Call it after ``tight_layout``: the saved figure is cropped to what is drawn."""
    import textwrap

    from matplotlib.lines import Line2D

    handles: dict[str, Any] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    notes = [textwrap.fill(note, width) for note in dict.fromkeys(notes)]
    if not handles and not notes:
        return
    options = {"loc": "upper center", "bbox_to_anchor": (0.5, 0.0), "frameon": False, "fontsize": 8,
               "ncol": 1 if notes else max(1, min(len(handles), 5))} | legend
    fig.legend([*handles.values(), *(Line2D([], [], ls="none") for _ in notes)], [*handles, *notes], **options)


def add_legend_notes(ax: Any, notes: Sequence[str], **legend: Any) -> None:
    """The axes' legend with ``notes`` as entries without a line (nothing new without notes and a legend)."""
    from matplotlib.lines import Line2D

    handles, labels = ax.get_legend_handles_labels()
    if not handles and not notes:
        return
    notes = list(dict.fromkeys(notes))
    ax.legend([*handles, *(Line2D([], [], ls="none") for _ in notes)], [*labels, *notes], **legend)
