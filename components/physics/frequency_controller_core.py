"""Frequency control of the MRE isolators (after Gu et al. 2015).

Source: X. Gu, J. Li, Y. Li and M. Askari, "Frequency control of smart base isolation
system employing a novel adaptive magneto-rheological elastomer base isolator",
J. Intell. Mater. Syst. Struct. (online 2015): tune the isolated structure's natural
frequency away from the dominant frequency of the ground motion. The estimator and the
selection below are this project's own stated method:

* Dominant frequency: the peak of the periodogram of the last ``window`` samples of the
  ground acceleration (one per communication step), mean removed, Hann window, zero-padded
  to at least 8 times the window (scipy.signal.periodogram), searched in [f_lo, f_hi],
  refined by a parabola through the peak bin and its neighbours (log power). Recomputed
  every ``update_every`` steps; until the first window has filled, the current is i_start
  (i_max by default: the device starts stiff, the safe passive setting).
* Structure: the first undamped natural frequency of the isolated building with the
  isolators linearised at current i (secant at x_lin, :mod:`lqg_plant_core`), by
  scipy.linalg.eigh of (K(i), M), precomputed on a grid of ``n_grid`` currents over
  [0, i_max] at initialization.
* Choice: the grid current whose f1(i) is furthest from the dominant frequency f_d,
  max |f1(i) - f_d| [Hz]; ties go to the lower current. f1 grows with the current, so
  this picks 0 or i_max: i_max when f_d lies below the midpoint of f1(0) and f1(i_max)
  (2.1 Hz with the defaults), 0 above it.

Units: ag [m/s^2], frequencies [Hz], i [A].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import periodogram

try:
    from . import lqg_plant_core as plant_core
    from .lqg_plant_core import BuildingModel, IsolatorLaw, ParameterError
except ImportError:  # inside an FMU the cores are top-level modules
    import lqg_plant_core as plant_core
    from lqg_plant_core import BuildingModel, IsolatorLaw, ParameterError


MAX_WINDOW = 10_000_000  # steps: a sanity bound (80 MB of samples)
MAX_GRID = 10_001  # currents: one eigenvalue problem each at initialization


@dataclass(frozen=True)
class FrequencyDesign:
    """Design parameters.

    i_max [A], i_start [A] (held until the first window has filled), window [steps] (>= 2),
    update_every [steps] (>= 1) (steps: the unit's own communication steps, ``units.NAME.step`` when set),
    f_lo, f_hi [Hz] the search band, x_lin [m] the secant
    amplitude (0: tangent at 0), n_grid the currents of the precomputed grid (>= 2).
    """

    i_max: float = 3.0
    i_start: float = 3.0
    window: int = 2000  # 2 s at the 1 ms step of the shipped scenarios
    update_every: int = 20
    f_lo: float = 0.2
    f_hi: float = 10.0
    x_lin: float = 0.005
    n_grid: int = 31

    def __post_init__(self) -> None:
        if not (math.isfinite(self.i_max) and self.i_max > 0):
            raise ParameterError("i_max", f"i_max must be positive and finite, got {self.i_max}")
        if not (math.isfinite(self.i_start) and 0 <= self.i_start <= self.i_max):
            raise ParameterError("i_start", f"i_start must lie in [0, i_max = {self.i_max}], got {self.i_start}")
        if not 2 <= self.window <= MAX_WINDOW:
            raise ParameterError("window", f"window must be at least two steps (and at most {MAX_WINDOW}), "
                                 f"got {self.window}")
        if self.update_every < 1:
            raise ParameterError("update_every", f"update_every must be at least one step, got {self.update_every}")
        if not (math.isfinite(self.f_lo) and math.isfinite(self.f_hi) and 0 <= self.f_lo < self.f_hi):
            raise ParameterError("f_lo", f"need 0 <= f_lo < f_hi (finite), got f_lo = {self.f_lo}, f_hi = {self.f_hi}")
        if not (math.isfinite(self.x_lin) and self.x_lin >= 0):
            raise ParameterError("x_lin", f"x_lin must be >= 0 m and finite, got {self.x_lin}")
        if not 2 <= self.n_grid <= MAX_GRID:
            raise ParameterError("n_grid", f"n_grid must lie in [2, {MAX_GRID}], got {self.n_grid}")


def dominant_frequency(samples: np.ndarray, fs: float, f_lo: float, f_hi: float) -> float:
    """Peak frequency [Hz] of the periodogram of ``samples`` (rate fs [Hz]) in [f_lo, f_hi]; NaN if flat."""
    x = np.asarray(samples, dtype=float)
    nfft = max(8 * len(x), 1024)
    f, p = periodogram(x, fs=fs, window="hann", nfft=nfft, detrend="constant", scaling="density")
    band = (f >= f_lo) & (f <= f_hi)
    if not band.any():
        return math.nan
    idx = np.flatnonzero(band)
    k = int(idx[np.argmax(p[idx])])
    if not p[k] > 0:
        return math.nan
    if idx[0] < k < idx[-1] and p[k - 1] > 0 and p[k + 1] > 0:
        a, b, c = np.log(p[k - 1 : k + 2])
        denom = a - 2 * b + c
        shift = 0.5 * (a - c) / denom if denom < 0 else 0.0
        return float(f[k] + shift * (f[1] - f[0]))
    return float(f[k])


class FrequencyController:
    """Current that keeps the isolated structure's first frequency away from the ground's dominant one."""

    def __init__(
        self,
        design: FrequencyDesign | None = None,
        building: BuildingModel | None = None,
        isolator: IsolatorLaw | None = None,
    ) -> None:
        self.design = d = design if design is not None else FrequencyDesign()
        self.building = building if building is not None else BuildingModel()
        self.isolator = isolator if isolator is not None else IsolatorLaw()
        self.currents = np.linspace(0.0, d.i_max, d.n_grid)
        try:
            with np.errstate(all="ignore"):
                self.f1 = np.array([plant_core.first_natural_frequency(self.building,
                                                                       self.isolator.stiffness(i, d.x_lin))
                                    for i in self.currents])
        except ValueError as exc:  # scipy refuses non-finite matrices
            raise ValueError(f"the natural frequencies cannot be computed: {exc}") from None
        if not np.all(np.isfinite(self.f1) & (self.f1 > 0)):
            raise ValueError("the isolated structure has no positive first natural frequency on the current grid")
        self._buffer = np.zeros(d.window)
        self._count = 0  # samples pushed so far
        self.f_dominant = math.nan  # Hz
        self.i = d.i_start

    def choose(self, f_d: float) -> float:
        """The grid current [A] whose first frequency is furthest from f_d [Hz] (ties: the lower current)."""
        if not (math.isfinite(f_d) and f_d > 0):
            return self.i
        distance = np.abs(self.f1 - f_d)
        return float(self.currents[int(np.argmax(distance))])

    @property
    def f_structure(self) -> float:
        """First natural frequency [Hz] at the present current (linearised model, interpolated on the grid)."""
        return float(np.interp(self.i, self.currents, self.f1))

    def window_samples(self) -> np.ndarray:
        """The last ``window`` samples, oldest first (fewer before the window has filled)."""
        n = self.design.window
        k = self._count % n
        ordered = np.concatenate((self._buffer[k:], self._buffer[:k]))
        return ordered if self._count >= n else ordered[n - self._count :]

    def update(self, ag: float, h: float) -> float:
        """Take the ground acceleration ag [m/s^2] at this communication point (step h [s]); returns i [A]."""
        d = self.design
        self._buffer[self._count % d.window] = ag
        self._count += 1
        if self._count >= d.window and (self._count - d.window) % d.update_every == 0:
            self.f_dominant = dominant_frequency(self.window_samples(), 1.0 / h, d.f_lo, d.f_hi)
            self.i = self.choose(self.f_dominant)
        return self.i


def controller_parts(values: Mapping[str, Any], n_levels: int = 4) -> tuple[
        FrequencyDesign, BuildingModel, IsolatorLaw]:
    """The controller's design objects from its FMU parameter values by name (the arguments of
    :class:`FrequencyController`); :class:`ParameterError` names the first one out of its domain."""
    return (plant_core.design_from(FrequencyDesign, values), plant_core.building_from(values, n_levels),
            plant_core.design_from(IsolatorLaw, values))


def parameter_problem(values: Mapping[str, Any], n_levels: int = 4) -> tuple[str, str] | None:
    """(parameter, message) for the first FMU parameter out of its domain, or a design that cannot be made from
    them, or None (a check before any run)."""
    found = plant_core.first_parameter_problem(controller_parts, values, n_levels)
    if found is not None:
        return found
    try:
        FrequencyController(*controller_parts(values, n_levels))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return "m_0", f"the controller's design (the building model m_j, k_j, c_j) fails: {exc}"
    return None
