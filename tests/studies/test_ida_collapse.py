"""Collapse in IDA: limit states on residual drift, drift ratio and collapse; a non-converged OpenSees run
counted as a collapse; the collapse fragility on synthetic data; one tiny end-to-end collapse IDA."""

from __future__ import annotations

import csv
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from orchestration.ida_study.fragility import Fit, Stripe
from orchestration.ida_study.ida_config import IdaSpec, load_ida
from orchestration.ida_study.ida_jobs import COLLAPSE_MARK, residual_drifts, run_status
from orchestration.ida_study.ida_metrics import collapse_margins, exceeded, fragilities, result_row
from orchestration.ida_study.ida_records import ComponentInfo, RunOutcome

from ..conftest import PROJECT, RECORDS

# the message the OpenSees building unit gives (components/physics/opensees_building_core.py), as the master
# reports it: the unit's log line under the failed FMI call
NOT_CONVERGED = ("unit 'building', t = 3.217 s: doStep returned error\n    [building] error: OpenSees building "
                 "(dyke_steel01.py) at t = 3.217 s: OpenSees' transient analysis failed to converge in the step from "
                 "t = 3.217 s (h = 0.001 s, also with 10x shorter steps): failed to converge after: 25 iterations")


def spec_data(**changes) -> dict:
    data = {"suite": {"folder": "records/"}, "intensity": {"measure": "sa", "levels": [0.1, 0.2]},
            "strategies": ["passive-off"], "storey_heights": [0.5, 0.5, 0.5],
            "limit_states": {"res": {"quantity": "residual_drift", "threshold": 0.0025},
                             "dr": {"quantity": "drift_ratio", "threshold": 0.0128},
                             "collapse": {"quantity": "collapse", "threshold": 0.1}}}
    data.update(changes)
    return data


def load(tmp_path: Path, data: dict) -> tuple:
    path = tmp_path / "ida.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_ida(path)


def test_limit_states_on_residual_drift_drift_ratio_and_collapse_are_read(tmp_path):
    loaded, problems, _ = load(tmp_path, spec_data(collapse_margin={"s_mt": 1.07, "source": "SDC Dmax at 0.84 s"}))
    assert not problems
    spec = loaded.spec
    assert {n: ls.quantity for n, ls in spec.limit_states.items()} == {
        "res": "residual_drift", "dr": "drift_ratio", "collapse": "collapse"}
    assert spec.storey_heights == [0.5, 0.5, 0.5] and spec.collapse_margin.s_mt == 1.07


@pytest.mark.parametrize(("changes", "words"), [
    ({"storey_heights": None}, "give storey_heights"),
    ({"storey_heights": [0.5, -0.5, 0.5]}, "storey_heights must be positive"),
    ({"limit_states": {"c": {"quantity": "colapse", "threshold": 0.1}}}, "collapse"),
    ({"limit_states": {"c": {"quantity": "collapse", "threshold": 0.0}}}, "greater than 0"),
    ({"intensity": {"measure": "pga", "levels": [0.1]}, "collapse_margin": {"s_mt": 1.0, "source": "x"}},
     "needs intensity.measure 'sa'"),
    ({"collapse_margin": {"s_mt": 1.0}}, "source"),
])
def test_bad_collapse_settings_are_problems_naming_the_key(tmp_path, changes, words):
    loaded, problems, _ = load(tmp_path, spec_data(**changes))
    assert loaded is None and problems
    assert words in " ".join(f"{p.key} {p.message}" for p in problems)


def test_a_run_that_opensees_cannot_converge_counts_as_a_collapse_not_an_error():
    assert run_status(False, NOT_CONVERGED, "failed") == "collapsed"
    other = "unit 'building', t = 1 s: doStep returned error\n    something else"
    assert run_status(False, other, "failed") == "failed"
    assert run_status(True, None, "ok") == "ok"
    assert COLLAPSE_MARK in NOT_CONVERGED

    comp = ComponentInfo("rec", "rec", "", "synthetic", (0.0, 10.0), 10.0, 0.1, 0.2)
    collapsed = RunOutcome("rec/0.4/passive-off", True, "finished",
                           {"status": run_status(False, NOT_CONVERGED, "failed"), "error": NOT_CONVERGED,
                            "end_time_s": 3.217, "metrics": {}}, None, 1.0, "w")
    failed = RunOutcome("rec/0.4/sosm", True, "finished",
                        {"status": "failed", "error": "a unit could not be loaded", "end_time_s": 0.0, "metrics": {}},
                        None, 1.0, "w")
    row_c = result_row(comp, "sa", 0.4, "passive-off", collapsed, None)
    row_f = result_row(comp, "sa", 0.4, "sosm", failed, None)
    assert row_c["status"] == "collapsed" and row_c["drift_1_mm"] is None
    for quantity in ("collapse", "drift_ratio", "residual_drift", "storey_drift"):  # every limit state exceeded
        assert exceeded(row_c, quantity, 0.1, [0.5, 0.5, 0.5]) is True
        assert exceeded(row_f, quantity, 0.1, [0.5, 0.5, 0.5]) is None  # a failure is left out of the stripes
    # in the stripes: the collapse counts at its level, the failure not at all
    spec = IdaSpec.model_validate(spec_data(strategies=["passive-off", "sosm"], intensity={"levels": [0.4]}))
    fits = fragilities([row_c, row_f], spec)
    assert fits["collapse"]["passive-off"].stripes == [Stripe(0.4, 1, 1)]
    assert fits["collapse"]["sosm"].stripes == [Stripe(0.4, 0, 0)]


