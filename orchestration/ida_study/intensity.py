"""Intensity measures of a record as the runs play it, and the isolated building's period.

* ``pga``: peak ground acceleration [g] (independent of the time scale).
* ``sa``: 5 %-damped pseudo-spectral acceleration [g] at the isolated period T1, of the
  record as played (times multiplied by the study's time scale), from the piecewise-exact
  SDOF solution (:mod:`components.physics.response_spectrum`).

T1 is the first-mode period of the building on its isolators with the isolators' secant
stiffness ``F(x_ref, 0, i_ref) / x_ref`` at the reference displacement and current (the
tangent stiffness at 0 when x_ref = 0); by default 8 mm (the identified range) and 0 A.
A record is scaled to an intensity level by ``scale = level / IM(record)``: IM is linear
in the amplitude. T1 is computed by :func:`components.physics.building_periods.isolated_period`
(shared with each run's ``periods`` section).
"""

from __future__ import annotations

import numpy as np

from components.physics.ground_motion_core import Record
from components.physics.response_spectrum import pseudo_acceleration, resample_uniform

MEASURES = {"pga": "PGA", "sa": "Sa(T1, 5 %)"}


def measure(record: Record, name: str, time_scale: float = 1.0, period: float | None = None,
            damping: float = 0.05) -> float:
    """The intensity ``name`` ('pga' or 'sa') of a record played at ``time_scale`` [g]."""
    if name == "pga":
        return float(np.max(np.abs(record.accel_g)))
    if name == "sa":
        if period is None:
            raise ValueError("Sa needs the period")
        accel, dt = resample_uniform(record.time, record.accel_g)
        return float(pseudo_acceleration(accel, dt * time_scale, period, damping))
    raise ValueError(f"unknown intensity measure {name!r} (known: {', '.join(MEASURES)})")
