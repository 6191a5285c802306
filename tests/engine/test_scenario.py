"""Scenario files: typed parsing, every problem at once with file, line and key; data path; checks."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from orchestration.engine_hooks import HOOKS, check_record, resolve_scenario
from orchestration.master.datapath import ENV_VAR, find_data_file
from orchestration.master.errors import ScenarioError
from orchestration.master.scenario import load_scenario
from orchestration.master.yaml_source import DataFile

from ..conftest import PROJECT

SCENARIOS = PROJECT / "scenarios"


def write(tmp_path: Path, text: str, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def problems_of(path: Path, overrides=()) -> list[str]:
    with pytest.raises(ScenarioError) as err:
        load_scenario(path, tuple(overrides))
    return [str(p) for p in err.value.problems]


def test_shipped_scenario_extends_the_system():
    loaded = load_scenario(SCENARIOS / "kobe.yaml")
    sc = loaded.scenario
    assert sc.name == "kobe"
    assert list(sc.units) == ["ground", "building", "isolator", "controller"]
    assert sc.units["ground"].parameters == {"scale": 0.5, "record": DataFile("kobe_1995_jma_ns.csv", "record")}
    assert sc.simulation.step == 0.001 and sc.simulation.stop_time == 150.0 and sc.simulation.n_steps == 150_000
    assert str(sc.connections[4]) == "isolator.F -> building.F"


def test_overrides_set_unit_parameters_and_keys():
    loaded = load_scenario(SCENARIOS / "elcentro.yaml",
                           ("controller.mode=passive", "controller.i_passive=3", "simulation.stop_time=2"))
    sc = loaded.scenario
    assert sc.units["controller"].parameters == {"mode": "passive", "i_passive": 3}
    assert sc.simulation.stop_time == 2


def test_every_problem_is_reported_with_file_line_and_key(tmp_path):
    path = write(tmp_path, """\
        name: bad
        units:
          a:
            fmu: a.fmu
            colour: red
        connections:
          - a.y -> b.u
        simulation:
          step: fast
          stop_time: 1.0
        outputs: [a.y]
        surprise: 1
        """)
    found = problems_of(path)
    text = "\n".join(found)
    assert f"{path}:5: units.a.colour: unknown key" in text
    assert f"{path}:9: simulation.step: Input should be a valid number" in text
    assert f"{path}:12: surprise: unknown key" in text
    assert len(found) == 3


def test_missing_fields(tmp_path):
    path = write(tmp_path, "units:\n  a:\n    parameters: {}\n")
    text = "\n".join(problems_of(path))
    assert "units.a.fmu: required key is missing" in text
    assert "simulation: required key is missing" in text


@pytest.mark.parametrize(
    ("sim", "message"),
    [("step: 0.0\n  stop_time: 1.0", "greater than 0"),
     ("step: 2.0\n  stop_time: 1.0", "larger than the simulated span"),
     ("step: 0.3\n  stop_time: 1.0", "not a whole number of steps"),
     ("step: 0.1\n  stop_time: -1.0", "must be after start_time")],
)
def test_time_grid_problems(tmp_path, sim, message):
    path = write(tmp_path, f"units:\n  a: {{fmu: a.fmu}}\nsimulation:\n  {sim}\n")
    assert any(message in p for p in problems_of(path))


def test_duplicate_keys_and_bad_yaml(tmp_path):
    dup = write(tmp_path, "units: {}\nunits: {}\n")
    assert any(":2: units: duplicate key" in p for p in problems_of(dup))
    broken = write(tmp_path, "units: [\n", "b.yaml")
    assert any("not valid YAML" in p for p in problems_of(broken))


def test_bad_override_value_type_is_named(tmp_path):
    found = problems_of(SCENARIOS / "elcentro.yaml", ["simulation.step=[1, 2]"])
    assert any("--set simulation.step=[1, 2]" in p and "simulation.step" in p for p in found)


def test_extends_loop_is_an_error(tmp_path):
    write(tmp_path, "extends: b.yaml\n", "a.yaml")
    write(tmp_path, "extends: a.yaml\n", "b.yaml")
    assert any("'extends' loops" in p for p in problems_of(tmp_path / "a.yaml"))


def test_data_path_order_and_missing_file(tmp_path, monkeypatch):
    first, second = tmp_path / "first", tmp_path / "second"
    first.mkdir()
    second.mkdir()
    (first / "r.csv").write_text("0,0\n1,1\n")
    (second / "r.csv").write_text("0,0\n1,1\n")
    (second / "only2.csv").write_text("0,0\n1,1\n")
    third = tmp_path / "third"  # an application's default folder: searched after the environment's
    third.mkdir()
    (third / "only2.csv").write_text("0,0\n1,1\n")
    (third / "only3.csv").write_text("0,0\n1,1\n")
    monkeypatch.setenv(ENV_VAR, str(second))
    assert find_data_file("r.csv", (first,), defaults=(third,)) == (first / "r.csv").resolve()
    assert find_data_file("only2.csv", (first,), defaults=(third,)) == (second / "only2.csv").resolve()
    assert find_data_file("only3.csv", (first,), defaults=(third,)) == (third / "only3.csv").resolve()
    with pytest.raises(FileNotFoundError) as err:
        find_data_file("nothere.csv", (first,), defaults=(third,))
    text = str(err.value)
    assert all(str(d / "nothere.csv") in text for d in (first, second, third))


def test_the_shipped_records_are_on_the_projects_data_path(monkeypatch, tmp_path):
    """A clone needs nothing beside it: a scenario finds its record in scenarios/records (no ../shared)."""
    monkeypatch.delenv(ENV_VAR, raising=False)
    monkeypatch.chdir(tmp_path)
    records = (PROJECT / "scenarios" / "records").resolve()
    for name in ("elcentro", "hachinohe", "northridge", "kobe"):
        loaded = load_scenario(PROJECT / "scenarios" / f"{name}.yaml")
        record = loaded.scenario.units["ground"].parameters["record"]
        assert isinstance(record, DataFile) and record.kind == "record"
        found = find_data_file(record.name, (), loaded.base_dir("units", "ground", "parameters", "record"),
                               HOOKS.default_data_dirs)
        assert found.parent == records
        assert check_record(found) is None


def system_yaml(fmu_dir: Path, extra: str = "", connections: str | None = None) -> str:
    conns = connections if connections is not None else """
          - ground.ag -> building.ag
          - building.x_0 -> isolator.x
          - building.v_0 -> isolator.v
          - isolator.F -> building.F"""
    return textwrap.dedent(f"""\
        units:
          ground:
            fmu: {fmu_dir}/GroundMotionSource.fmu
            parameters: {{record: !data elcentro_1940_ns.csv, scale: 0.5}}
          building:
            fmu: {fmu_dir}/ShearBuilding.fmu
          isolator:
            fmu: {fmu_dir}/MreIsolator.fmu
        connections:{textwrap.indent(textwrap.dedent(conns), "          ")}
        simulation: {{step: 0.001, stop_time: 0.01}}
        """) + textwrap.dedent(extra)


def resolve_problems(path: Path) -> list[str]:
    with pytest.raises(ScenarioError) as err:
        resolve_scenario(load_scenario(path), build=False)
    return [str(p) for p in err.value.problems]


def test_a_valid_system_resolves(fmu_dir, tmp_path, elcentro):
    plan = resolve_scenario(load_scenario(write(tmp_path, system_yaml(fmu_dir))), build=False)
    assert plan.parameters["ground"]["record"] == str(elcentro.resolve())
    assert len(plan.links) == 4


def test_connection_problems_are_all_reported(fmu_dir, tmp_path):
    conns = """
        - ground.ag -> building.ag
        - building.x_0 -> isolator.nope
        - building.v_0 -> isolator.F
        - ground.ag -> isolator.v
        - isolator.F -> building.F
        - isolator.F -> building.F
        - ghost.y -> building.ag"""
    text = "\n".join(resolve_problems(write(tmp_path, system_yaml(fmu_dir, connections=conns))))
    assert "connections[1]: isolator (MreIsolator) has no variable 'nope'" in text
    assert "connections[2]: isolator.F is output, expected input" in text
    assert "connections[3]: unit mismatch: ground.ag is in m/s2, isolator.v in m/s" in text
    assert "connections[5]: building.F is already driven by connections[4]" in text
    assert "connections[6]: no unit named 'ghost'" in text


def test_parameter_problems(fmu_dir, tmp_path):
    extra = """\
        outputs: [building.x_9]
        limits: {max_abs: {building.x_0: 0.1}}
        """
    text = system_yaml(fmu_dir, extra).replace("scale: 0.5", "scale: fast, n_storeys: 3")
    found = "\n".join(resolve_problems(write(tmp_path, text)))
    assert "units.ground.parameters.scale: 'scale' is Real [1], got 'fast'" in found
    assert "units.ground.parameters.n_storeys: GroundMotionSource has no variable 'n_storeys'" in found
    assert "outputs[0]: building (ShearBuilding) has no variable 'x_9'" in found


def test_a_misspelt_variable_gets_the_closest_name_of_the_right_causality(fmu_dir, tmp_path):
    conns = """
        - ground.ag -> building.ag
        - building.x_0 -> isolator.xx
        - building.v_0 -> isolator.v
        - isolator.Ff -> building.F"""
    text = system_yaml(fmu_dir, connections=conns).replace("scale: 0.5", "scale: 0.5, scal: 1.0, zzzz: 1.0")
    found = "\n".join(resolve_problems(write(tmp_path, text)))
    assert "GroundMotionSource has no variable 'scal' (did you mean 'scale'?)" in found
    assert "GroundMotionSource has no variable 'zzzz'\n" in found + "\n"  # nothing close: no suggestion
    assert "isolator (MreIsolator) has no variable 'xx' (did you mean 'x'?)" in found  # an input, not the output F
    assert "isolator (MreIsolator) has no variable 'Ff' (did you mean 'F'?)" in found


def test_missing_record_lists_the_places_searched(fmu_dir, tmp_path):
    text = system_yaml(fmu_dir).replace("elcentro_1940_ns.csv", "missing_quake.csv")
    found = "\n".join(resolve_problems(write(tmp_path, text)))
    assert "units.ground.parameters.record: data file 'missing_quake.csv' not found (searched:" in found


def test_not_an_fmu(fmu_dir, tmp_path):
    (tmp_path / "fake.fmu").write_text("not a zip")
    text = system_yaml(fmu_dir).replace(f"{fmu_dir}/MreIsolator.fmu", str(tmp_path / "fake.fmu"))
    found = "\n".join(resolve_problems(write(tmp_path, text)))
    assert "units.isolator.fmu:" in found and "not an FMU (not a zip archive)" in found


def test_algebraic_loop_is_a_scenario_error(fmu_dir, tmp_path):
    conns = """
        - building.a_0 -> building.ag
        - building.x_0 -> isolator.x
        - building.v_0 -> isolator.v
        - isolator.F -> building.F"""
    found = "\n".join(resolve_problems(write(tmp_path, system_yaml(fmu_dir, connections=conns))))
    assert "connections: algebraic loop" in found and "building.a_0 -> building.ag -> building.a_0" in found


@pytest.mark.parametrize("tool, file, hint", [
    ("run.py", "case_study.yaml", "this is a study file, not a scenario file: use python orchestration/study.py"),
    ("run.py", "identification.yaml", "this is an identification file, not a scenario file: "
                                      "use python orchestration/identify.py"),
    ("study.py", "kobe.yaml", "this is a scenario file, not a study file: use python orchestration/run.py"),
])
@pytest.mark.slow
def test_the_wrong_kind_of_file_names_the_right_tool(tmp_path, tool, file, hint):
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / tool), str(PROJECT / "scenarios" / file),
                           "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and hint in proc.stderr
    assert "unknown key" not in proc.stderr  # one line, not a wall of unknown keys
    assert not (tmp_path / "out").exists()


# -- strict values and bounded input ----------------------------------------------------------------


@pytest.mark.parametrize(("override", "message"), [
    ("simulation.step=true", "simulation.step: Input should be a valid number"),
    ("simulation.stop_time=.inf", "simulation.stop_time: Input should be a finite number"),
    ("simulation.step=1e-320", "more than 1e+12"),
    ("connections=[{source: ground.ag, target: building.ag, delayed: 1}]", "connections[0].delayed"),
    ("limits.max_abs={building.x_0: true}", "limits.max_abs.building.x_0"),
    ("ground.scale=.nan", "must be a finite number"),
    ("name=../escape", "must be a plain name"),
    ("x=&a [*a]", "an alias refers to the anchor that contains it"),
])
def test_values_are_strict(override, message):
    text = "\n".join(problems_of(SCENARIOS / "elcentro.yaml", [override]))
    assert message in text


def test_yaml_1_2_numbers_exponents_are_numbers_and_python_spellings_are_not(tmp_path):
    base = f"extends: {SCENARIOS / 'elcentro.yaml'}\n"
    loaded = load_scenario(write(tmp_path, base + "simulation: {step: 1e-3, stop_time: 2E1}\n"))
    assert loaded.scenario.simulation.step == 0.001 and loaded.scenario.simulation.stop_time == 20.0
    problems = problems_of(write(tmp_path, base + "simulation: {step: 1_0}\n", "u.yaml"))
    assert any("simulation.step: Input should be a valid number" in p for p in problems)


@pytest.mark.parametrize(("text", "message"), [
    (b"name: caf\xe9\n", "not UTF-8 text (byte 0xe9 at offset 9)"),
    (("a: " + "[" * 500 + "]" * 500).encode(), "nested more than 64 levels deep"),
    (("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True))).encode(),
     "expands to more than 20,000 values"),
    (b"a: &a {b: *a}\n", "recursive structure"),
    (b"a: !!float abc\n", "cannot read value"),
])
def test_hostile_yaml_is_a_scenario_error_naming_the_file(tmp_path, text, message):
    path = tmp_path / "h.yaml"
    path.write_bytes(text)
    problems = problems_of(path)
    assert any(message in p and "h.yaml" in p for p in problems), problems


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "extends fifo", "extends device"])
def test_only_regular_files_are_read(tmp_path, kind):
    import os

    if kind in ("fifo", "extends fifo"):
        os.mkfifo(tmp_path / "f.yaml")
    target = {"fifo": tmp_path / "f.yaml", "device": Path("/dev/zero"), "folder": tmp_path}.get(kind)
    if target is None:
        target = write(tmp_path, f"extends: {tmp_path / 'f.yaml' if 'fifo' in kind else '/dev/zero'}\n", "s.yaml")
    problems = problems_of(target)
    assert any("not a regular file" in p for p in problems), problems


def test_a_result_too_large_for_the_disk_budget_is_refused(monkeypatch, tmp_path):
    from orchestration.master.scenario import MEMORY_ENV, result_size_problem

    sim = load_scenario(SCENARIOS / "kobe.yaml").scenario.simulation
    # 150,001 rows x 26 columns x (8 bytes recorded + at most 20 bytes of CSV) = 104 MiB
    monkeypatch.setenv(MEMORY_ENV, "10")
    text = result_size_problem(sim, 25, tmp_path)
    assert "150,001 samples x 26 columns" in text and "104 MiB" in text and "10 MiB" in text
    monkeypatch.setenv(MEMORY_ENV, "200")
    assert result_size_problem(sim, 25, tmp_path) is None
    monkeypatch.delenv(MEMORY_ENV)  # the default budget is the free space where the results go
    assert result_size_problem(sim, 25, tmp_path / "not" / "yet") is None


def test_string_choices_declared_in_a_description():
    from orchestration.master.resolve import declared_choices

    assert declared_choices("'sosm' or 'passive' (constant current)") == ("sosm", "passive")
    assert declared_choices('one of "a", "b" | "c"') == ("a", "b", "c")
    assert declared_choices("the 'sosm' mode") == () and declared_choices("") == ()


@pytest.mark.parametrize(("fmi_type", "declared", "start", "value"), [
    ("Real", "", "0.5", 0.5),
    ("Real", "Float32", "-1e3", -1000.0),
    ("Real", "", "INF", float("inf")),
    ("Integer", "", "42", 42),
    ("Integer", "Int64", " -7 ", -7),
    ("Integer", "UInt64", "18446744073709551615", 2**64 - 1),  # exact: never through a float
    ("Enumeration", "", "2", 2),
    ("Boolean", "", "true", True),
    ("Boolean", "", " 1 ", True),  # xs:boolean: white space around the value is not part of it
    ("Boolean", "", "false", False),
    ("Boolean", "", "0", False),
    ("String", "", "fast", "fast"),
    ("Real", "", "not a number", "not a number"),  # text that does not parse is kept as it is
    ("Real array", "", "1 2", "1 2"),
])
def test_a_declared_start_value_is_read_by_its_declared_type(fmi_type, declared, start, value):
    from orchestration.master.unit import Variable, start_value

    var = Variable("v", 0, fmi_type, "parameter", "fixed", start=start, declared_type=declared)
    assert start_value(var) == value and type(start_value(var)) is type(value)


def _fmu_with_description(tmp_path, xml: str) -> Path:
    import zipfile

    path = tmp_path / "m.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", textwrap.dedent(xml).strip())
    return path


@pytest.mark.parametrize(("body", "expected"), [
    ('<ModelVariables><ScalarVariable name="x" valueReference="0"><Real/></ScalarVariable></ModelVariables>'
     '<ModelStructure><Outputs><Unknown index="1"/></Outputs></ModelStructure>', None),
    ("", "no <ModelVariables> element"),
    ('<ModelVariables><ScalarVariable valueReference="0"><Real/></ScalarVariable></ModelVariables>',
     "has no name attribute"),
    ('<ModelVariables><ScalarVariable name="x" valueReference="a"><Real/></ScalarVariable></ModelVariables>',
     "valueReference 'a' is not an integer"),
    ('<ModelVariables><ScalarVariable name="x" valueReference="0"/></ModelVariables>', "has 0 type elements"),
    ('<ModelVariables><ScalarVariable name="x" valueReference="0"><Real/></ScalarVariable></ModelVariables>'
     '<ModelStructure><Outputs><Unknown index="2"/></Outputs></ModelStructure>',
     'index="2"> (line 1) points at no variable (there are 1)'),
    ('<ModelVariables><ScalarVariable name="x" valueReference="0"><Real/></ScalarVariable></ModelVariables>'
     '<ModelStructure><Outputs><Unknown index="1" dependencies="1 5"/></Outputs></ModelStructure>',
     "dependencies '5' is not the index of a variable"),
    ('<UnitDefinitions><Unit name="m"><BaseUnit m="1.5"/></Unit></UnitDefinitions><ModelVariables/>',
     "the exponent must be an integer"),
])
def test_structure_problems_of_a_model_description_are_named(tmp_path, body, expected):
    from orchestration.master.fmu_description import structure_problem

    path = _fmu_with_description(tmp_path, f'<fmiModelDescription fmiVersion="2.0">{body}</fmiModelDescription>')
    found = structure_problem(path)
    assert (found is None) if expected is None else (found is not None and expected in found), found


def test_structure_problems_of_the_root_and_of_fmi3_references(tmp_path):
    from orchestration.master.fmu_description import structure_problem

    assert "not <fmiModelDescription>" in structure_problem(_fmu_with_description(tmp_path, "<other/>"))
    assert "FMI 1.0 FMU" in structure_problem(_fmu_with_description(
        tmp_path, '<fmiModelDescription fmiVersion="1.0"/>'))
    fmi3 = ('<fmiModelDescription fmiVersion="3.0"><ModelVariables><Float64 name="x" valueReference="7"/>'
            '</ModelVariables><ModelStructure><Output valueReference="{ref}"/></ModelStructure></fmiModelDescription>')
    assert structure_problem(_fmu_with_description(tmp_path, fmi3.format(ref=7))) is None
    text = structure_problem(_fmu_with_description(tmp_path, fmi3.format(ref=8)))
    assert text is not None and 'valueReference="8"> (line 1) points at no variable' in text and "there are" not in text


def test_an_fmu_name_longer_than_the_file_system_allows_is_a_scenario_error(tmp_path, capsys):
    """A name the OS refuses (ENAMETOOLONG) is exit 2 naming the key, not an internal error (found by
    test_reliability's property test)."""
    from orchestration.run import main

    code = main([str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "units.building.fmu=" + "A" * 300,
                 "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "units.building.fmu" in err and "not a usable file name" in err
    assert not (tmp_path / "out").exists()
