"""Intensity measures of a record as the runs play it, and the isolated building's period.

* ``pga``: peak ground acceleration [g] (independent of the time scale).
* ``sa``: 5 %-damped pseudo-spectral acceleration [g] at the isolated period T1, of the
  record as played (times multiplied by the study's time scale), from the piecewise-exact
  SDOF solution (:mod:`components.physics.response_spectrum`).

T1 is the first-mode period of the building on its isolators with the isolators' secant
stiffness ``F(x_ref, 0, i_ref) / x_ref`` at the reference displacement and current (the
tangent stiffness at 0 when x_ref = 0); by default 8 mm (the identified range) and 0 A.
A record is scaled to an intensity level by ``scale = level / IM(record)``: IM is linear
in the amplitude.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from components.physics.ground_motion_core import Record
from components.physics.mre_isolator_core import GeneralizedCoefficients, isolator_force, isolator_stiffness
from components.physics.response_spectrum import pseudo_acceleration, resample_uniform
from components.physics.shear_building_core import BuildingParams, natural_frequencies

MEASURES = {"pga": "PGA", "sa": "Sa(T1, 5 %)"}


def isolator_secant_stiffness(coeffs: GeneralizedCoefficients, n_isolators: int, current: float,
                              displacement: float) -> float:
    """Secant stiffness [N/m] of the isolators at ``displacement`` [m] and ``current`` [A] (tangent at 0)."""
    if displacement == 0.0:
        return isolator_stiffness(0.0, current, coeffs, n_isolators)
    return isolator_force(displacement, 0.0, current, coeffs, 0.0, n_isolators) / displacement


def isolated_period(building: BuildingParams, coeffs: GeneralizedCoefficients, n_isolators: int,
                    current: float = 0.0, displacement: float = 0.008) -> float:
    """First-mode period [s] of the building with the isolators as a linear spring at its base."""
    k_iso = isolator_secant_stiffness(coeffs, n_isolators, current, displacement)
    fixed = replace(building, k=(building.k[0] + k_iso, *building.k[1:]))
    omega = natural_frequencies(fixed)
    return 2 * math.pi / float(omega[0])


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
