"""A parameter outside its unit's domain is a configuration error before any run (exit 2, nothing written).

The check is the engine's generic ``ResolveHooks.parameter_check``; the project's hook
(orchestration/parameter_domains.py) hands each unit's resolved values to the rule in its
physics core, the same function the FMU applies when it initializes. So every case here is
checked twice: the scenario is refused naming the unit, the parameter and the line, and the
FMU itself, given the same value directly through fmpy (no master), fails at initialization.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from fmpy.fmi1 import FMICallException

from orchestration.building_report import REPORT
from orchestration.engine_hooks import resolve_scenario
from orchestration.master.errors import ScenarioError
from orchestration.master.scenario import load_scenario

from ..support.fmu_driver import Driven

PROJECT = Path(__file__).resolve().parents[2]
SCENARIOS = PROJECT / "scenarios"

# (scenario, --set overrides, unit, parameter, a text the problem must contain)
CASES = [
    ("kobe_yielding", ("building.fy_2=0.0",), "building", "fy_2", "must be a finite number > 0"),
    ("kobe_yielding", ("building.b_1=1.0",), "building", "b_1", "must be in [0, 1)"),
    ("kobe_yielding", ("building.b_3=-0.1",), "building", "b_3", "must be in [0, 1)"),
    ("kobe_yielding", ("building.hysteresis=bouc-wen", "building.n_2=0.5"), "building", "n_2", "must be >= 1"),
    ("kobe", ("building.p_delta=true", "building.h_1=3.0", "building.h_2=-1.0", "building.h_3=3.0"), "building",
     "h_2", "must be > 0 for P-Delta"),
    ("kobe", ("building.m_2=-1.0",), "building", "m_2", "masses must be positive"),
    ("kobe", ("isolator.beyond_range=stop", "isolator.k_stop=-1.0"), "isolator", "k_stop", "must not be negative"),
    ("kobe", ("isolator.beyond_range=stop", "isolator.x_limit=0.005"), "isolator", "x_limit", "must exceed"),
    ("elcentro_c_isolator", ("isolator.beyond_range=stop", "isolator.c_stop=-5.0"), "isolator", "c_stop",
     "must not be negative"),
    ("elcentro_clipped_optimal", ("controller.q_drift=-1.0",), "controller", "q_drift", "must be >= 0"),
    ("elcentro_clipped_optimal", ("controller.i_nom=4.0",), "controller", "i_nom", "must lie in [0, i_max"),
    ("elcentro_clipped_optimal", ("controller.law=bang",), "controller", "law", "law must be one of"),
    ("elcentro_clipped_optimal", ("controller.r_acc=0.0",), "controller", "r_acc", "must be positive"),
    ("elcentro_lyapunov", ("controller.q_acc=-2.0",), "controller", "q_acc", "must be >= 0"),
    ("elcentro_frequency", ("controller.window=1",), "controller", "window", "at least two steps"),
    ("elcentro_frequency", ("controller.m_2=0.0",), "controller", "m_2", "must be positive"),
    ("kobe", ("controller.lambda=0.0",), "controller", "lambda", "must be positive"),
    # designs that cannot be made from values each in its own domain: found before any run, not at t = 0
    ("elcentro_clipped_optimal", ("controller.r=0.0", "controller.q_acc=0.0"), "controller", "r",
     "control weight must be positive"),
    ("elcentro_clipped_optimal", ("controller.s_ground=0.0", "controller.s_force=0.0"), "controller", "s_ground",
     "are both 0"),
    ("elcentro_lyapunov", ("controller.s_ground=0.0", "controller.s_force=0.0"), "controller", "s_ground",
     "are both 0"),
    ("nominal_plant_elcentro", ("coil.tau=-0.01",), "coil", "tau", "must be >= 0 s"),
]


def _problems(scenario: str | Path, overrides: tuple[str, ...] = ()) -> list:
    loaded = load_scenario(SCENARIOS / f"{scenario}.yaml" if isinstance(scenario, str) else scenario, overrides,
                           REPORT.model)
    try:
        resolve_scenario(loaded)
    except ScenarioError as exc:
        return exc.problems
    return []


@pytest.mark.parametrize(("scenario", "overrides", "unit", "parameter", "text"), CASES,
                         ids=[f"{c[0]}-{c[3]}" for c in CASES])
def test_out_of_domain_value_is_a_scenario_error_naming_unit_parameter_and_line(scenario, overrides, unit,
                                                                                parameter, text):
    problems = _problems(scenario, overrides)
    assert len(problems) == 1, problems
    (problem,) = problems
    assert problem.key == f"units.{unit}.parameters.{parameter}"
    assert text in problem.message
    setter = next(o for o in overrides if o.startswith(f"{unit}.{parameter}="))
    assert problem.file == f"--set {setter}"  # where the value came from


def test_the_shipped_scenarios_pass_the_check():
    for scenario in ("kobe_yielding", "elcentro_clipped_optimal", "elcentro_lyapunov", "elcentro_frequency",
                     "elcentro_c_isolator"):
        assert _problems(scenario) == [], scenario
    # the paper's law at 3 A is stiffer (6.57 MN/m past 8 mm) than the default 5 MN/m stop: a stop that stops it is set
    stop = ("isolator.beyond_range=stop", "isolator.k_stop=1e7")
    assert _problems("kobe", (*stop, "building.hysteresis=bouc-wen")) == []


def test_a_value_from_a_file_names_that_file_and_line(tmp_path):
    scenario = tmp_path / "weak.yaml"
    scenario.write_text(f"extends: {SCENARIOS / 'kobe_yielding.yaml'}\nname: weak\nunits:\n  building:\n"
                        "    parameters:\n      fy_3: -100.0\n")
    (problem,) = _problems(scenario)
    assert (problem.file, problem.line, problem.key) == (str(scenario), 6, "units.building.parameters.fy_3")


def test_a_declared_start_at_fault_is_named_at_the_unit():
    # P-Delta on, storey heights left at their declared start 0 m: the unit and the parameter are named
    (problem,) = _problems("kobe", ("building.p_delta=true",))
    assert problem.key == "units.building"
    assert problem.message.startswith("h_1 (declared start value): ") and "must be > 0 for P-Delta" in problem.message
    assert problem.file.endswith("isolated_building.yaml") and problem.line is not None


def _driven_fails(fmu: Path, parameters: dict) -> bool:
    """True if the FMU, given these parameters directly, fails at initialization or at its first step."""
    try:
        unit = Driven(fmu, "domain", parameters)
    except FMICallException:
        return True
    try:
        unit.step(0.0, 1e-3)
    except FMICallException:
        return True
    finally:
        unit.close(terminate=False)
    return False


FMU_CASES = [
    ("ShearBuilding", {"hysteresis": "bilinear", "fy_2": 0.0}),
    ("ShearBuilding", {"hysteresis": "bilinear", "b_1": 1.0}),
    ("ShearBuilding", {"p_delta": True, "h_1": 3.0, "h_2": -1.0, "h_3": 3.0}),
    ("MreIsolator", {"beyond_range": "stop", "k_stop": -1.0}),
    ("MreIsolatorC", {"beyond_range": "stop", "c_stop": -5.0}),
    ("BoucWenIsolator", {"gamma_1": -2000.0}),
    ("ClippedOptimalCurrentController", {"q_drift": -1.0}),
    ("LyapunovCurrentController", {"q_acc": -2.0}),
    ("FrequencyCurrentController", {"window": 1}),
    ("SosmCurrentController", {"lambda": 0.0}),
]


@pytest.mark.parametrize(("name", "parameters"), FMU_CASES, ids=[f"{c[0]}-{next(iter(c[1]))}" for c in FMU_CASES])
def test_the_fmu_itself_refuses_what_the_check_refuses(name, parameters, capfd):
    """The independent side: the FMU, driven by fmpy alone, refuses the same value (one rule, in the core)."""
    _problems("kobe")  # the project's FMUs up to date in fmus/ (built on demand)
    fmu = PROJECT / "fmus" / f"{name}.fmu"
    assert _driven_fails(fmu, parameters)
    assert "[ERROR]" in capfd.readouterr().out
    good = {k: v for k, v in parameters.items() if k in ("hysteresis", "beyond_range", "p_delta")}
    if good.get("p_delta"):
        good.update(h_1=3.0, h_2=3.0, h_3=3.0)
    if good.get("beyond_range") == "stop":
        good["k_stop"] = 1.0e7  # stiffer than the paper's law past 8 mm at 3 A (6.57 MN/m): a stop that stops it
    assert not _driven_fails(fmu, good)  # and accepts the same unit without the bad value


@pytest.fixture(scope="module")
def opensees():
    from components.physics.opensees_building_core import OpenSeesUnavailable, import_opensees

    try:
        import_opensees()
    except OpenSeesUnavailable as exc:
        pytest.skip(str(exc))


@pytest.mark.parametrize(("source", "text"), [
    ("import math\nBASE_NODE = 1\nFLOOR_NODES = [2, 3, 4]\nraise RuntimeError('no such section')\n",
     "line 4: RuntimeError: no such section"),
    ("ops.model('basic', '-ndm', 1, '-ndf', 1)\nops.node(1, 0.0)\n", "defines no BASE_NODE"),
])
def test_an_opensees_script_that_raises_or_defines_no_base_node_is_refused(opensees, tmp_path, source, text):
    script = tmp_path / "bad_model.py"
    script.write_text(source)
    for value in (f"!data {script}", str(script)):  # a data file (found on the data path) or a plain path
        (problem,) = _problems("elcentro_opensees", (f"building.script={value}",))
        assert problem.key == "units.building.parameters.script" and text in problem.message
    assert _problems("elcentro_opensees") == []  # the shipped linear Dyke script passes


def test_cli_exit_2_names_unit_parameter_and_line_and_writes_nothing(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), str(SCENARIOS / "kobe.yaml"),
                           "--set", "controller.lambda=-1", "--set", "building.substeps=4", "--out", str(out),
                           "--no-plots"], capture_output=True, text=True, timeout=120, cwd=PROJECT)
    assert proc.returncode == 2, proc.stderr
    assert "--set controller.lambda=-1: units.controller.parameters.lambda: SOSM gain lam must be positive" \
        in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not out.exists()


def test_a_sensor_delay_out_of_its_domain_is_refused_before_any_run(tmp_path):
    """SensorChannels: a delay of -1 step (or a fraction), a negative noise RMS: the unit and parameter named."""
    scenario = tmp_path / "sensed.yaml"
    scenario.write_text(f"extends: {SCENARIOS / 'nominal_plant_elcentro.yaml'}\nname: sensed\nunits:\n"
                        f"  sensors:\n    fmu: {PROJECT / 'fmus' / 'SensorChannels.fmu'}\n")
    assert _problems(scenario) == []
    for setter, parameter, text in (("sensors.delay=-1", "delay", "whole number of communication steps"),
                                    ("sensors.rms_disp_1=-0.001", "rms_disp_1", "must be >= 0")):
        (problem,) = _problems(scenario, (setter,))
        assert problem.key == f"units.sensors.parameters.{parameter}" and text in problem.message, problem


def test_the_design_checks_agree_with_the_controllers_own_construction():
    """The independent side of the design checks: the controller class itself fails on the values refused, and
    builds on the shipped ones (so the check refuses nothing the unit could run)."""
    from components.physics import clipped_optimal_core as co

    values = {f"{n}_{j}": v for n, vs in (("m", (98.3, 98.3, 98.3, 98.3)), ("k", (0.0, 6.84e5, 6.84e5, 6.84e5)),
                                          ("c", (0.0, 0.0, 0.0, 0.0))) for j, v in enumerate(vs)}
    assert co.parameter_problem(values) is None
    co.ClippedOptimalController(*co.controller_parts(values))
    bad = {**values, "r": 0.0, "q_acc": 0.0}
    assert co.parameter_problem(bad)[0] == "r"
    with pytest.raises(ValueError, match="control weight"):
        co.ClippedOptimalController(*co.controller_parts(bad))
