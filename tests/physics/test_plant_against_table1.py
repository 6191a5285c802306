"""The data-supported plant (BoucWenIsolator.fmu, its default coefficients) against the paper's Table 1.

Independent expectation: the peak force of each test condition's own hyperbolic fit (Table 1, Eq. 3-4,
evaluated analytically on the sine), not any output of the identification pipeline. The FMU is driven
through fmpy (tests/support/fmu_driver.py) with x = A sin(2 pi f t), v = dx/dt, a constant current.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from components.identification.paper_tables import TABLE1, TEST_MATRIX
from tests.support.fmu_driver import Driven

STEPS_PER_CYCLE = 400
CYCLES = 3


def table1_peak(f: float, a_mm: float, i: float) -> float:
    """Peak |F| [N] of one device under x = A sin(2 pi f t), Table 1's fit of that condition (paper units)."""
    p = TABLE1[(f, a_mm, i)]
    t = np.linspace(0.0, 1.0 / f, 20001)
    x = a_mm * np.sin(2 * np.pi * f * t)
    v = a_mm * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    return float(np.max(np.abs(p["c0"] * v + p["k0"] * x + p["alpha"] * np.sinh(p["beta"] * x))))


def fmu_peak(unit: Driven, f: float, a_m: float, i: float) -> float:
    """Peak |F| per device [N] over the last of CYCLES cycles of x = a sin(2 pi f t) (fresh state y = 0)."""
    h = 1.0 / (f * STEPS_PER_CYCLE)
    w = 2 * math.pi * f
    peak = 0.0
    for k in range(CYCLES * STEPS_PER_CYCLE + 1):
        t = k * h
        unit.set(x=a_m * math.sin(w * t), v=a_m * w * math.cos(w * t), i=i)
        if k >= (CYCLES - 1) * STEPS_PER_CYCLE:
            peak = max(peak, abs(unit.get("F")[0]) / 2)
        unit.step(t, h)
    return peak


@pytest.fixture
def plant(fmu_dir):
    units = []

    def make(**parameters) -> Driven:
        unit = Driven(fmu_dir / "BoucWenIsolator.fmu", f"plant{len(units)}", parameters)
        units.append(unit)
        return unit

    yield make
    for unit in units:
        unit.close()


@pytest.mark.slow
def test_the_plant_peak_force_is_within_table1_at_the_36_conditions(plant):
    errors = []
    for f, a, i in TEST_MATRIX:
        unit = plant()
        errors.append(fmu_peak(unit, f, a * 1e-3, i) / table1_peak(f, a, i) - 1.0)
        unit.close()
    errors = np.abs(errors)
    assert np.median(errors) < 0.10
    assert errors.max() < 0.30


@pytest.mark.slow
def test_the_plant_does_not_stiffen_past_the_tested_stroke(plant):
    at_8, at_149 = (fmu_peak(plant(), 1.0, a, 3.0) for a in (8e-3, 14.9e-3))
    assert at_149 / at_8 <= 2.5
    # the data's trend (Table 1, 1 Hz 3 A): the 4-8 mm increment continued to 14.9 mm
    trend = 1 + (table1_peak(1.0, 8.0, 3.0) - table1_peak(1.0, 4.0, 3.0)) / 4.0 * 6.9 / table1_peak(1.0, 8.0, 3.0)
    assert at_149 / at_8 == pytest.approx(trend, rel=0.15)
