"""The Python API's arguments: checked types (TypeError naming the argument), paths where a plan is expected,
and a unit that cannot load as a failed result (docs/running.md: a unit failure does not raise)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from orchestration.api import ScenarioError, load_scenario, run
from orchestration.master.execution import StopRequest

from ..conftest import PROJECT, shipped_record

ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"
SHORT = "simulation.stop_time=0.05"


@pytest.fixture(scope="module")
def plan():
    return load_scenario(ELCENTRO, [SHORT])


def test_a_single_data_folder_string_is_one_folder_not_its_characters(tmp_path):
    shutil.copy(shipped_record("elcentro_1940_ns.csv"), tmp_path / "only_here.csv")
    plan = load_scenario(str(ELCENTRO), [SHORT, "ground.record=!record only_here.csv"], data_dirs=str(tmp_path))
    assert plan.data_files["ground.record"] == (tmp_path / "only_here.csv").resolve()
    plan = load_scenario(ELCENTRO, SHORT, data_dirs=tmp_path)  # a single override string is one override
    assert plan.loaded.scenario.simulation.stop_time == 0.05


@pytest.mark.parametrize(("kwargs", "argument"), [
    ({"path": None}, "path"), ({"path": 3}, "path"), ({"path": b"scenarios/kobe.yaml"}, "path"),
    ({"overrides": 5}, "overrides"), ({"overrides": [1.5]}, "overrides[0]"), ({"overrides": {"a": 1}}, "overrides"),
    ({"data_dirs": 5}, "data_dirs"), ({"data_dirs": [None]}, "data_dirs[0]"),
])
def test_load_scenario_refuses_arguments_of_the_wrong_type_naming_them(kwargs, argument):
    args = {"path": ELCENTRO} | kwargs
    with pytest.raises(TypeError, match=rf"load_scenario\(\): {argument.replace('[', '.').replace(']', '.')}"):
        load_scenario(**args)


def test_run_takes_a_scenario_path_as_the_plan(tmp_path):
    short = tmp_path / "short.yaml"
    short.write_text(f"extends: {ELCENTRO}\nsimulation: {{stop_time: 0.05}}\n")
    for k, given in enumerate((str(short), short)):
        res = run(given, out=tmp_path / f"out{k}")
        assert res.complete and res.time[-1] == 0.05


def test_a_missing_scenario_path_given_to_run_is_a_scenario_error(tmp_path):
    with pytest.raises(ScenarioError, match=r"nowhere\.yaml"):
        run(tmp_path / "nowhere.yaml", out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("kwargs", "argument"), [
    ({"stop": 5}, "stop"), ({"stop": True}, "stop"), ({"stop": "now"}, "stop"), ({"plots": "yes"}, "plots"),
    ({"progress": 1}, "progress"), ({"out": 7}, "out"), ({"out": ""}, "out"),
])
def test_run_refuses_bad_arguments_before_any_folder(plan, tmp_path, kwargs, argument):
    args = {"out": tmp_path / "out"} | kwargs
    with pytest.raises((TypeError, ValueError), match=rf"run\(\): {argument}"):
        run(plan, **args)
    assert list(tmp_path.iterdir()) == []


def test_run_refuses_something_that_is_not_a_plan(tmp_path):
    with pytest.raises(TypeError, match=r"run\(\): plan must be a SystemPlan"):
        run({"units": {}}, out=tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def test_a_stop_request_set_before_the_run_stops_it_at_once(plan, tmp_path):
    stop = StopRequest()
    stop.set("asked")
    res = run(plan, out=tmp_path / "out", stop=stop)
    assert res.status == "interrupted" and "asked" in res.error and len(res.time) == 1


@pytest.mark.parametrize("damage", ["garbage", "gone", "no description"])
def test_an_fmu_damaged_between_load_and_run_is_a_failed_result(tmp_path, damage):
    fmu = tmp_path / "iso.fmu"
    shutil.copy(PROJECT / "fmus" / "MreIsolator.fmu", fmu)
    plan = load_scenario(ELCENTRO, [SHORT, f"units.isolator.fmu={fmu}"])
    if damage == "garbage":
        fmu.write_bytes(b"not a zip any more")
    elif damage == "gone":
        fmu.unlink()
    else:
        import zipfile

        with zipfile.ZipFile(tmp_path / "other.fmu", "w") as z:
            z.writestr("other.txt", "x")
        (tmp_path / "other.fmu").replace(fmu)
    res = run(plan, out=tmp_path / "out")
    assert res.status == "failed" and not res.complete
    assert "isolator" in res.error and str(fmu) in res.error
    summary = json.loads((Path(res.folder) / "summary.json").read_text())
    assert summary["complete"] is False and summary["status"] == "failed"
