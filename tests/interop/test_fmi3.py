"""FMI 3.0 co-simulation units in the master (orchestration.master.fmi3_cosim_unit).

The unit under test is ``ConstantCurrent3``, a plain-C FMI 3.0 FMU built here from
``tests/support/fmi3/constant_current3.c`` (tests/support/fmi3_build.py): i = count * current + offset
when enabled, with failure injection (fail_at, fail_mode) and log messages from
fmi3Terminate/fmi3FreeInstance that show which teardown calls the master made.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy.validation import validate_fmu

from orchestration.engine_hooks import plan_scenario, run_scenario
from orchestration.master.errors import ScenarioError, SimulationError, UnitCallError
from orchestration.master.fmi2_cosim_unit import FmuUnit
from orchestration.master.fmi3_cosim_unit import Fmu3Unit
from orchestration.master.fmi_status import FMI3_STATUS, LogRecord, check_status
from orchestration.master.fmu_description import FmuFormatError, read_description
from orchestration.master.session import run_plan

from ..conftest import PROJECT
from ..support.fmi3_build import (
    FMI1_DESCRIPTION,
    FMI2_ME_DESCRIPTION,
    FMI3_ME_DESCRIPTION,
    VARIABLES,
    build_constant_current3,
    model_description,
    write_fmu,
)

SWAP_SCENARIO = PROJECT / "scenarios" / "elcentro_constant_current.yaml"
VR_I, VR_OFFSET = VARIABLES["i"][0], VARIABLES["offset"][0]


@pytest.fixture(scope="module")
def fmu3(tmp_path_factory) -> Path:
    return build_constant_current3(tmp_path_factory.mktemp("fmi3"))


def scenario_with_controller(tmp_path: Path, fmu: Path, name: str = "elcentro_fmi3") -> Path:
    """El Centro with the controller swapped for ``fmu`` (extends the shipped swap scenario)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"extends: {SWAP_SCENARIO}\nname: {name}\nunits:\n  controller:\n    fmu: {fmu}\n")
    return path


def run_capturing_units(path: Path, overrides: tuple[str, ...], out: Path):
    """Run a scenario and keep the unit objects the run created (to inspect them afterwards)."""
    plan = plan_scenario(path, overrides)
    created: list = []
    create = plan.create_units

    def capture(on_log=None):
        created.extend(create(on_log))
        return created

    plan.create_units = capture
    return run_plan(plan, out, plots=False), created


def driven(fmu: Path, parameters: dict | None = None, name: str = "c") -> Fmu3Unit:
    unit = Fmu3Unit(name, fmu, parameters)
    unit.setup(0.0, 1.0)
    unit.exit_initialization()
    return unit


def messages(unit: Fmu3Unit) -> list[str]:
    return [r.message for r in unit.log]


# -- the unit itself ---------------------------------------------------------------------------------


def test_fmi3_unit_passes_fmpy_validate(fmu3):
    assert validate_fmu(str(fmu3)) == []
    proc = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(fmu3)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0 and "No problems found" in proc.stdout, proc.stdout + proc.stderr


def test_fmi3_description_types_units_and_dependencies(fmu3, tmp_path):
    desc, _ = read_description(fmu3, "c")
    assert desc.fmi_version == "3.0" and desc.model_identifier == "ConstantCurrent3"
    v = desc.variables
    assert {n: v[n].type for n in VARIABLES} == {
        "time": "Real", "current": "Real", "i": "Real", "offset": "Real", "fail_at": "Real",
        "fail_mode": "Integer", "count": "Integer", "enabled": "Boolean", "tag": "String"}
    assert {n: v[n].vr for n in VARIABLES} == {n: vr for n, (vr, _, _) in VARIABLES.items()}
    # unit from the declaredType (Current, A) and from the variable itself (s)
    assert (v["current"].unit, v["i"].unit, v["offset"].unit, v["fail_at"].unit) == ("A", "A", "A", "s")
    assert v["count"].unit is None
    assert [x.name for x in desc.outputs()] == ["i"] and [x.name for x in desc.inputs()] == ["offset"]
    assert v["time"].causality == "independent"
    assert desc.dependencies == {"i": ("offset",)} and desc.feedthrough("i") == ("offset",)
    # declared as no dependency at all, and not declared (None: every input)
    dest = tmp_path / "other"
    dest.mkdir()
    none = write_fmu(dest / "none.fmu", {"modelDescription.xml": model_description("{x}", "")})
    undeclared = write_fmu(dest / "undeclared.fmu", {"modelDescription.xml": model_description("{x}", None)})
    assert read_description(none, "c")[0].dependencies == {"i": ()}
    d = read_description(undeclared, "c")[0]
    assert d.dependencies == {"i": None} and d.feedthrough("i") == ("offset",)


