"""Response spectra of a study's records as its runs play them, with the building's periods marked.

The 5 %-damped pseudo-spectral acceleration PSa(T) [g] of each record (amplitude scale and time scale
applied, as the ground-motion unit plays it), from the piecewise-exact SDOF solution of
:mod:`components.physics.response_spectrum` (Nigam & Jennings 1969; Chopra, section 5.2). A vertical line
marks each period a caller names (the isolated period T1, the fixed-base period): where the record's
spectrum crosses it is what the building feels.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from components.physics.response_spectrum import pseudo_acceleration, resample_uniform
from orchestration.figure_axes import plain_log_axis

PERIODS_S = np.geomspace(0.05, 5.0, 61)
"""The spectra's periods [s]: 0.05-5 s, 30 per decade (the fixed-base and isolated periods of the building
on its isolators lie inside)."""
DAMPING = 0.05


def spectrum(time_s: np.ndarray, accel_g: np.ndarray, scale: float = 1.0, time_scale: float = 1.0,
             periods_s: np.ndarray = PERIODS_S, damping: float = DAMPING) -> np.ndarray:
    """PSa [g] at ``periods_s`` of a record (times [s], accelerations [g]) played at ``scale`` and ``time_scale``."""
    accel, dt = resample_uniform(np.asarray(time_s, dtype=float), np.asarray(accel_g, dtype=float))
    return scale * pseudo_acceleration(accel, dt * time_scale, periods_s, damping)


def spectrum_figure(spectra: Mapping[str, np.ndarray], marks: Mapping[str, float], title: str,
                    periods_s: np.ndarray = PERIODS_S, median: bool = False) -> Any:
    """One panel: each record's spectrum (thin grey lines and their median when ``median``, else a labelled line
    per record), a dashed vertical line per period in ``marks`` (label -> period [s]); log axes, plain labels."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for name, values in spectra.items():
        if median:
            ax.plot(periods_s, values, color="0.6", lw=0.6)
        else:
            ax.plot(periods_s, values, lw=1.3, label=name)
    if median and spectra:
        ax.plot(periods_s, np.median(np.vstack(list(spectra.values())), axis=0), color="k", lw=2.0,
                label=f"median of {len(spectra)} records")
    for k, (label, period) in enumerate(marks.items()):  # black and grey: apart from the records' colours
        ax.axvline(period, color=("k", "0.5")[k % 2], ls=("--", "-.")[k % 2], lw=1.2, label=f"{label} = {period:.3g} s")
    plain_log_axis(ax.xaxis)
    plain_log_axis(ax.yaxis)
    ax.set(xlabel="period T [s]", ylabel=f"pseudo-spectral acceleration ({DAMPING:.0%} damping) [g]", title=title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return fig
