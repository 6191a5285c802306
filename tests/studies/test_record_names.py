"""A study's records by their readable names (the scenario's label of its ground record) beside their ids."""

from __future__ import annotations

from types import SimpleNamespace

from orchestration.case_study.case_figures import named
from orchestration.case_study.case_plan import record_name
from orchestration.case_study.case_records import RecordInfo
from orchestration.engine_hooks import plan_scenario

from ..conftest import PROJECT


def test_the_name_is_the_scenarios_label_of_the_record_it_plays():
    plan = plan_scenario(PROJECT / "scenarios" / "kobe.yaml", ("simulation.stop_time=0.01",))
    assert record_name(plan) == "Kobe 1995, JMA Kobe N-S"
    other = plan_scenario(PROJECT / "scenarios" / "kobe.yaml",
                          ("simulation.stop_time=0.01", "ground.record=!record elcentro_1940_ns.csv"))
    assert record_name(other) is None  # the label names another file: no name, the id stands for it


def test_figures_name_records_and_json_keeps_the_name():
    info = RecordInfo("kobe.yaml", 1.0, [1.0], "kobe.csv", 0.5, 1.0, 2, "Kobe 1995, JMA Kobe N-S")
    assert RecordInfo.from_json(info.to_json()) == info
    assert named(SimpleNamespace(records={"kobe": info}), "kobe") == "Kobe 1995, JMA Kobe N-S ×0.5"
    old = RecordInfo.from_json({k: v for k, v in info.to_json().items() if k != "name"})  # a study.json before names
    assert named(SimpleNamespace(records={"kobe": old}), "kobe") == "kobe ×0.5"