def test_drift_ratio_uses_each_storeys_height():
    row = {"status": "ok", "drift_1_mm": 40.0, "drift_2_mm": 30.0, "drift_3_mm": 10.0}
    # 40 mm / 0.5 m = 8 %, 30 mm / 0.25 m = 12 %
    assert exceeded(row, "collapse", 0.10, [0.5, 0.25, 0.5]) is True
    assert exceeded(row, "collapse", 0.10, [0.5, 0.5, 0.5]) is False
    assert exceeded(row, "drift_ratio", 0.079, [0.5, 0.5, 0.5]) is True


def test_residual_drift_removes_the_elastic_and_viscous_parts():
    """A storey with plastic offset r: shear = k (d - r) + c dv - (P/h) d; the function must give r back."""
    k, c, pd = [5e5, 7e5, 6e5], [120.0, 50.0, 40.0], [5e3, 3e3, 1e3]
    r, d, v = [-4.2e-3, 1.1e-3, 0.0], [-3.0e-3, 2.5e-3, 0.4e-3], [0.01, 0.03, -0.02, 0.05]
    ts = {f"building.v_{j}": np.array([0.0, v[j]]) for j in range(4)}
    for j in range(1, 4):
        ts[f"building.drift_{j}"] = np.array([0.0, d[j - 1]])
        shear = k[j - 1] * (d[j - 1] - r[j - 1]) + c[j - 1] * (v[j] - v[j - 1]) - pd[j - 1] * d[j - 1]
        ts[f"building.shear_{j}"] = np.array([0.0, shear])
    out = residual_drifts(ts, {"k": k, "c": c, "pdelta": pd})
    for j in range(1, 4):
        assert out[f"residual_drift_{j}_mm"] == pytest.approx(1e3 * r[j - 1], abs=1e-9)
    assert out["residual_drift_max_mm"] == pytest.approx(4.2, abs=1e-9)
    # another building unit (no constants): the drift at the end of the run
    assert residual_drifts(ts, None)["residual_drift_1_mm"] == pytest.approx(-3.0)


def test_collapse_fragility_recovers_a_known_median_and_dispersion_synthetic():
    """SYNTHETIC data: each of 3000 records collapses at a lognormal intensity (median 0.35 g, beta 0.45);
    an IDA ladder runs every record at every level. The maximum-likelihood fit through the study's
    stripes must give both back within the sampling error, and the margin is the median over S_MT."""
    rng = np.random.default_rng(7)
    theta, beta, n = 0.35, 0.45, 3000
    capacity = theta * np.exp(beta * rng.standard_normal(n))
    levels = [0.05, 0.1, 0.2, 0.3, 0.4, 0.6, 0.9, 1.4]
    spec = IdaSpec.model_validate(spec_data(intensity={"levels": levels},
                                            collapse_margin={"s_mt": 0.7, "source": "synthetic"}))
    rows = []
    for i in range(n):
        for x in levels:  # 'drift ratio' beyond 10 % exactly when the level passes the record's capacity
            rows.append({"record_id": f"r{i}", "im_unscaled": 0.1, "strategy": "passive-off", "intensity": x,
                         "status": "ok", "drift_1_mm": 60.0 if x > capacity[i] else 10.0, "drift_2_mm": 1.0,
                         "drift_3_mm": 1.0})
    fit = fragilities(rows, spec)["collapse"]["passive-off"]
    assert fit.ok
    assert fit.theta == pytest.approx(theta, rel=0.04)
    assert fit.beta == pytest.approx(beta, rel=0.08)
    # The interval of the median treats the stripes as independent (multiple-stripe analysis, a fresh set of
    # records per level); with such data it covers the true median. (The same records at every level, as
    # in an IDA, make the stripes correlated and the interval too narrow: docs/structures.md.)
    fresh = [{"record_id": f"r{i}-{x}", "im_unscaled": 0.1, "strategy": "passive-off", "intensity": x,
              "status": "ok", "drift_1_mm": 60.0 if x > theta * math.exp(beta * rng.standard_normal()) else 10.0,
              "drift_2_mm": 1.0, "drift_3_mm": 1.0} for x in levels for i in range(300)]
    msa = fragilities(fresh, spec)["collapse"]["passive-off"]
    lo, hi = msa.theta_interval()
    assert lo < theta < hi and hi / lo < 1.2
    (margin,) = collapse_margins({"collapse": {"passive-off": fit}}, spec, rows)
    assert margin["margin"] == pytest.approx(fit.theta / 0.7) and margin["margin_kind"] == "CMR (FEMA P695)"
    # without S_MT: the ratio to the records' own median intensity, labelled as not the CMR
    spec2 = IdaSpec.model_validate(spec_data(intensity={"levels": levels}))
    (other,) = collapse_margins({"collapse": {"passive-off": fit}}, spec2, rows)
    assert other["margin"] == pytest.approx(fit.theta / 0.1) and "not FEMA P695" in other["margin_kind"]


