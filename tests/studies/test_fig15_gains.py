"""The second SOSM gain set (strategy sosm-fig15, scenarios/sosm_gains_fig15.yaml): the paper's Fig. 15 current."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from orchestration.api import load_scenario, run
from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.in_process_model import system_setup
from orchestration.building_studies.strategies import strategy_overrides
from orchestration.case_study.case_config import load_study
from orchestration.case_study.claims import PINNED_SHARE
from orchestration.case_study.objective import simulate as _simulate
from orchestration.case_study.tuning import gain_set_overrides, read_table
from orchestration.engine_hooks import plan_scenario

from ..conftest import PROJECT

STUDY = PROJECT / "scenarios" / "case_study.yaml"


def test_the_gain_file_fits_the_study_and_records_its_tuning():
    study = load_study(STUDY)
    gains, doc = read_gains(study.gain_set_path("sosm-fig15"))
    i_max, obj, tuning = study.gain_set("sosm-fig15")
    assert gains.i_max == i_max == 2.5 and gains.zeta * gains.theta > gains.rho  # Eq. (39)
    lo, hi = tuning.bounds["s_release"]  # the release band (not in the paper) is tuned, within its bounds
    assert lo <= gains.s_release <= hi and doc["units"]["s_release"] == "m/s"
    assert doc["procedure"]["strategy"] == "sosm-fig15"
    # one effective current limit per unit: the controller's own 2.5 A, the isolator the study's 3 A
    over = doc["procedure"]["overrides"]
    assert [o for o in over if o.startswith("controller.i_max=")] == ["controller.i_max=2.5"]
    assert [o for o in over if o.startswith("isolator.i_max=")] == ["isolator.i_max=3.0"]
    assert doc["procedure"]["objective"] == obj.model_dump() and obj.w_saturation > 0
    assert doc["procedure"]["record"] == tuning.record
    assert set(doc["check_other_records"]) == set(study.spec.records)
    rows = read_table(doc["evaluations"]["sosm"])
    assert len(rows) == doc["result"]["evaluations"]
    best = min(rows, key=lambda r: r["J"])  # the file's gains are its best evaluation
    assert (best["lambda"], best["rho"], best["zeta"], best["theta"], best["s_release"]) == (
        gains.lam, gains.rho, gains.zeta, gains.theta, gains.s_release)
    assert best["J"] == doc["result"]["objective"]


@pytest.mark.slow
def test_the_current_varies_within_the_papers_range_on_every_record():
    """In-process, each whole record (the quiet tails count: Kobe's 150 s are mostly tail; about 7 s in all):
    within [0, 2.5] A, at neither end for more than the claim's share, spread over the range."""
    study = load_study(STUDY)
    gains, _ = read_gains(study.gain_set_path("sosm-fig15"))
    lo, hi = study.spec.paper_current_range
    for r in study.spec.records:
        plan = plan_scenario(study.scenario_path(r), gain_set_overrides(study, "sosm-fig15"))
        i = _simulate(system_setup(plan, None, gains), plan).i
        assert lo <= i.min() and i.max() <= hi, r  # the controller clips exactly to [0, i_max]
        # the report's Fig. 15 check: pinned at neither bound (1e-6 A: the clip is exact, the tolerance only
        # keeps the test off the last bit)
        assert np.mean(i >= hi - 1e-6) <= PINNED_SHARE, r
        assert np.mean(i <= lo + 1e-6) <= PINNED_SHARE, r
        # "varies continuously": it reaches both ends and spreads over the range, not two levels: a pinned or
        # two-level current has a 10-90 % span near 0 or near 2.5 A; 0.5 A is a fifth of the range (measured
        # 0.68 A on El Centro, the narrowest, to 2.1 A on Kobe with the shipped gains)
        assert i.min() <= lo + 1e-6 and i.max() >= hi - 1e-6, r
        assert 0.5 <= np.percentile(i, 90) - np.percentile(i, 10) < hi - lo, r
        assert len(np.unique(np.round(i, 3))) > 100, r


@pytest.mark.slow
def test_the_strategy_runs_the_fmu_with_its_own_limit(tmp_path):
    """Through the master: the sosm-fig15 overrides make the controller FMU stop at 2.5 A (the isolator keeps 3 A)."""
    study = load_study(STUDY)
    _, doc = read_gains(study.gain_set_path("sosm-fig15"))
    over = [*gain_set_overrides(study, "sosm-fig15"),
            *strategy_overrides("sosm-fig15", study.spec.i_max, doc["gains"], None), "simulation.stop_time=6"]
    plan = load_scenario(study.scenario_path("elcentro"), over)
    assert plan.parameters["controller"]["i_max"] == 2.5 and plan.parameters["isolator"]["i_max"] == 3.0
    res = run(plan, out=tmp_path / "run")
    assert res.complete
    i = res["controller.i"]
    assert 0.0 <= i.min() and i.max() <= 2.5
    # the in-process model of the same setting gives the same current (rounding: 1e-6 A)
    gains = read_gains(study.gain_set_path("sosm-fig15"))[0]
    ref = _simulate(system_setup(plan, None, gains), plan).i
    np.testing.assert_allclose(i, ref, rtol=0, atol=1e-6)
    # the FMU got the release band (parameter s_release, m/s): without it the same run gives another current
    paper = _simulate(system_setup(plan, None, dataclasses.replace(gains, s_release=0.0)), plan).i
    assert plan.parameters["controller"]["s_release"] == gains.s_release > 0
    assert np.max(np.abs(paper - i)) > 0.1  # A: far above the 1e-6 A agreement above
