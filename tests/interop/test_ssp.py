"""SSP 1.0 export and import: the package is valid, complete, runs like the YAML, and bad ones are refused."""

from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.ssp.ssd import read_ssd, read_ssv

from orchestration.engine_hooks import plan_scenario, resolve_scenario
from orchestration.interop.ssp_package import SSD_FILE, export_ssp, load_ssp
from orchestration.master.errors import ScenarioError
from orchestration.master.scenario import LoadedScenario, load_scenario
from orchestration.master.session import run_plan

PROJECT = Path(__file__).resolve().parents[2]
KOBE = PROJECT / "scenarios" / "kobe.yaml"


@pytest.fixture(scope="module")
def kobe_ssp(kobe, tmp_path_factory) -> Path:
    return export_ssp(plan_scenario(KOBE), tmp_path_factory.mktemp("ssp") / "kobe.ssp")


def _rewrite(package: Path, dest: Path, member: str, edit) -> Path:
    """A copy of the package with one member's text edited (or removed when edit returns None)."""
    with zipfile.ZipFile(package) as zin, zipfile.ZipFile(dest, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == member:
                text = edit(data.decode(errors="replace"))
                if text is None:
                    continue
                data = text.encode()
            zout.writestr(item, data)
    return dest


def _problems(exc: pytest.ExceptionInfo) -> list:
    return exc.value.problems


# -- the package --------------------------------------------------------------------------------


def test_package_layout_and_schema(kobe_ssp, kobe):
    with zipfile.ZipFile(kobe_ssp) as z:
        names = set(z.namelist())
        assert z.read(f"resources/{kobe.name}") == kobe.read_bytes()
        for fmu in ("GroundMotionSource", "ShearBuilding", "MreIsolator", "SosmCurrentController"):
            assert z.read(f"resources/{fmu}.fmu") == (PROJECT / "fmus" / f"{fmu}.fmu").read_bytes()
    assert names == {SSD_FILE, "resources/GroundMotionSource.fmu", "resources/ShearBuilding.fmu",
                     "resources/MreIsolator.fmu", "resources/SosmCurrentController.fmu",
                     "resources/ground.ssv", "resources/isolator.ssv", f"resources/{kobe.name}"}
    # fmpy's own reader validates the SSD and every referenced .ssv against the SSP 1.0 schemas
    ssd = read_ssd(str(kobe_ssp), validate=True)
    assert ssd.version == "1.0" and ssd.name == "kobe"
    assert [e.name for e in ssd.system.elements] == ["ground", "building", "isolator", "controller"]


def test_components_connectors_and_connections(kobe_ssp):
    ssd = read_ssd(str(kobe_ssp), validate=True)
    sc = load_scenario(KOBE).scenario
    with zipfile.ZipFile(kobe_ssp) as z:
        root = z.read(SSD_FILE).decode()
    for element in ssd.system.elements:
        md = read_model_description(str(PROJECT / "fmus" / Path(element.source).name))
        assert element.source == f"resources/{Path(sc.units[element.name].fmu).name}"
        expected = {v.name: v.causality for v in md.modelVariables if v.causality != "local"}
        assert {c.name: c.kind for c in element.connectors} == expected
        for v in md.modelVariables:
            if v.type == "Real" and v.unit and v.causality in ("input", "output"):
                block = re.search(rf'<ssd:Component name="{element.name}".*?</ssd:Component>', root, re.S).group(0)
                assert re.search(rf'name="{re.escape(v.name)}" kind="{v.causality}">\s*<ssc:Real unit="'
                                 rf'{re.escape(v.unit)}"/>', block)
    got = [(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in ssd.system.connections]
    assert got == [(c.source.unit, c.source.name, c.target.unit, c.target.name) for c in sc.connections]
    assert 'unit="N"' in root and '<ssc:Unit name="N">' in root


def test_parameter_values_in_ssv(kobe_ssp, kobe):
    ground = read_ssv(str(kobe_ssp), resource="resources/ground.ssv", validate=True)
    isolator = read_ssv(str(kobe_ssp), resource="resources/isolator.ssv", validate=True)
    values = {p.name: (p.type, p.value) for p in ground.parameters}
    assert values == {"scale": ("Real", "0.5"), "record": ("String", f"resources/{kobe.name}")}
    assert {p.name: (p.type, p.value) for p in isolator.parameters} == {"n_isolators": ("Integer", "2")}


def test_loaded_package_is_the_same_scenario(kobe_ssp, kobe):
    original = load_scenario(KOBE).scenario
    loaded = load_ssp(kobe_ssp)
    try:
        sc = loaded.scenario
        for field in ("name", "description", "connections", "simulation", "outputs", "report", "limits", "results"):
            assert getattr(sc, field) == getattr(original, field), field
        assert set(sc.units) == set(original.units)
        record = sc.units["ground"].parameters["record"]
        assert Path(record.name).read_bytes() == kobe.read_bytes()
        assert Path(sc.units["isolator"].fmu).read_bytes() == (PROJECT / "fmus" / "MreIsolator.fmu").read_bytes()
        assert sc.units["isolator"].parameters == {"n_isolators": 2}
        workdir = loaded.workdir
    finally:
        loaded.cleanup()
    assert not workdir.exists()


@pytest.mark.slow
def test_running_the_package_equals_running_the_yaml(kobe_ssp, tmp_path):
    overrides = ("simulation.start_time=5", "simulation.stop_time=7", "controller.mode=passive",
                 "controller.i_passive=1.5")
    loaded = load_ssp(kobe_ssp, overrides)
    assert loaded.scenario.units["controller"].parameters == {"mode": "passive", "i_passive": 1.5}
    from_ssp = run_plan(resolve_scenario(loaded), out=tmp_path / "ssp", plots=False)
    from_yaml = run_plan(plan_scenario(KOBE, overrides), out=tmp_path / "yaml", plots=False)
    assert from_ssp.result.complete and from_ssp.result.steps_done == 2000
    assert from_ssp.recorder.names == from_yaml.recorder.names
    np.testing.assert_array_equal(from_ssp.recorder.data, from_yaml.recorder.data)
    assert np.max(np.abs(from_ssp.recorder.column("ground.ag"))) > 0.01  # the record from the package plays
    assert np.max(np.abs(from_ssp.recorder.column("building.x_0"))) > 1e-4
    assert "kobe.ssp" in (from_ssp.folder / "manifest.json").read_text()


def test_delayed_connections_survive_the_round_trip(kobe, tmp_path):
    loaded = load_scenario(KOBE)
    sc = loaded.scenario
    connections = [c.model_copy(update={"delayed": str(c) .startswith("isolator.F")}) for c in sc.connections]
    delayed = LoadedScenario(sc.model_copy(update={"connections": connections}), loaded.path, loaded.lines, loaded.raw)
    package = export_ssp(resolve_scenario(delayed), tmp_path / "delayed.ssp")
    back = load_ssp(package)
    assert [c.delayed for c in back.scenario.connections] == [c.delayed for c in connections]
    assert sum(c.delayed for c in back.scenario.connections) == 1
    back.cleanup()


# -- bad packages -------------------------------------------------------------------------------


def test_missing_fmu_is_named(kobe_ssp, tmp_path):
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", SSD_FILE,
                   lambda t: t.replace('source="resources/MreIsolator.fmu"', 'source="resources/MreIsolatr.fmu"'))
    with pytest.raises(ScenarioError) as exc:
        load_ssp(bad)
    (problem,) = _problems(exc)
    assert problem.message == "component 'isolator': FMU 'resources/MreIsolatr.fmu' is not in the package"
    assert problem.file.endswith(f"bad.ssp!/{SSD_FILE}") and problem.key == "units.isolator.fmu"
    with zipfile.ZipFile(bad) as z:
        lines = z.read(SSD_FILE).decode().splitlines()
    assert 'name="isolator"' in lines[problem.line - 1]


def test_fmu_file_removed_from_the_package(kobe_ssp, tmp_path):
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", "resources/ShearBuilding.fmu", lambda t: None)
    with pytest.raises(ScenarioError, match=r"component 'building': FMU 'resources/ShearBuilding\.fmu' is not in"):
        load_ssp(bad)


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ('endElement="isolator" endConnector="x"', 'endElement="isolator" endConnector="xb"',
         "connection 1 (building.x_0 -> isolator.xb): component 'isolator' has no connector 'xb'"),
        ('startElement="isolator" startConnector="F"', 'startElement="isolater" startConnector="F"',
         "connection 4 (isolater.F -> building.F): no component named 'isolater' "
         "(components: ground, building, isolator, controller)"),
    ],
)
def test_broken_connection_names_the_unit_and_variable(kobe_ssp, tmp_path, old, new, expected):
    def edit(text: str) -> str:
        assert old in text
        return text.replace(old, new)

    with pytest.raises(ScenarioError) as exc:
        load_ssp(_rewrite(kobe_ssp, tmp_path / "bad.ssp", SSD_FILE, edit))
    assert [p.message for p in _problems(exc)] == [expected]
    assert _problems(exc)[0].line is not None


