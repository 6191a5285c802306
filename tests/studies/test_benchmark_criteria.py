"""The benchmark's criteria J1...J9 and control effort against hand-computed values (no runs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orchestration.case_study.benchmark_criteria import effort, energy_share, normalised, raw_criteria, rms

W = 2 * math.pi  # rad/s: period 1 s
T = np.linspace(0.0, 2.0, 2001)  # two whole periods, 1 ms samples (extrema at multiples of 0.25 s are samples)
MASSES = [100.0, 50.0, 40.0, 30.0]


def _series() -> dict[str, np.ndarray]:
    s, c = np.sin(W * T), np.cos(W * T)
    return {
        "time": T,
        "building.x_0": 0.01 * s,  # m
        "building.v_0": 0.01 * W * c,
        "building.v_1": 0.01 * W * c, "building.v_2": 0.01 * W * c, "building.v_3": 0.01 * W * c,
        "building.a_0": 2.0 * s, "building.a_1": 3.0 * s, "building.a_2": 1.0 * c, "building.a_3": 2.5 * s,
        "building.drift_1": 0.001 * s, "building.drift_2": 0.004 * c, "building.drift_3": 0.002 * s,
        "building.shear_1": 700.0 * c,
        "isolator.F": 500.0 * 0.01 * W * c,  # a pure damper, c = 500 N s/m
        "isolator.F_off": 300.0 * 0.01 * W * c,  # at 0 A: c = 300 N s/m
        "ground.ag": -4.0 * c,
        "controller.i": 1.0 + 0.5 * s,
    }


def test_raw_criteria_of_sines() -> None:
    j = raw_criteria(_series(), MASSES)
    base_shear = 100 * 2 + 50 * 3 + 30 * 2.5  # the sine parts add in phase; a_2 (cosine) is 90 degrees apart
    assert j["J1"] == pytest.approx(math.hypot(base_shear, 40 * 1.0), rel=1e-5)
    assert j["J2"] == pytest.approx(700.0)
    assert j["J3"] == pytest.approx(0.01)
    assert j["J4"] == pytest.approx(0.004)
    assert j["J5"] == pytest.approx(3.0)  # floors 1..3 only: a_0 is the base
    assert j["J6"] == pytest.approx(200 * 0.01 * W)  # the controllable part: (500 - 300) N s/m times peak v
    assert j["J7"] == pytest.approx(0.01 / math.sqrt(2), rel=1e-9)
    assert j["J8"] == pytest.approx(3.0 / math.sqrt(2), rel=1e-9)
    assert math.isnan(j["J9"])  # J9 comes from the run's energy section, not from the sampled series


def test_energy_share_comes_from_the_energy_section() -> None:
    energy = {"checked": True, "isolator_J": 2.5, "input_J": 10.0}
    assert raw_criteria(_series(), MASSES, energy)["J9"] == pytest.approx(0.25)
    assert energy_share(energy) == pytest.approx(0.25)
    assert math.isnan(energy_share(None))
    assert math.isnan(energy_share({"checked": False, "note": "not checked: OpenSees"}))
    assert math.isnan(energy_share({"checked": True, "isolator_J": 1.0, "input_J": 0.0}))


def test_effort_of_a_sine_current() -> None:
    e = effort(T, 1.0 + 0.5 * np.sin(W * T))
    assert e["mean_current_A"] == pytest.approx(1.0, rel=1e-9)
    assert e["joule_A2s"] == pytest.approx(2.0 * (1 + 0.5 ** 2 / 2), rel=1e-9)
    assert e["switching_rate_A_s"] == pytest.approx(4 * 0.5 * 2 / 2.0, rel=1e-9)  # 2 A of travel per period


def test_rms_and_normalised() -> None:
    assert rms(T, np.full_like(T, -3.0)) == pytest.approx(3.0)
    n = normalised({"J1": 2.0, "J3": 1.0, "J5": 0.0}, {"J1": 4.0, "J3": 0.0, "J5": 2.0})
    assert n["J1"] == 0.5 and math.isnan(n["J3"]) and n["J5"] == 0.0 and math.isnan(n["J9"])


def test_masses_must_match_the_levels() -> None:
    with pytest.raises(ValueError, match="3 masses for 4 levels"):
        raw_criteria(_series(), MASSES[:3])


def test_j6_is_the_controllable_force_over_the_reference() -> None:
    """J6 = max|F - F_off|, NaN without F_off (an isolator that does not give it), and normalised by the J6
    reference's value (passive-on's), not by the baseline's (passive-off's is zero)."""
    series = _series()
    series["isolator.F_off"] = series["isolator.F"].copy()  # 0 A throughout: nothing controlled
    assert raw_criteria(series, MASSES)["J6"] == 0.0
    del series["isolator.F_off"]
    assert math.isnan(raw_criteria(series, MASSES)["J6"])
    n = normalised({"J1": 2.0, "J6": 3.0}, {"J1": 4.0, "J6": 0.0}, {"J1": 100.0, "J6": 6.0})
    assert n["J1"] == pytest.approx(0.5)  # the baseline's
    assert n["J6"] == pytest.approx(0.5)  # the J6 reference's
    assert math.isnan(normalised({"J6": 3.0}, {"J6": 1.0})["J6"])  # no reference run: not over the baseline
