"""Reliability: failing units, NaN, divergence, interrupts; partial results kept and marked; fuzzing."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from components.build.pythonfmu_units import FmuSource, build
from orchestration.master.errors import ScenarioError
from orchestration.master.scenario import load_scenario
from orchestration.master.session import run_plan
from orchestration.project import plan_scenario, resolve_scenario

from .conftest import PROJECT

RUN = [sys.executable, str(PROJECT / "orchestration" / "run.py")]


@pytest.fixture(scope="module")
def failing_fmu(tmp_path_factory) -> Path:
    source = FmuSource(PROJECT / "tests" / "units" / "failing_unit_fmu.py", "FailingUnit", ())
    return build(source, tmp_path_factory.mktemp("failing"))


def scenario_with_saboteur(tmp_path: Path, fmu: Path, failure: str, fail_at: float = 0.5) -> Path:
    path = tmp_path / "sabotaged.yaml"
    path.write_text(textwrap.dedent(f"""\
        extends: {PROJECT / "scenarios" / "elcentro.yaml"}
        name: sabotaged
        units:
          saboteur:
            fmu: {fmu}
            parameters: {{fail_at: {fail_at}, failure: {failure}}}
        connections:
          - ground.ag -> building.ag
          - building.x_0 -> isolator.x
          - building.v_0 -> isolator.v
          - controller.i -> isolator.i
          - isolator.F -> building.F
          - {{source: building.x_0, target: controller.x, delayed: true}}
          - {{source: building.v_0, target: controller.v, delayed: true}}
          - {{source: building.arel_0, target: controller.a, delayed: true}}
          - building.x_0 -> saboteur.u
        simulation: {{stop_time: 1.0}}
        """))
    return path


def check_partial(folder: Path, rows_at_most: int) -> dict:
    summary = json.loads((folder / "summary.json").read_text())
    manifest = json.loads((folder / "manifest.json").read_text())
    assert summary["complete"] is False and manifest["complete"] is False
    lines = (folder / "timeseries.csv").read_text().splitlines()
    assert lines[0].startswith("time,") and 1 < len(lines) <= rows_at_most + 1
    assert all(len(line.split(",")) == len(lines[0].split(",")) for line in lines)
    return summary


@pytest.mark.parametrize(("failure", "expected"), [
    ("discard", "fmi2DoStep returned discard"),
    ("nan", "variable 'y'"),
    ("raise", "fmi2DoStep returned fatal"),
])
def test_a_failing_unit_stops_the_run_and_keeps_partial_results(tmp_path, failing_fmu, failure, expected):
    plan = plan_scenario(scenario_with_saboteur(tmp_path, failing_fmu, failure))
    outcome = run_plan(plan, out=tmp_path / "run", plots=False)
    assert outcome.result.status == "failed"
    error = outcome.result.error
    assert error.unit == "saboteur" and error.time == pytest.approx(0.5, abs=1.5e-3)
    assert expected in str(error)
    if failure == "discard":
        assert "deliberate failure at t = 0.5 s" in str(error)
    summary = check_partial(outcome.folder, 502)
    assert summary["error"] and "saboteur" in summary["error"]
    for unit in outcome.units:
        # FMI 2.0: after fmi2Fatal no function may be called, so that instance is abandoned
        if not (failure == "raise" and unit.name == "saboteur"):
            assert unit.freed, unit.name


def test_cli_exit_code_and_message_for_a_failing_unit(tmp_path, failing_fmu):
    out = tmp_path / "run"
    proc = subprocess.run([*RUN, str(scenario_with_saboteur(tmp_path, failing_fmu, "discard")), "--out", str(out),
                           "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1
    assert "unit 'saboteur'" in proc.stderr and "t = 0.5 s" in proc.stderr and "marked incomplete" in proc.stderr
    assert "Traceback" not in proc.stderr
    check_partial(out, 502)


def test_divergence_limit_stops_the_run(tmp_path):
    plan = plan_scenario(PROJECT / "scenarios" / "elcentro.yaml",
                         ("simulation.stop_time=5", "limits.max_abs={building.x_0: 0.002}"))
    outcome = run_plan(plan, out=tmp_path / "run", plots=False)
    error = outcome.result.error
    assert outcome.result.status == "failed" and error.unit == "building" and error.variable == "x_0"
    assert "exceeds the limit 0.002" in str(error)
    check_partial(outcome.folder, 5001)
    assert all(u.freed for u in outcome.units)


def test_sigint_leaves_a_complete_readable_partial_run(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([*RUN, str(PROJECT / "scenarios" / "kobe.yaml"), "--out", str(out), "--quiet",
                             "--no-plots"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not out.exists() and time.monotonic() < deadline:  # the folder appears once the run starts
        time.sleep(0.1)
    time.sleep(1.5)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1, stderr
    assert "interrupted (SIGINT received)" in stderr and "Traceback" not in stderr
    summary = check_partial(out, 150_000)
    assert summary["status"] == "interrupted" and summary["steps_done"] < 150_000


def test_sigterm_does_the_same(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([*RUN, str(PROJECT / "scenarios" / "kobe.yaml"), "--out", str(out), "--quiet",
                             "--no-plots"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not out.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1, stderr
    assert check_partial(out, 150_000)["status"] == "interrupted"


def test_unreadable_record_is_a_scenario_error_before_any_unit_loads(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("0,0\n0.02,abc\n")
    with pytest.raises(ScenarioError) as err:
        plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"ground.record=!record {bad}",))
    assert f"units.ground.parameters.record: unreadable record: {bad}:2: not a number" in str(err.value)


def _zip(path: Path, files: dict[str, str]) -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name, text in files.items():
            z.writestr(name, text)
    return path


FMI1 = '<?xml version="1.0"?><fmiModelDescription fmiVersion="1.0" modelName="m" modelIdentifier="m" ' \
       'guid="{1}" numberOfContinuousStates="0" numberOfEventIndicators="0"><ModelVariables/></fmiModelDescription>'
ME_ONLY = '<?xml version="1.0"?><fmiModelDescription fmiVersion="2.0" modelName="m" guid="{1}">' \
          '<ModelExchange modelIdentifier="m"/><ModelVariables/><ModelStructure/></fmiModelDescription>'


@pytest.mark.parametrize(("files", "message"), [
    (None, "not an FMU (not a zip archive)"),
    ({"other.txt": "x"}, "the zip has no modelDescription.xml"),
    ({"modelDescription.xml": FMI1}, "FMI 1.0"),
    ({"modelDescription.xml": ME_ONLY}, "model-exchange-only"),
])
def test_malformed_fmus_are_clear_scenario_errors(tmp_path, files, message):
    fmu = tmp_path / "bad.fmu"
    if files is None:
        fmu.write_text("plain text")
    else:
        _zip(fmu, files)
    with pytest.raises(ScenarioError) as err:
        plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"units.isolator.fmu={fmu}",))
    text = str(err.value)
    assert "units.isolator.fmu" in text and message in text


# -- fuzzing ---------------------------------------------------------------------------------------
scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True, allow_infinity=True),
                    st.text(max_size=12))
KEYS = ["name", "units", "connections", "simulation", "outputs", "results", "report", "limits", "extends", "step",
        "stop_time", "fmu", "parameters", "ground", "building", "record", "algorithm", "inputs", "source", "target",
        "delayed", "max_abs", "x"]
trees = st.recursive(scalars, lambda kids: st.one_of(
    st.lists(kids, max_size=4), st.dictionaries(st.sampled_from(KEYS), kids, max_size=5)), max_leaves=25)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(tree=trees)
def test_fuzzed_structures_only_raise_scenario_errors(tmp_path, tree):
    path = tmp_path / "fuzz.yaml"
    path.write_text(yaml.safe_dump(tree))
    before = set(tmp_path.iterdir())
    try:
        resolve_scenario(load_scenario(path), build=False)
    except ScenarioError:
        pass
    assert set(tmp_path.iterdir()) == before  # nothing written


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(alphabet=st.characters(codec="utf-8"), max_size=200))
def test_fuzzed_yaml_text_only_raises_scenario_errors(tmp_path, text):
    path = tmp_path / "fuzz.yaml"
    path.write_text(text)
    try:
        resolve_scenario(load_scenario(path), build=False)
    except ScenarioError:
        pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fuzz.yaml"]


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.text(max_size=30), value=st.text(max_size=30))
def test_fuzzed_overrides_only_raise_scenario_errors(tmp_path, key, value):
    try:
        resolve_scenario(load_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"{key}={value}",)), build=False)
    except ScenarioError:
        pass
