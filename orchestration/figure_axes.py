"""Axis styles the studies' figures share: plain tick labels a reader can read at a glance."""

from __future__ import annotations

from typing import Any


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