def test_fmi3_types_the_master_does_not_exchange_keep_their_names(tmp_path):
    xml = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="T" instantiationToken="{t}">
  <CoSimulation modelIdentifier="T"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <UInt8 name="n" valueReference="1" causality="parameter" variability="fixed" start="1"/>
    <Float64 name="y" valueReference="2" causality="output" variability="continuous">
      <Dimension start="3"/>
    </Float64>
    <Float32 name="z" valueReference="3" causality="output" variability="continuous"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="2" dependencies=""/>
    <Output valueReference="3" dependencies=""/>
  </ModelStructure>
</fmiModelDescription>
"""
    desc, _ = read_description(write_fmu(tmp_path / "t.fmu", {"modelDescription.xml": xml}), "t")
    assert {n: desc.variables[n].type for n in ("n", "y", "z")} == {"n": "UInt8", "y": "Float64 array",
                                                                      "z": "Float32"}


def test_fmi3_unit_protocol_parameters_get_set_step(fmu3):
    unit = driven(fmu3, {"current": 2.5, "count": 3, "enabled": True, "tag": "north", "fail_mode": 0})
    try:
        out, inp = unit.prepare([VR_I]), unit.prepare([VR_OFFSET])
        assert unit.get_real(out).tolist() == [7.5]  # 3 * 2.5 + 0
        for k in range(5):
            unit.set_real(inp, np.array([0.25 * k]))
            unit.step(0.1 * k, 0.1)
            assert unit.get_real(out).tolist() == [7.5 + 0.25 * k]
        names = ["count", "enabled", "tag", "fail_mode", "current"]
        variables = unit.description.variables
        assert [unit.get_values(variables[n].fmi_type, [variables[n].vr])[0] for n in names] == [
            3, True, "north", 0, 2.5]
        assert unit.get_real(unit.prepare([])).size == 0
    finally:
        unit.terminate()
    assert unit.freed
    assert messages(unit) == ["tag: north", "fmi3Terminate", "fmi3FreeInstance"]
    disabled = driven(fmu3, {"current": 2.5, "enabled": False})
    try:
        assert disabled.get_real(disabled.prepare([VR_I])).tolist() == [0.0]
    finally:
        disabled.terminate()


def test_fmi3_parameter_errors_name_the_parameter(fmu3):
    for parameters, text in (({"fail_mode": 7}, "fail_mode must be 0..3"), ({"fail_mode": 2**31}, "out of range")):
        unit = Fmu3Unit("c", fmu3, parameters)
        try:
            with pytest.raises(SimulationError) as info:
                unit.setup(0.0, 1.0)
        finally:
            unit.terminate()
        assert info.value.unit == "c" and info.value.variable == "fail_mode"
        assert text in str(info.value)
        assert unit.freed


def test_fmi3_log_messages_reach_their_own_unit(fmu3):
    seen: list[tuple[str, LogRecord]] = []
    a = Fmu3Unit("a", fmu3, {"tag": "alpha"}, on_log=lambda u, r: seen.append((u, r)))
    b = Fmu3Unit("b", fmu3, {"tag": "beta"}, on_log=lambda u, r: seen.append((u, r)))
    try:
        for unit in (a, b):
            unit.setup(0.0, 1.0)
        for unit in (b, a):
            unit.exit_initialization()
    finally:
        a.terminate()
        b.terminate()
    assert messages(a) == ["tag: alpha", "fmi3Terminate", "fmi3FreeInstance"]
    assert messages(b) == ["tag: beta", "fmi3Terminate", "fmi3FreeInstance"]
    assert [(u, r.message) for u, r in seen][:2] == [("b", "tag: beta"), ("a", "tag: alpha")]
    assert all(r.status == "ok" and r.category == "logEvents" for _, r in seen)


# -- failures and the FMI 3.0 teardown rules --------------------------------------------------------


def test_fmi3_error_status_is_a_unit_call_error_then_free_without_terminate(fmu3):
    unit = driven(fmu3, {"current": 1.0, "fail_at": 0.2, "fail_mode": 1})
    try:
        unit.step(0.0, 0.1)
        unit.step(0.1, 0.1)
        with pytest.raises(UnitCallError) as info:
            unit.step(0.2, 0.1)  # first step whose midpoint is past 0.2 s
    finally:
        unit.terminate()
    err = info.value
    assert (err.unit, err.function, err.status) == ("c", "fmi3DoStep", "error")
    assert err.time == pytest.approx(0.2)
    assert err.details == ("[error] injected error at t = 0.2 s (fail_at = 0.2 s)",)
    assert unit.freed
    assert messages(unit)[-1] == "fmi3FreeInstance" and "fmi3Terminate" not in messages(unit)


def test_fmi3_terminate_simulation_is_a_simulation_error_then_terminate_and_free(fmu3):
    unit = driven(fmu3, {"fail_at": 0.2, "fail_mode": 2})
    try:
        unit.step(0.0, 0.1)
        unit.step(0.1, 0.1)
        with pytest.raises(SimulationError) as info:
            unit.step(0.2, 0.1)
    finally:
        unit.terminate()
    err = info.value
    assert not isinstance(err, UnitCallError)
    assert err.unit == "c" and err.time == pytest.approx(0.3)
    assert "terminateSimulation" in str(err) and "unit 'c'" in str(err) and "t = 0.3 s" in str(err)
    assert unit.warnings == 1
    assert messages(unit)[-2:] == ["fmi3Terminate", "fmi3FreeInstance"]
    assert unit.freed


def test_fmi3_fatal_status_leaves_the_instance_alone(fmu3):
    unit = driven(fmu3, {"fail_at": 0.0, "fail_mode": 3})
    try:
        with pytest.raises(UnitCallError) as info:
            unit.step(0.0, 0.1)
    finally:
        unit.terminate()
    assert info.value.status == "fatal" and info.value.time == 0.0
    assert messages(unit) == ["injected fatal error at t = 0 s"]  # neither fmi3Terminate nor fmi3FreeInstance
    assert unit.freed


def test_status_translation_is_shared_by_both_fmi_versions():
    log = [LogRecord("ok", "", "fine"), LogRecord("warning", "", "careful"), LogRecord("error", "", "broken")]
    for status in (0, 1):
        check_status("u", "f", status, 1.0, log)
        check_status("u", "f", status, 1.0, log, FMI3_STATUS)
    with pytest.raises(UnitCallError) as info:
        check_status("u", "fmi3DoStep", 2, 1.5, log, FMI3_STATUS)
    assert (info.value.status, info.value.time, info.value.details) == ("discard", 1.5,
                                                                        ("[warning] careful", "[error] broken"))
    with pytest.raises(UnitCallError, match="returned pending"):
        check_status("u", "fmi2DoStep", 5, 0.0, log)
    with pytest.raises(UnitCallError, match="illegal status 5"):  # fmi3Status has no pending
        check_status("u", "fmi3DoStep", 5, 0.0, log, FMI3_STATUS)


# -- in a scenario ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_fmi3_controller_in_a_scenario_equals_the_fmi2_units(tmp_path, fmu3, elcentro):
    """The FMI 3.0 constant-current unit swapped in for the controller gives exactly the columns of the
    pythonfmu ConstantCurrent unit and of the SOSM unit's passive mode at the same current."""
    path = scenario_with_controller(tmp_path, fmu3)
    fmi3, units = run_capturing_units(path, ("simulation.stop_time=2", "controller.current=3.0"), tmp_path / "a")
    fmi2 = run_scenario(SWAP_SCENARIO, ("simulation.stop_time=2", "controller.current=3.0"), out=tmp_path / "b",
                        plots=False)
    passive = run_scenario(PROJECT / "scenarios" / "elcentro.yaml",
                           ("simulation.stop_time=2", "controller.mode=passive", "controller.i_passive=3.0"),
                           out=tmp_path / "c", plots=False)
    assert fmi3.result.complete and fmi2.result.complete and passive.result.complete
    kinds = {u.name: type(u) for u in units}
    assert kinds["controller"] is Fmu3Unit and kinds["building"] is FmuUnit
    assert all(u.freed for u in units)
    assert fmi3.recorder.count == 2001
    assert np.all(fmi3.recorder.column("controller.i") == 3.0)
    for other in (fmi2, passive):
        assert fmi3.recorder.names == other.recorder.names
        assert np.array_equal(fmi3.recorder.times, other.recorder.times)
        for name in fmi3.recorder.names:
            assert np.array_equal(fmi3.recorder.column(name), other.recorder.column(name)), name


