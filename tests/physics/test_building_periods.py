"""The building's periods: fixed base and on its isolators, and each run's ``periods`` section and console line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import eigh

from components.physics.building_periods import fixed_base_periods, isolated_period, isolator_secant_stiffness
from components.physics.mre_isolator_core import TABLE2, isolator_force
from components.physics.shear_building_core import BuildingParams
from orchestration.building_report import periods_section
from orchestration.master.report import RunDescription
from orchestration.run import period_lines

# Dyke et al. (1996) three-storey model, Table 3 of the paper: 98.3 kg per floor, storeys 516, 684, 684 kN/m
M_FLOOR = 98.3
K1, K2, K3 = 516e3, 684e3, 684e3
PAPER_UNITS = {"ground": "GroundMotionSource", "building": "ShearBuilding", "isolator": "MreIsolator",
               "controller": "SosmCurrentController"}


def test_the_dyke_building_is_the_published_model():
    b = BuildingParams.dyke()
    assert b.m[1:] == (M_FLOOR,) * 3 and b.k[1:] == (K1, K2, K3)


def test_fixed_base_periods_are_those_of_the_three_storeys_on_a_fixed_base():
    K = np.array([[K1 + K2, -K2, 0.0], [-K2, K2 + K3, -K3], [0.0, -K3, K3]])
    M = M_FLOOR * np.eye(3)
    expected = 2 * np.pi / np.sqrt(eigh(K, M, eigvals_only=True))
    assert fixed_base_periods(BuildingParams.dyke()) == pytest.approx(sorted(expected, reverse=True), rel=1e-12)


def test_isolated_period_of_a_two_level_building_is_the_hand_solution():
    m0, m1, k1 = 98.3, 150.0, 4e5
    k_iso = isolator_secant_stiffness(TABLE2, 2, 0.0, 0.008)
    assert k_iso == pytest.approx(isolator_force(0.008, 0.0, 0.0, TABLE2, 0.0, 2) / 0.008, rel=1e-12)
    a, det = (k_iso + k1) / m0 + k1 / m1, k_iso * k1 / (m0 * m1)
    lam = (a - math.sqrt(a * a - 4 * det)) / 2
    building = BuildingParams(m=(m0, m1), k=(0.0, k1), c=(0.0, 0.0))
    assert isolated_period(building, TABLE2, 2, 0.0, 0.008) == pytest.approx(2 * math.pi / math.sqrt(lam), rel=1e-10)


@pytest.mark.parametrize("current", [0.0, 3.0])
def test_isolated_period_of_the_dyke_building_is_the_first_mode_with_the_base_spring(current):
    k_iso = isolator_secant_stiffness(TABLE2, 2, current, 0.008)
    K = np.array([[k_iso + K1, -K1, 0, 0], [-K1, K1 + K2, -K2, 0], [0, -K2, K2 + K3, -K3], [0, 0, -K3, K3]])
    lam = eigh(K, M_FLOOR * np.eye(4), eigvals_only=True)
    expected = 2 * math.pi / math.sqrt(lam[0])
    assert isolated_period(BuildingParams.dyke(), TABLE2, 2, current) == pytest.approx(expected, rel=1e-10)


def test_a_run_s_periods_section_states_units_currents_and_the_reference_displacement():
    run = RunDescription({}, PAPER_UNITS, set_values={"isolator": {"n_isolators": 2, "i_max": 2.0}})
    section = periods_section(run)
    b = BuildingParams.dyke()
    assert section["fixed_base_s"] == fixed_base_periods(b)
    assert section["isolated_0A_s"] == isolated_period(b, TABLE2, 2, 0.0, 0.008)
    assert section["isolated_i_max_s"] == isolated_period(b, TABLE2, 2, 2.0, 0.008)
    assert section["i_max_A"] == 2.0 and section["reference_displacement_m"] == 0.008
    assert section["isolated_0A_s"] > section["isolated_i_max_s"]  # the current stiffens the isolators
    line, = period_lines({"periods": section})
    assert line.startswith("periods: fixed base 0.184, 0.0633, 0.0423 s; isolated T1 ")
    assert "at 0 A" in line and "at 2 A" in line and "8 mm" in line


@pytest.mark.parametrize(("units", "values", "why"), [
    ({**PAPER_UNITS, "isolator": "BoucWenIsolator"}, {}, "isolator is BoucWenIsolator"),
    (PAPER_UNITS, {"building": {"hysteresis": "steel01"}}, "building parameter hysteresis"),
    ({**PAPER_UNITS, "lag": "CurrentLag"}, {}, "units the in-process model lacks: lag"),
])
def test_a_system_the_in_process_model_lacks_says_why_it_has_no_periods(units, values, why):
    section = periods_section(RunDescription({}, units, set_values=values))
    assert list(section) == ["note"] and why in section["note"]
    assert period_lines({"periods": section}) == [f"periods: {section['note']}"]
    assert period_lines({}) == []
