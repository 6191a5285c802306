"""A tiny robustness study against runs done directly with the variation written by hand."""

from __future__ import annotations

import csv
import json

import pytest

from orchestration.building_studies.run_metrics import read_timeseries
from orchestration.case_study.benchmark_criteria import raw_criteria
from orchestration.case_study.case_jobs import BENCHMARK_OUTPUTS_OVERRIDE
from orchestration.case_study.case_run import main
from orchestration.engine_hooks import run_scenario

from ..conftest import PROJECT

pytestmark = pytest.mark.slow  # a study of 2 strategies x 3 plants on a 2 s window, then 3 direct runs

SCENARIOS = PROJECT / "scenarios"
MASSES = [98.3, 98.3, 98.3, 98.3]  # the building FMU's defaults (Dyke et al. 1996, base floor 98.3 kg)
LAGGED = ["ground.ag -> building.ag", "building.x_0 -> isolator.x", "building.v_0 -> isolator.v",
          "controller.i -> current_lag.i_cmd", "current_lag.i -> isolator.i", "isolator.F -> building.F",
          {"source": "building.x_0", "target": "controller.x", "delayed": True},
          {"source": "building.v_0", "target": "controller.v", "delayed": True},
          {"source": "building.arel_0", "target": "controller.a", "delayed": True}]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("robustness")
    path = tmp / "tiny.yaml"
    path.write_text(f"""\
extends: {SCENARIOS / 'controller_benchmark.yaml'}
name: tiny_robustness
strategies: [passive-off, sosm]
overrides: [simulation.stop_time=2]
timeseries: true
workers: 2
output: {tmp / 'studies'}
robustness:
  variants:
    heavy: {{scale: {{building.m_0: 1.2, building.m_1: 1.2, building.m_2: 1.2, building.m_3: 1.2}}}}
    lag: {{current_lag: 0.01}}
""")
    folder = tmp / "out"
    assert main([str(path), "--set", f"records={{elcentro: {SCENARIOS / 'elcentro.yaml'}}}", "--out", str(folder),
                 "--quiet"]) == 0
    rows = list(csv.DictReader((folder / "robustness.csv").open()))
    return folder, json.loads((folder / "study.json").read_text()), rows, tmp


def _row(rows, strategy, variant):
    return next(r for r in rows if r["strategy"] == strategy and r["variant"] == variant and r["record"] == "elcentro")


def test_variants_equal_runs_with_the_variation_written_by_hand(study):
    folder, doc, rows, tmp = study
    assert {(r["strategy"], r["variant"]) for r in rows} == {(s, v) for s in ("passive-off", "sosm")
                                                             for v in ("nominal", "heavy", "lag")}
    nominal = {e["strategy"]: e for e in doc["runs"]}
    base = [*doc["run_overrides"], *nominal["sosm"]["overrides"]]
    off = raw_criteria(read_timeseries(folder / nominal["passive-off"]["folder"] / "timeseries.csv"), MASSES)
    heavy = [f"building.m_{j}={m * 1.2!r}" for j, m in enumerate(MASSES)]
    lag = [f"units.current_lag.fmu={PROJECT / 'fmus' / 'CurrentLag.fmu'}", "units.current_lag.parameters.tau=0.01",
           f"connections={json.dumps(LAGGED)}"]
    variant_runs = {(e["strategy"], e["variant"]): e for e in doc["variant_runs"]}
    for name, extra in (("heavy", heavy), ("lag", lag)):
        out = tmp / f"direct-{name}"
        run_scenario(SCENARIOS / "elcentro.yaml", (*base, *extra, BENCHMARK_OUTPUTS_OVERRIDE), out, plots=False)
        direct = (out / "timeseries.csv").read_bytes()
        assert direct == (folder / variant_runs[("sosm", name)]["folder"] / "timeseries.csv").read_bytes()
        raw = raw_criteria(read_timeseries(out / "timeseries.csv"), MASSES)
        row = _row(rows, "sosm", name)
        nom = _row(rows, "sosm", "nominal")
        for j in ("J3", "J4", "J5"):
            # over passive-off, NOMINAL plant; the table's J comes from every step in float64 (the run's numbers),
            # the by-hand one from the CSV's 12 significant digits: they agree to about 1e-11
            assert float(row[j]) == pytest.approx(raw[j] / off[j], rel=1e-9)
            assert float(row[f"{j}_change_pct"]) == pytest.approx(100 * (float(row[j]) / float(nom[j]) - 1), rel=1e-9)
    # the lag changes an SOSM run; a constant 0 A does not notice it
    assert _row(rows, "sosm", "lag")["J5"] != _row(rows, "sosm", "nominal")["J5"]
    assert _row(rows, "passive-off", "lag")["J5"] == "1.0"