def test_fmi3_error_in_a_scenario_fails_the_run_naming_unit_and_time(tmp_path, fmu3, elcentro):
    path = scenario_with_controller(tmp_path, fmu3)
    outcome, units = run_capturing_units(
        path, ("simulation.stop_time=1", "controller.current=3.0", "controller.fail_at=0.5"), tmp_path / "run")
    result = outcome.result
    assert result.status == "failed" and not outcome.summary["complete"]
    err = result.error
    assert isinstance(err, UnitCallError) and err.unit == "controller" and err.function == "fmi3DoStep"
    assert err.time == pytest.approx(0.5) and result.steps_done == 500
    assert "unit 'controller'" in outcome.summary["error"] and "t = 0.5 s" in outcome.summary["error"]
    assert "injected error at t = 0.5 s" in outcome.summary["error"]
    assert outcome.recorder.count == 501  # rows up to the last completed step
    assert len(units) == 4 and all(u.freed for u in units)
    controller = next(u for u in units if u.name == "controller")
    assert messages(controller)[-1] == "fmi3FreeInstance" and "fmi3Terminate" not in messages(controller)


# -- what is still refused ---------------------------------------------------------------------------


@pytest.mark.parametrize(("xml", "text"), [
    (FMI1_DESCRIPTION, "FMI 1.0 FMU; this master runs FMI 2.0 (co-simulation or model exchange) and FMI 3.0 "
                       "co-simulation FMUs"),
    (FMI3_ME_DESCRIPTION, "FMI 3.0 FMU without Co-Simulation (model exchange only); this master runs FMI 3.0 FMUs "
                          "as co-simulation (model exchange: FMI 2.0 only)"),
], ids=["fmi1", "fmi3-me"])
def test_fmi1_and_fmi3_model_exchange_only_fmus_are_refused(tmp_path, xml, text):
    fmu = write_fmu(tmp_path / "unit.fmu", {"modelDescription.xml": xml})
    with pytest.raises(FmuFormatError) as info:
        read_description(fmu, "controller")
    assert str(info.value) == f"{fmu}: {text}"
    with pytest.raises(ScenarioError) as scenario_error:
        plan_scenario(scenario_with_controller(tmp_path, fmu, "refused"), ("simulation.stop_time=1",))
    (problem,) = scenario_error.value.problems
    assert problem.key == "units.controller.fmu" and problem.message == f"{fmu}: {text}"


def test_an_fmi2_model_exchange_only_fmu_is_accepted_and_its_binary_checked(tmp_path):
    """FMI 2.0 model exchange runs (tests/interop/test_model_exchange.py); this description-only FMU lacks the
    library."""
    fmu = write_fmu(tmp_path / "unit.fmu", {"modelDescription.xml": FMI2_ME_DESCRIPTION})
    assert read_description(fmu, "controller")[0].model_identifier == "Me2"
    with pytest.raises(ScenarioError) as scenario_error:
        plan_scenario(scenario_with_controller(tmp_path, fmu, "me_only"), ("simulation.stop_time=1",))
    binary, parameter = scenario_error.value.problems  # its description was read: Me2 has no 'current'
    assert binary.key == "units.controller.fmu"
    assert binary.message.startswith(f"{fmu}: no library for this platform, binaries/") and "Me2" in binary.message
    assert parameter.message == "Me2 has no variable 'current'"
