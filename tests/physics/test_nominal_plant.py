"""The nominal plant (scenarios/nominal_plant.yaml): one file the benchmark, robustness and per-controller IDA share;
the record files on it agree with the paper's; its coil lag, its currents and its sweep."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orchestration.building_studies.in_process_model import NotMonolithic, monolithic_problem, system_setup
from orchestration.building_studies.run_metrics import read_timeseries
from orchestration.case_study.case_config import load_study
from orchestration.case_study.case_run import main as study_main
from orchestration.case_study.current_sweep import cosimulated_peaks
from orchestration.engine_hooks import plan_scenario, run_scenario
from orchestration.ida_study.ida_config import load_ida
from orchestration.master.yaml_source import load_tree

from ..conftest import PROJECT

SCENARIOS = PROJECT / "scenarios"
RECORDS = ("elcentro", "hachinohe", "northridge", "kobe")
PAIRS = (*RECORDS, "kobe_yielding")  # each paper scenario and its nominal-plant twin
ETA_DYKE_1996 = 50.0  # [1/s] the MR damper's first-order filter (Dyke, Spencer, Sain & Carlson 1996)


@pytest.mark.parametrize("record", PAIRS)
def test_a_record_on_the_nominal_plant_is_the_papers_record_with_only_the_plant_changed(record):
    paper, _ = load_tree(SCENARIOS / f"{record}.yaml")
    nominal, _ = load_tree(SCENARIOS / f"nominal_plant_{record}.yaml")
    assert nominal["units"]["ground"] == paper["units"]["ground"]  # record, scale 0.5
    # the same record length and scheme; the plant couples at 0.25 ms while the controller keeps the paper's 1 ms
    assert {k: v for k, v in nominal["simulation"].items() if k != "step"} == \
        {k: v for k, v in paper["simulation"].items() if k != "step"}
    assert (nominal["simulation"]["step"], paper["simulation"]["step"]) == (0.00025, 0.001)
    assert nominal["limits"] == paper["limits"]
    assert nominal["units"]["building"] == paper["units"]["building"]
    assert nominal["units"]["controller"] == {**paper["units"]["controller"], "step": paper["simulation"]["step"]}
    assert nominal["units"]["isolator"]["fmu"] == "../fmus/BoucWenIsolator.fmu"
    assert paper["units"]["isolator"]["fmu"] == "../fmus/MreIsolator.fmu"
    record_labels = {k: v for k, v in paper["report"]["labels"].items() if k.startswith("ground.record=")}
    assert record_labels and all(nominal["report"]["labels"][k] == v for k, v in record_labels.items())


def test_the_coil_lag_is_dykes_filter_and_sits_between_command_and_device():
    tree, _ = load_tree(SCENARIOS / "nominal_plant.yaml")
    assert tree["units"]["coil"]["fmu"] == "../fmus/CurrentLag.fmu"
    assert tree["units"]["coil"]["parameters"]["tau"] == pytest.approx(1 / ETA_DYKE_1996, rel=1e-12)
    conns = [c for c in tree["connections"] if isinstance(c, str)]
    assert "controller.i -> coil.i_cmd" in conns and "coil.i -> isolator.i" in conns
    assert "controller.i -> isolator.i" not in conns
    plan = plan_scenario(SCENARIOS / "nominal_plant_elcentro.yaml", ("simulation.stop_time=0.01",))
    assert plan.descriptions["isolator"].model_identifier == "BoucWenIsolator"
    assert plan.descriptions["coil"].model_identifier == "CurrentLag"
    recorded = {f"{u}.{v}" for u, v in plan.recorded}
    assert {"controller.i", "coil.i"} <= recorded  # both the command and the device current
    assert (str(plan.report.current), str(plan.report.device_current)) == ("controller.i", "coil.i")


def test_the_studies_run_the_plant_the_docs_say():
    """The benchmark and robustness records and the per-controller IDA: the nominal plant; the case study, the
    Kobe quick start and the other IDA studies: the paper's system (docs/studies.md, "Plants")."""
    bench = load_study(SCENARIOS / "controller_benchmark.yaml")
    rob = load_study(SCENARIOS / "controller_robustness.yaml")
    case = load_study(SCENARIOS / "case_study.yaml")
    for study in (bench, rob):
        assert {r: study.scenario_path(r).name for r in study.spec.records} == {
            r: f"nominal_plant_{r}.yaml" for r in RECORDS}
        assert not study.spec.reference.enabled  # the Radau reference models the paper's system only
    assert {r: case.scenario_path(r).name for r in case.spec.records} == {r: f"{r}.yaml" for r in RECORDS}
    assert load_tree(SCENARIOS / "kobe.yaml")[0]["units"]["isolator"]["fmu"] == "../fmus/MreIsolator.fmu"
    for name, scenario in (("ida_controllers", "nominal_plant.yaml"), ("ida", "isolated_building.yaml"),
                           ("ida_shipped", "isolated_building.yaml"), ("ida_yielding", "kobe_yielding.yaml")):
        loaded, problems, _ = load_ida(SCENARIOS / f"{name}.yaml")
        assert not problems and loaded.resolve(loaded.spec.scenario, "scenario").name == scenario