def test_connector_that_the_fmu_lacks(kobe_ssp, tmp_path):
    def edit(text: str) -> str:
        text = text.replace('<ssd:Connector name="x" kind="input">', '<ssd:Connector name="x_b" kind="input">')
        return text.replace('endElement="isolator" endConnector="x"', 'endElement="isolator" endConnector="x_b"')

    with pytest.raises(ScenarioError) as exc:
        load_ssp(_rewrite(kobe_ssp, tmp_path / "bad.ssp", SSD_FILE, edit))
    messages = [p.message for p in _problems(exc)]
    assert "component 'isolator': connector 'x_b' is not a variable of its FMU resources/MreIsolator.fmu" in messages


def test_schema_violation_is_reported_with_its_line(kobe_ssp, tmp_path):
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", SSD_FILE,
                   lambda t: t.replace('kind="output"', 'kind="outlet"', 1))
    with pytest.raises(ScenarioError) as exc:
        load_ssp(bad)
    (problem,) = _problems(exc)
    assert "SystemStructureDescription.xsd" in problem.message and "outlet" in problem.message
    assert problem.line is not None


def test_missing_parameter_set_and_data_file(kobe_ssp, kobe, tmp_path):
    no_ssv = _rewrite(kobe_ssp, tmp_path / "a.ssp", "resources/isolator.ssv", lambda t: None)
    with pytest.raises(ScenarioError, match=r"component 'isolator': parameter set 'resources/isolator\.ssv' is not"):
        load_ssp(no_ssv)
    no_record = _rewrite(kobe_ssp, tmp_path / "b.ssp", f"resources/{kobe.name}", lambda t: None)
    with pytest.raises(ScenarioError) as exc:
        load_ssp(no_record)
    assert [p.message for p in _problems(exc)] == [
        f"component 'ground', parameter 'record': data file 'resources/{kobe.name}' is not in the package"]


