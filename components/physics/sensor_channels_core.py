"""Measurement channels between a plant and its controller: seeded Gaussian noise and a delay.

A robustness variant of the controller benchmark runs a controller on
measurements that are not the plant's exact values. Each channel passes one signal through:

    y_k(t_n) = u_k(t_{n-d}) + rms_k * z_k,n,    z_k,n ~ N(0, 1) independent, seeded,

with d >= 0 whole communication steps of delay (the unit's own steps, ``units.NAME.step`` when set; the same for
every channel) and rms_k >= 0 the
stated root mean square of the additive noise in the signal's own SI unit. The noise is
white in discrete time: one sample per communication point, held (the model of a digital
controller's sampled sensor; the usual continuous-time white noise of intensity S sampled at a
step h has the variance S/h, e.g. Dyke et al. 1996, Sec. 4, for the sensor noise of a
clipped-optimal design). Before the first sample the signal is taken to have sat at its initial value.

With d = 0 the output is the live input plus noise (direct feedthrough); with d >= 1 it is the
sample of d steps before, stored when the channel is stepped from t_{n} (the input then is
u(t_n), a sample at the communication point). Units: every value in the connected signal's SI unit.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

MAX_DELAY_STEPS = 100_000
"""Longest delay [communication steps] a channel set keeps (its history is that many samples)."""


class SensorChannels:
    """N channels u_k -> y_k: a delay of ``delay`` steps and noise of RMS ``rms[k]`` (seeded by ``seed``)."""

    def __init__(self, rms: Sequence[float], delay: int = 0, seed: int = 0) -> None:
        rms = [float(r) for r in rms]
        for k, r in enumerate(rms):
            if not (math.isfinite(r) and r >= 0.0):
                raise ValueError(f"channel {k + 1}: noise RMS must be >= 0 and finite, got {r}")
        if isinstance(delay, bool) or int(delay) != delay or not 0 <= delay <= MAX_DELAY_STEPS:
            raise ValueError(f"delay must be a whole number of steps in [0, {MAX_DELAY_STEPS}], got {delay}")
        if isinstance(seed, bool) or int(seed) != seed or not 0 <= seed < 2**31:  # the FMU's seed: an FMI Integer
            raise ValueError(f"seed must be an integer in [0, 2^31 - 1] (an FMI Integer, int32), got {seed}")
        self.rms = np.asarray(rms, dtype=float)
        self.delay = int(delay)
        self.seed = int(seed)
        self._rng = np.random.Generator(np.random.PCG64(self.seed))
        self._history: deque[np.ndarray] = deque(maxlen=max(self.delay, 1))
        self._noise = np.zeros(len(rms))
        self.n = 0  # index of the present sample (t_n)

    def _draw(self) -> None:
        z = self._rng.standard_normal(len(self.rms))
        self._noise = self.rms * z

    def start(self, u0: Sequence[float]) -> None:
        """Initialise at t_0 with the inputs u(t_0): the history holds u(t_0), the first noise sample is drawn."""
        u0 = np.asarray(u0, dtype=float)
        self._history.clear()
        self._history.extend(u0.copy() for _ in range(max(self.delay, 1)))
        self.n = 0
        self._draw()

    def step(self, u_sample: Sequence[float]) -> None:
        """Advance one communication step from t_n: ``u_sample`` is u(t_n) (used when delay >= 1)."""
        if self.delay >= 1:
            self._history.append(np.asarray(u_sample, dtype=float).copy())
        self.n += 1
        self._draw()

    def outputs(self, u_live: Sequence[float]) -> np.ndarray:
        """y at the present sample: ``u_live`` + noise (delay 0), else the sample of ``delay`` steps ago + noise."""
        base = np.asarray(u_live, dtype=float) if self.delay == 0 else self._history[0]
        return base + self._noise


def parameter_problem(values: Mapping[str, Any], n_levels: int = 0) -> tuple[str, str] | None:
    """(parameter, message) for the first parameter out of its domain, or None: the checks :class:`SensorChannels`
    makes when the unit initializes (``delay`` whole steps in [0, MAX_DELAY_STEPS], each ``rms_*`` >= 0 and
    finite), made before any run."""
    delay = values.get("delay", 0)
    try:
        whole = not isinstance(delay, bool) and float(delay) == int(float(delay))
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole or not 0 <= int(float(delay)) <= MAX_DELAY_STEPS:
        return "delay", f"delay must be a whole number of communication steps in [0, {MAX_DELAY_STEPS}], got {delay!r}"
    for name in sorted(n for n in values if n.startswith("rms_")):
        value = values[name]
        try:
            ok = not isinstance(value, bool) and math.isfinite(float(value)) and float(value) >= 0.0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            return name, f"noise RMS {name} must be >= 0 and finite, got {value!r}"
    return None
