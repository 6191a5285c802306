"""Periods of the shear building: fixed at its base, and on its isolators (a linear spring at the base).

* Fixed base: the storeys above the base floor (levels 1..n, masses ``m[1:]``, storey
  stiffnesses ``k[1:]``) with the base floor held still: every mode, longest period first.
* Isolated: the first mode of the whole building (base floor included) with the isolators as
  a linear spring of their secant stiffness ``F(x_ref, 0, i) / x_ref`` at a reference
  displacement [m] and current [A] (the tangent stiffness at 0 when x_ref = 0), added to
  ``k[0]``. The reference displacement defaults to 8 mm, the isolator model's identified range.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.linalg import eigh

from components.physics.mre_isolator_core import (
    IDENTIFIED_RANGE_M,
    GeneralizedCoefficients,
    isolator_force,
    isolator_stiffness,
)
from components.physics.shear_building_core import BuildingParams, natural_frequencies, tridiagonal

REFERENCE_DISPLACEMENT_M = IDENTIFIED_RANGE_M
"""The displacement [m] of the isolators' secant stiffness by default: the identified range (8 mm)."""


def fixed_base_periods(building: BuildingParams) -> list[float]:
    """Periods [s] of the superstructure with the base floor fixed, every mode, longest first."""
    mass = np.diag(np.asarray(building.m[1:], dtype=float))
    stiffness = tridiagonal(building.k[1:])
    lam = eigh(stiffness, mass, eigvals_only=True)
    return [2 * math.pi / math.sqrt(float(v)) for v in np.sort(lam)]


def isolator_secant_stiffness(coeffs: GeneralizedCoefficients, n_isolators: int, current: float,
                              displacement: float) -> float:
    """Secant stiffness [N/m] of the isolators at ``displacement`` [m] and ``current`` [A] (tangent at 0)."""
    if displacement == 0.0:
        return isolator_stiffness(0.0, current, coeffs, n_isolators)
    return isolator_force(displacement, 0.0, current, coeffs, 0.0, n_isolators) / displacement


def isolated_period(building: BuildingParams, coeffs: GeneralizedCoefficients, n_isolators: int,
                    current: float = 0.0, displacement: float = REFERENCE_DISPLACEMENT_M) -> float:
    """First-mode period [s] of the building with the isolators as a linear spring at its base."""
    k_iso = isolator_secant_stiffness(coeffs, n_isolators, current, displacement)
    fixed = replace(building, k=(building.k[0] + k_iso, *building.k[1:]))
    omega = natural_frequencies(fixed)
    return 2 * math.pi / float(omega[0])