def test_unknown_parameter_is_reported_at_its_ssv_line(kobe_ssp, tmp_path):
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", "resources/isolator.ssv",
                   lambda t: t.replace('name="n_isolators"', 'name="n_isolator"'))
    loaded = load_ssp(bad)
    with pytest.raises(ScenarioError) as exc:
        resolve_scenario(loaded)
    (problem,) = _problems(exc)
    assert problem.message == "MreIsolator has no variable 'n_isolator' (did you mean 'n_isolators'?)"
    assert problem.file.endswith("bad.ssp!/resources/isolator.ssv") and problem.line == 4
    loaded.cleanup()


def test_not_a_package(tmp_path):
    text = tmp_path / "x.ssp"
    text.write_text("hello")
    with pytest.raises(ScenarioError, match="not a zip archive"):
        load_ssp(text)
    empty = tmp_path / "y.ssp"
    with zipfile.ZipFile(empty, "w") as z:
        z.writestr("readme.txt", "")
    with pytest.raises(ScenarioError, match=r"no SystemStructure\.ssd"):
        load_ssp(empty)


@pytest.mark.slow
def test_cli_export_and_check(kobe, kobe_ssp, tmp_path):
    out = tmp_path / "cli.ssp"
    script = str(PROJECT / "orchestration" / "ssp.py")
    done = subprocess.run([sys.executable, script, "export", str(KOBE), str(out)], capture_output=True, text=True,
                          cwd=tmp_path, check=False)
    assert done.returncode == 0, done.stderr
    assert zipfile.is_zipfile(out)
    done = subprocess.run([sys.executable, script, "check", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0 and "4 units, 8 connections, 150000 steps" in done.stdout
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", SSD_FILE,
                   lambda t: t.replace('endConnector="F"', 'endConnector="Fx"'))
    done = subprocess.run([sys.executable, script, "check", str(bad)], capture_output=True, text=True, check=False)
    assert done.returncode == 2
    assert "component 'building' has no connector 'Fx'" in done.stderr


@pytest.mark.slow
def test_run_cli_takes_a_package(kobe_ssp, tmp_path):
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), str(kobe_ssp),
                           "--set", "simulation.stop_time=0.5", "--out", str(out), "--no-plots", "--quiet"],
                          capture_output=True, text=True, cwd=tmp_path, check=False)
    assert done.returncode == 0, done.stderr
    assert (out / "timeseries.csv").read_text().count("\n") == 502  # header + 501 rows
    assert '"complete": true' in (out / "summary.json").read_text()


