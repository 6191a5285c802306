"""Base-floor sensitivity (study.py --base-sensitivity): conclusions on made-up peaks, a tiny run end to end."""

from __future__ import annotations

import csv
import subprocess
import sys

import pytest

from components.physics.monolithic import SystemSetup
from components.physics.shear_building_core import BuildingParams
from orchestration.building_studies.in_process_model import system_setup
from orchestration.building_studies.run_settings import run_overrides
from orchestration.case_study.base_sensitivity import conclusions
from orchestration.case_study.case_config import load_study
from orchestration.case_study.objective import peak_values
from orchestration.engine_hooks import plan_scenario
from orchestration.inprocess import simulate_coupled

from ..conftest import PROJECT

STUDY = PROJECT / "scenarios" / "case_study.yaml"


def row(variant: str, record: str, strategy: str, a3: float, d: float, s_bound: float = 0.0, i_max: float = 2.5
        ) -> dict:
    return {"variant": variant, "record": record, "strategy": strategy, "a3": a3, "d": d, "s_bound": s_bound,
            "i_min": 0.0, "i_max": i_max}


def test_conclusions_hold_and_fail_where_they_must():
    rows = []
    for v, sosm_a3, fig_share in (("ok", 2.0, 0.1), ("bad", 9.95, 0.5)):
        for rec in ("x", "y"):
            rows += [row(v, rec, "passive-off", 10.0, 1.0), row(v, rec, "passive-on", 3.0, 0.5),
                     row(v, rec, "sosm", sosm_a3 if rec == "y" else 2.0, 0.4),
                     row(v, rec, "sosm-fig15", 5.0, 0.6, s_bound=fig_share)]
    c = conclusions(rows, ["x", "y"], 2.5)
    assert c["ok"]["sosm_reduces"]["holds"] is True and c["ok"]["sosm_vs_on"]["signs"] == "−−"
    assert c["bad"]["sosm_reduces"]["holds"] is False  # 9.95 against 10: a 0.5 % tie is no reduction
    assert c["bad"]["sosm_vs_on"]["signs"] == "−+"
    assert c["ok"]["fig15_current"]["holds"] is True and c["bad"]["fig15_current"]["holds"] is False  # 50 % pinned
    assert c["ok"]["fig15_reduces"]["holds"] is True
    rows[-1] = row("bad", "y", "sosm-fig15", 5.0, 0.6, i_max=3.0)  # above 2.5 A
    assert conclusions(rows, ["x", "y"], 2.5)["bad"]["fig15_current"]["holds"] is False


@pytest.mark.slow
def test_a_tiny_sensitivity_run_through_the_cli(tmp_path):
    out = tmp_path / "sens"
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "study.py"), str(STUDY),
                           "--base-sensitivity", "--window", "1.5", "--set", "records={elcentro: elcentro.yaml}",
                           "--out", str(out), "--quiet"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    with open(out / "base_sensitivity.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 7 * 4  # 7 base-floor variants x 4 strategies, one record
    assert "| k_b = 5 kN/m |" in (out / "base_sensitivity.md").read_text()
    # one row against an independent in-process run with the base floor set by hand (same cores: rounding only)
    [got] = [r for r in rows if r["variant"] == "k_b = 5 kN/m" and r["strategy"] == "passive-on"]
    study = load_study(STUDY)
    plan = plan_scenario(study.scenario_path("elcentro"), run_overrides(study.spec))
    b = BuildingParams.dyke()
    building = BuildingParams(m=b.m, k=(5.0e3, *b.k[1:]), c=b.c)
    motion = system_setup(plan, 0.0).motion
    sim = plan.loaded.scenario.simulation
    tr = simulate_coupled(SystemSetup(motion, building, passive_current=3.0), sim.step, round(1.5 / sim.step),
                          sim.algorithm, **({"inputs": sim.inputs} if hasattr(sim, "inputs") else {}))
    want = peak_values(tr)
    assert float(got["a3"]) == pytest.approx(want["a3"], rel=1e-9)
    assert float(got["x0"]) == pytest.approx(want["x0"], rel=1e-9)
    # and the stiff base floor did change the response against the default (k_b = 0)
    [default] = [r for r in rows if r["variant"] == "m_b ×1 (default)" and r["strategy"] == "passive-on"]
    assert float(default["x0"]) != pytest.approx(float(got["x0"]), rel=1e-3)