def test_the_in_process_model_refuses_the_nominal_plant_and_takes_the_papers():
    nominal = plan_scenario(SCENARIOS / "nominal_plant_elcentro.yaml", ("simulation.stop_time=0.01",))
    paper = plan_scenario(SCENARIOS / "elcentro.yaml", ("simulation.stop_time=0.01",))
    assert "coil" in monolithic_problem(nominal)
    with pytest.raises(NotMonolithic, match="coil"):
        system_setup(nominal, 0.0)
    assert monolithic_problem(paper) is None and system_setup(paper, 0.0).n_isolators == 2
    bouc_wen = f"units.isolator.fmu={PROJECT / 'fmus' / 'BoucWenIsolator.fmu'}"
    swapped = plan_scenario(SCENARIOS / "elcentro.yaml", ("simulation.stop_time=0.01", bouc_wen))
    assert "BoucWenIsolator" in monolithic_problem(swapped)  # another isolator alone is refused too


@pytest.mark.parametrize("tau", ["-0.01", ".nan", ".inf", "'0.01'"])
def test_a_bad_coil_time_constant_is_exit_2_before_anything_is_written(tmp_path, capsys, tau):
    out = tmp_path / "out"
    code = study_main([str(SCENARIOS / "controller_benchmark.yaml"), "--out", str(out), "--quiet",
                       "--set", "records={elcentro: nominal_plant_elcentro.yaml}",
                       "--set", "strategies=[passive-off, sosm]",
                       "--set", f"overrides=[simulation.stop_time=1, coil.tau={tau}]"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "tau" in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.slow
def test_the_sweep_on_the_nominal_plant_is_the_direct_runs_at_each_current(tmp_path):
    """The best-constant sweep co-simulates the nominal plant's FMUs: its peaks are those of run.py-style runs of
    the scenario at each constant current (written by hand: the SOSM unit in passive mode)."""
    path = SCENARIOS / "nominal_plant_elcentro.yaml"
    base = ("simulation.stop_time=1.5", "isolator.i_max=3.0", "controller.i_max=3.0")
    plan = plan_scenario(path, base)
    for current in (0.0, 3.0):
        got = cosimulated_peaks(plan, current)
        out = tmp_path / f"direct-{current:g}"
        run_scenario(path, (*base, "controller.mode=passive", f"controller.i_passive={current}"), out, plots=False)
        data = read_timeseries(out / "timeseries.csv")
        assert got["x0"] == pytest.approx(np.max(np.abs(data["building.x_0"])), rel=1e-12)
        assert got["a3"] == pytest.approx(np.max(np.abs(data["building.a_3"])), rel=1e-12)
        assert got["d"] == pytest.approx(max(np.max(np.abs(data[f"building.drift_{j}"])) for j in (1, 2, 3)),
                                         rel=1e-12)
        assert got["i_mean"] == pytest.approx(current, abs=1e-12)
        assert np.allclose(data["coil.i"], current)  # the lag starts settled: a constant command, a constant current
    assert math.isfinite(got["x0"])


def test_a_sweep_current_whose_run_says_it_is_invalid_is_not_ranked(monkeypatch):
    from orchestration.case_study import current_sweep as tuning
    from orchestration.case_study.case_config import ObjectiveSpec

    def peaks(plan, current):  # the larger the current, the lower J; 3 A's run says it is invalid
        p = {"a3": 10.0 - current, "d": 0.01, "x0": 0.005, "i_mean": current, "i_min": current, "i_max": current,
             "i_limit": current, "s_bound": 1.0, "s_zero": float(current == 0), "valid": current != 3.0,
             "invalid_reasons": ["energy balance"] if current == 3.0 else []}
        return p

    monkeypatch.setattr(tuning, "monolithic_problem", lambda plan: "another plant")
    monkeypatch.setattr(tuning, "cosimulated_peaks", peaks)
    out = tuning.sweep_currents(None, [0.0, 1.5, 3.0], ObjectiveSpec())
    assert out["best_current_A"] == 1.5 and len(out["rows"]) == 3
    monkeypatch.setattr(tuning, "cosimulated_peaks", lambda plan, i: {**peaks(plan, 3.0), "i_mean": i})
    with pytest.raises(ValueError, match="no constant current gave a valid run"):
        tuning.sweep_currents(None, [0.0, 3.0], ObjectiveSpec())