# -- hostile packages ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("member", "old", "new", "message"), [
    ("resources/ground.ssv", 'value="0.5"', 'value="abc"', "parameter 'scale': 'abc' is not a number"),
    (SSD_FILE, 'stopTime="150.0"', 'stopTime="INF"', "DefaultExperiment stopTime: 'INF' is not finite"),
    (SSD_FILE, '"format": 1,', '"format": 1, "units": {"x": {"fmu": "/etc/passwd"}},',
     "annotation may not set 'units'"),
    (SSD_FILE, '"format": 1,', '"format": 1, "name": "../x",', "annotation may not set 'name'"),
    (SSD_FILE, '"step":', '"stop_time": 1e9, "step":', "may not set simulation.stop_time"),
    (SSD_FILE, '"dir": "runs"', '"dir": "/tmp/elsewhere"', "must be a relative folder inside the working folder"),
    (SSD_FILE, '"dir": "runs"', '"dir": "../up"', "must be a relative folder inside the working folder"),
])
def test_hostile_values_in_a_package_are_problems(kobe_ssp, tmp_path, member, old, new, message):
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", member, lambda t: t.replace(old, new, 1))
    with pytest.raises(ScenarioError) as exc:
        load_ssp(bad)
    assert any(message in p.message for p in _problems(exc)), _problems(exc)


def test_a_package_name_cannot_leave_the_results_folder(kobe_ssp, tmp_path):
    bad = _rewrite(kobe_ssp, tmp_path / "bad.ssp", SSD_FILE, lambda t: t.replace('name="kobe"', 'name="../up"', 1))
    with pytest.raises(ScenarioError, match="must be a plain name"):
        load_ssp(bad)


@pytest.mark.parametrize(("entry", "message"), [
    ("../../escaped.txt", "'..' in the path"), ("/tmp/escaped.txt", "an absolute path")])
def test_archive_entries_outside_the_folder_are_refused(kobe_ssp, tmp_path, entry, message):
    bad = tmp_path / "bad.ssp"
    bad.write_bytes(kobe_ssp.read_bytes())
    with zipfile.ZipFile(bad, "a") as z:
        z.writestr(entry, "x")
    with pytest.raises(ScenarioError, match=message):
        load_ssp(bad, workdir=tmp_path / "x")
    assert not (tmp_path / "escaped.txt").exists() and not (tmp_path / "x").exists()


def test_an_archive_beyond_the_size_limit_is_refused_before_extracting(kobe_ssp, tmp_path, monkeypatch):
    from orchestration.master import safe_archive

    monkeypatch.setattr(safe_archive, "MAX_UNPACKED_BYTES", 1 << 20)
    with pytest.raises(ScenarioError, match=r"unpacks to [\d,]+ bytes, more than the 1,048,576 allowed"):
        load_ssp(kobe_ssp, workdir=tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_records_keep_their_kind_through_a_package(kobe_ssp, kobe):
    loaded = load_ssp(kobe_ssp)
    record = loaded.scenario.units["ground"].parameters["record"]
    assert record.kind == "record" and record.name.endswith(kobe.name)  # checked before a run, like !record
    loaded.cleanup()