def test_controllers_keep_their_nominal_design(study):
    """A variant changes the plant only: every controller override of a variant run is its nominal run's."""
    _, doc, _, _ = study
    nominal = {e["strategy"]: e for e in doc["runs"]}
    for e in doc["variant_runs"]:
        mine = {o for o in e["overrides"] if o.startswith(("controller.", "units.controller."))}
        assert mine == {o for o in nominal[e["strategy"]]["overrides"] if o.startswith(("controller.",
                                                                                        "units.controller."))}
        assert not any(o.startswith(("building.", "isolator.")) for o in nominal[e["strategy"]]["overrides"])


def test_report_has_the_robustness_section(study):
    folder, _, _, _ = study
    report = (folder / "report.md").read_text()
    assert "## Robustness" in report and "Worst degradation per strategy" in report
    assert "passive-off on the nominal plant" in report


@pytest.fixture(scope="module")
def nominal_study(tmp_path_factory):
    """The shipped robustness file's coil-lag factor and the paper's law, on the nominal plant, 1.5 s of El Centro."""
    tmp = tmp_path_factory.mktemp("robustness-nominal")
    path = tmp / "tiny.yaml"
    path.write_text(f"""\
extends: {SCENARIOS / 'controller_robustness.yaml'}
name: tiny_nominal_robustness
strategies: [passive-off, sosm]
overrides: [simulation.stop_time=1.5]
timeseries: true
workers: 2
output: {tmp / 'studies'}
""")
    folder = tmp / "out"
    assert main([str(path), "--set", f"records={{elcentro: {SCENARIOS / 'nominal_plant_elcentro.yaml'}}}",
                 "--set", "robustness.variants={lag-x3: {scale: {coil.tau: 3.0}}, paper-law: {plant: {isolator: {fmu: "
                 + str(PROJECT / "fmus" / "MreIsolator.fmu") + ", parameters: {n_isolators: 2}}}}}",
                 "--out", str(folder), "--quiet"]) == 0
    rows = list(csv.DictReader((folder / "robustness.csv").open()))
    return folder, json.loads((folder / "study.json").read_text()), rows, tmp


def test_lag_factor_and_papers_law_equal_runs_written_by_hand(nominal_study):
    folder, doc, rows, tmp = nominal_study
    nominal = {e["strategy"]: e for e in doc["runs"]}
    base = [*doc["run_overrides"], *nominal["sosm"]["overrides"]]
    by_hand = {"lag-x3": [f"coil.tau={3.0 * (1 / 50)!r}"],  # 3 x the nominal plant's tau = 1/eta, eta = 50 1/s
               "paper-law": [f"units.isolator.fmu={PROJECT / 'fmus' / 'MreIsolator.fmu'}",
                             'units.isolator.parameters={"n_isolators": 2}', "isolator.i_max=3.0"]}
    variant_runs = {(e["strategy"], e["variant"]): e for e in doc["variant_runs"]}
    for name, extra in by_hand.items():
        out = tmp / f"direct-{name}"
        run_scenario(SCENARIOS / "nominal_plant_elcentro.yaml", (*base, *extra, BENCHMARK_OUTPUTS_OVERRIDE), out,
                     plots=False)
        assert (out / "timeseries.csv").read_bytes() == (
            folder / variant_runs[("sosm", name)]["folder"] / "timeseries.csv").read_bytes()
    # a slower coil changes an SOSM run, not a constant 0 A; the paper's law changes both
    assert _row(rows, "sosm", "lag-x3")["J5"] != _row(rows, "sosm", "nominal")["J5"]
    assert _row(rows, "passive-off", "lag-x3")["J5"] == "1.0"
    assert _row(rows, "passive-off", "paper-law")["J3"] != "1.0"
    ts = read_timeseries(folder / nominal["sosm"]["folder"] / "timeseries.csv")
    assert "coil.i" in ts and not (ts["coil.i"] == ts["controller.i"]).all()  # the device current lags the command
