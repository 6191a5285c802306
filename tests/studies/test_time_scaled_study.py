"""The time-scaled reading of the paper's "scaled down by 0.5" (scenarios/case_study_time_scaled.yaml)."""

from __future__ import annotations

import numpy as np
import pytest

from components.physics.ground_motion_core import G, read_record
from orchestration.api import load_scenario, run
from orchestration.building_studies.in_process_model import system_setup
from orchestration.building_studies.run_settings import run_overrides
from orchestration.case_study.case_config import load_study
from orchestration.case_study.case_records import RecordInfo
from orchestration.case_study.case_report import ground_reading
from orchestration.engine_hooks import plan_scenario

from ..conftest import PROJECT

STUDY = PROJECT / "scenarios" / "case_study_time_scaled.yaml"


def test_every_record_plays_at_full_amplitude_in_half_its_time():
    """The in-process playback against each record file read on its own: duration halves, amplitude x1."""
    study = load_study(STUDY)
    assert set(study.spec.records) == {"elcentro", "hachinohe", "northridge", "kobe"}
    for r in study.spec.records:
        plan = plan_scenario(study.scenario_path(r), run_overrides(study.spec))
        ground = plan.parameters["ground"]
        assert float(ground["scale"]) == 1.0 and float(ground["time_scale"]) == 0.5
        record = read_record(plan.data_files["ground.record"])
        motion = system_setup(plan, 0.0).motion
        assert motion.duration == pytest.approx(record.duration / 2, rel=1e-12)
        tau = record.time[1:-1:97]  # sample instants of the record
        played = np.array([motion.acceleration(t) for t in tau / 2])
        # exactly the record's samples in m/s² (no interpolation at a sample instant; rounding only)
        np.testing.assert_allclose(played, G * record.accel_g[1:-1:97], rtol=1e-12, atol=1e-12)
        assert motion.acceleration(record.duration / 2 + 0.01) == 0.0  # silent once the compressed record is over


def test_the_co_simulation_plays_the_compressed_record(tmp_path):
    """The GroundMotionSource FMU under the study's overrides: ag(t) is the record at 2t, unscaled."""
    study = load_study(STUDY)
    path = study.scenario_path("elcentro")
    plan = load_scenario(path, [*study.spec.overrides, "simulation.stop_time=3", "controller.mode=passive"])
    res = run(plan, out=tmp_path / "run")
    assert res.complete
    record = read_record(plan.data_files["ground.record"])
    expected = G * np.interp(2 * res.time, record.time, record.accel_g)
    # the FMU interpolates linearly between the same samples: equal to rounding (1e-9 of the 9 m/s² peak)
    np.testing.assert_allclose(res["ground.ag"], expected, rtol=0, atol=1e-9)
    # and this is not the amplitude reading: ×0.5 at the record's own speed differs by metres per s²
    amplitude = 0.5 * G * np.interp(res.time, record.time, record.accel_g)
    assert np.max(np.abs(res["ground.ag"] - amplitude)) > 1.0


def test_the_report_names_the_reading():
    def study(scale: float, time_scale: float) -> dict[str, RecordInfo]:
        return {"a": RecordInfo("a.yaml", 10.0, [1.0, 1.0], "a.csv", scale, time_scale, 2)}

    assert "time-scaled reading" in ground_reading(study(1.0, 0.5))
    assert "amplitude reading" in ground_reading(study(0.5, 1.0))
    assert "fundamental frequency of smart structure" in ground_reading(study(0.5, 1.0))  # the paper's sentence