def test_no_collapse_gives_no_margin_but_says_so():
    spec = IdaSpec.model_validate(spec_data())
    fit = Fit("none-exceed", stripes=[Stripe(0.1, 4, 0)], note="no run exceeded it up to 0.1")
    (m,) = collapse_margins({"collapse": {"sosm": fit}, "dr": {"sosm": fit}}, spec, [])
    assert m["fit"] == "none-exceed" and math.isnan(m["margin"])


@pytest.mark.slow
def test_tiny_collapse_ida_end_to_end(tmp_path):
    """Northridge on the yielding building, passive-off, two levels: elastic at the first (residual drift 0
    by the unit's own law), past a 3 % drift ratio at the second (collapse by drift ratio)."""
    folder = tmp_path / "suite"
    folder.mkdir()
    shutil.copy(RECORDS / "northridge_1994_sylmar_ns.csv", folder)
    study = {
        "name": "mini-collapse", "scenario": str(PROJECT / "scenarios" / "kobe_yielding.yaml"),
        "suite": {"folder": str(folder)}, "time_scale": 0.2, "window": {"tail_s": 0.5},
        "intensity": {"measure": "sa", "period_s": 0.8396, "levels": [0.02, 0.6]},
        "strategies": ["passive-off"], "storey_heights": [0.5, 0.5, 0.5],
        "limit_states": {"collapse": {"quantity": "collapse", "threshold": 0.03},
                         "res": {"quantity": "residual_drift", "threshold": 0.001}},
        "output": str(tmp_path / "studies"), "workers": 1,
    }
    path = tmp_path / "ida.yaml"
    path.write_text(yaml.safe_dump(study))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "ida.py"), str(path), "--out", str(out),
                           "--quiet"], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "MRE_COSIM_CODE_VERSION": "tests"})
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(open(out / "results.csv")))
    low, high = (next(r for r in rows if float(r["intensity"]) == x) for x in (0.02, 0.6))
    assert low["status"] == high["status"] == "ok"
    k1, fy1 = 516000.0, 3300.0
    assert float(low["drift_1_mm"]) < 1e3 * fy1 / k1  # elastic: no plastic offset
    assert abs(float(low["residual_drift_max_mm"])) < 1e-6
    assert float(high["drift_1_mm"]) > 0.03 * 500.0 and float(high["residual_drift_max_mm"]) > 1.0
    margins = list(csv.DictReader(open(out / "collapse.csv")))
    assert [m["strategy"] for m in margins] == ["passive-off"]
    assert margins[0]["fit"] == "separated" and "not FEMA P695" in margins[0]["margin_kind"]
    fragility = {r["limit_state"]: r for r in csv.DictReader(open(out / "fragility.csv"))}
    assert fragility["collapse"]["stripes"] == "0.02:0/1 0.6:1/1"
    assert "## Collapse" in (out / "report.md").read_text()


@pytest.mark.slow
def test_the_shipped_collapse_study_is_valid():
    from orchestration.ida_study.ida_plan import prepare_ida

    path = PROJECT / "scenarios" / "ida_yielding.yaml"
    prepared = prepare_ida(path, *load_ida(path))
    try:
        assert len(prepared.components) == 4 and len(prepared.plans) == 12
        assert prepared.storeys == {"k": [516000.0, 684000.0, 684000.0], "c": [125.0, 50.0, 50.0],
                                    "pdelta": [0.0, 0.0, 0.0]}  # Dyke et al. (1996), the paper's Table 3
        assert "collapse" in {ls.quantity for ls in prepared.study.spec.limit_states.values()}
    finally:
        prepared.cleanup()
