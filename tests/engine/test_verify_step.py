"""Step convergence (``run.py --verify-step``): the plant's step halved, the controller's period pinned, each peak's
change in summary.json; a run whose peaks move more than the tolerance is not converged (numerically invalid)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from orchestration.building_report import step_changes
from orchestration.engine_hooks import plan_scenario
from orchestration.step_check import controller_unit, half_step_overrides, step_section

from ..conftest import PROJECT

ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"
COARSE = {"peak_base_displacement_m": 0.010, "peak_drift_m": {"building.drift_1": 0.002},
          "peak_abs_acceleration_m_s2": {"building.a_3": 4.0}, "peak_isolator_force_N": 1000.0}


def test_each_peak_s_change_is_fine_over_coarse_minus_one():
    fine = {"peak_base_displacement_m": 0.0101, "peak_drift_m": {"building.drift_1": 0.002},
            "peak_abs_acceleration_m_s2": {"building.a_3": 3.9}, "peak_isolator_force_N": 1000.0}
    changes = step_changes(COARSE, fine)
    assert changes["peak_base_displacement_m"] == pytest.approx(0.01)
    assert changes["peak_drift_m[building.drift_1]"] == 0.0
    assert changes["peak_abs_acceleration_m_s2[building.a_3]"] == pytest.approx(-0.025)
    assert math.isnan(step_changes(COARSE, {})["peak_isolator_force_N"])  # a peak the fine run lacks


def test_a_run_whose_peaks_move_more_than_the_tolerance_is_not_converged():
    fine = {**COARSE, "peak_abs_acceleration_m_s2": {"building.a_3": 4.2}, "complete": True, "valid": True}
    section, reasons = step_section(COARSE, fine, {"plant_step_s": 1e-3}, 0.01, "half")
    assert section["converged"] is False and section["largest"] == "peak_abs_acceleration_m_s2[building.a_3]"
    assert section["largest_change"] == pytest.approx(0.05)
    assert len(reasons) == 1 and reasons[0].startswith("step not converged") and "report.step_tolerance" in reasons[0]
    section, reasons = step_section(COARSE, {**COARSE, "complete": True}, {}, 0.01, "half")
    assert section["converged"] is True and reasons == []
    section, reasons = step_section(COARSE, {**COARSE, "complete": False, "error": "diverged"}, {}, 0.01, "half")
    assert section["converged"] is False and "did not end (diverged)" in reasons[0]


def test_the_controller_is_the_unit_the_current_role_names_and_its_period_is_pinned():
    plan = plan_scenario(ELCENTRO)
    assert controller_unit(plan) == "controller"
    extra, pinned = half_step_overrides(plan)
    assert extra == ["simulation.step=0.0005", "units.controller.step=0.001"]
    assert pinned["controller_step_s"] == 0.001 and pinned["half_step_s"] == 0.0005
    plan = plan_scenario(ELCENTRO, ("report.current=isolator.F", "simulation.stop_time=4"))  # another role holder
    assert controller_unit(plan) == "isolator"
    assert half_step_overrides(plan)[0][1] == "units.isolator.step=0.001"


def test_a_bad_step_tolerance_is_refused_naming_the_key(tmp_path):
    proc = subprocess.run([sys.executable, "orchestration/run.py", str(ELCENTRO), "--set", "report.step_tolerance=-1",
                           "--out", str(tmp_path / "r"), "--no-plots", "--quiet"], cwd=PROJECT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2 and "report.step_tolerance" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.slow
def test_verify_step_writes_the_changes_and_the_half_step_run(tmp_path):
    out = tmp_path / "r"
    proc = subprocess.run([sys.executable, "orchestration/run.py", str(ELCENTRO), "--set", "simulation.stop_time=2",
                           "--out", str(out), "--no-plots", "--quiet", "--verify-step"], cwd=PROJECT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    step = summary["step_convergence"]
    assert step["plant_step_s"] == 0.001 and step["half_step_s"] == 0.0005 and step["controller_step_s"] == 0.001
    half = json.loads((tmp_path / "r-half-step" / "summary.json").read_text())
    assert half["n_steps"] == 2 * summary["n_steps"]
    expected = half["peak_abs_acceleration_m_s2"]["building.a_3"] / summary["peak_abs_acceleration_m_s2"][
        "building.a_3"] - 1
    assert step["changes"]["peak_abs_acceleration_m_s2[building.a_3]"] == pytest.approx(expected)
    assert step["converged"] == (step["largest_change"] <= 0.01)
    assert summary["valid"] == (step["converged"] and not summary["invalid_reasons"])
    assert "with the plant's step halved" in proc.stdout


@pytest.mark.slow
def test_study_verify_step_gives_each_row_its_change(tmp_path):
    import csv

    from orchestration.study import main

    out = tmp_path / "bench"
    code = main([str(PROJECT / "scenarios" / "controller_benchmark.yaml"), "--out", str(out), "--quiet",
                 "--workers", "1", "--verify-step", "--set", "overrides=[simulation.stop_time=2]",
                 "--set", "records={elcentro: elcentro.yaml}", "--set", "strategies=[passive-off, passive-on]"])
    assert code == 0
    rows = {r["strategy"]: r for r in csv.DictReader(open(out / "criteria.csv"))}
    study = json.loads((out / "study.json").read_text())
    halves = {e["strategy"]: e for e in study["half_step_runs"]}
    assert set(halves) == {"passive-off", "passive-on"} and all(e["ok"] for e in halves.values())
    for s, row in rows.items():
        entry = next(e for e in study["runs"] if e["strategy"] == s)
        changes = entry["step_change"]
        ranked = [f"J{k}" for k in (1, 2, 3, 4, 5, 7, 8)]  # the ranking's criteria: J6 is shown apart
        assert float(row["step_change"]) == pytest.approx(max(abs(changes[j]) for j in ranked))
        assert row["valid"] in ("True", "False")
        half_summary = json.loads((out / halves[s]["folder"] / "summary.json").read_text())
        base_summary = json.loads((out / entry["folder"] / "summary.json").read_text())
        assert half_summary["n_steps"] == 2 * base_summary["n_steps"]
    assert "step change" in (out / "report.md").read_text()
