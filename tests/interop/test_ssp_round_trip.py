"""SSP round trips for every FMI type, and packages whose text XML cannot hold or should not contain.

Export → import → run must equal running the scenario itself: the same FMU, the same values, so the
same bits on one machine. SSP 1.0's ssv:Integer is 32-bit (xs:int): wider integers travel as the
digits in an ssv:String with an ``org.mre-cosim.value`` annotation naming their FMI type.
"""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from orchestration.engine_hooks import plan_scenario
from orchestration.interop.ssp_package import export_ssp, load_ssp
from orchestration.master.errors import ScenarioError
from orchestration.master.scenario import load_scenario

from ..support.typed_build import build_typed3

PROJECT = Path(__file__).resolve().parents[2]
INPUTS = {  # an FMI 3.0 value of every type, beyond xs:int where the type allows it
    "u_Float64": 0.1, "u_Float32": 1.5, "u_Int8": -128, "u_UInt8": 255, "u_Int16": -32768, "u_UInt16": 65535,
    "u_Int32": -2147483648, "u_UInt32": 4294967295, "u_Int64": 2**40 + 3, "u_UInt64": 2**52 + 1,
    "u_Boolean": True, "u_String": "a, \"quoted\" text", "u_Enumeration": "neg",
}
EXTREMES = {"u_Int64": -(2**63), "u_UInt64": 2**64 - 1}  # exact through the package, not recordable in a CSV


@pytest.fixture(scope="module")
def typed3(tmp_path_factory) -> Path:
    return build_typed3(tmp_path_factory.mktemp("typed"))


def scenario(folder: Path, fmu: Path, inputs: dict, description: str = "every FMI 3.0 type") -> Path:
    lines = ["name: types3", f"description: {json.dumps(description)}", "units:", "  a:", f"    fmu: {fmu}",
             "    parameters:", "      echo: true", "      k8: -7"]
    yaml_value = {str: repr, bool: lambda v: str(v).lower()}
    lines += [f"      {k}: {yaml_value.get(type(v), str)(v)}" for k, v in inputs.items()]
    recordable = [k for k, v in inputs.items() if isinstance(v, str | float | bool) or abs(v) <= 2**53]
    outputs = ", ".join(f"a.y_{k[2:]}" for k in recordable)
    lines += ["connections: []", f"outputs: [{outputs}]", "simulation:", "  step: 0.001", "  stop_time: 0.005"]
    path = folder / "types3.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def run(source: Path, out: Path) -> bytes:
    done = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), str(source), "--out", str(out),
                           "--no-plots", "--quiet"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return (out / "timeseries.csv").read_bytes()


def test_every_fmi_type_runs_the_same_from_its_package(typed3, tmp_path):
    yaml = scenario(tmp_path, typed3, INPUTS)
    package = export_ssp(plan_scenario(yaml), tmp_path / "types3.ssp")
    direct, through = run(yaml, tmp_path / "direct"), run(package, tmp_path / "package")
    assert through == direct
    _header, first = direct.decode().splitlines()[:2]
    assert "4294967295" in first and str(2**40 + 3) in first  # the echoed values, so the inputs did arrive


def test_64_bit_extremes_keep_their_exact_value(typed3, tmp_path):
    yaml = scenario(tmp_path, typed3, {**INPUTS, **EXTREMES})
    package = export_ssp(plan_scenario(yaml), tmp_path / "types3.ssp")
    with zipfile.ZipFile(package) as z:
        ssv = z.read("resources/a.ssv").decode()
    assert 'value="18446744073709551615"' in ssv and "org.mre-cosim.value" in ssv
    loaded = load_ssp(package)
    try:
        params = loaded.scenario.units["a"].parameters
        original = load_scenario(yaml).scenario.units["a"].parameters
        for name in EXTREMES:
            assert params[name] == original[name] and type(params[name]) is int
        assert params["u_Float32"] == 1.5 and params["u_Int8"] == -128
    finally:
        loaded.cleanup()


def test_an_annotated_value_outside_its_type_is_a_problem(typed3, tmp_path):
    package = export_ssp(plan_scenario(scenario(tmp_path, typed3, {**INPUTS, **EXTREMES})), tmp_path / "t.ssp")
    edited = tmp_path / "edited.ssp"
    with zipfile.ZipFile(package) as zin, zipfile.ZipFile(edited, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "resources/a.ssv":
                data = data.replace(b'value="18446744073709551615"', b'value="18446744073709551616"')
            zout.writestr(item.filename, data)
    with pytest.raises(ScenarioError) as exc:
        load_ssp(edited)
    assert "u_UInt64" in str(exc.value) and "outside UInt64's range" in str(exc.value)


def test_a_character_xml_cannot_hold_is_refused_before_anything_is_written(typed3, tmp_path):
    yaml = scenario(tmp_path, typed3, INPUTS, description="bell \x07 here")
    dest = tmp_path / "bell.ssp"
    done = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "ssp.py"), "export", str(yaml), str(dest)],
                          capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert "description" in done.stderr and "U+0007" in done.stderr
    assert not dest.exists() and list(tmp_path.glob("*.ssp*")) == []


@pytest.mark.parametrize("edit", [
    lambda t: t.replace("<?xml version='1.0' encoding='UTF-8'?>",
                        "<?xml version='1.0' encoding='UTF-8'?>\n<!DOCTYPE x [<!ENTITY e \"v\">]>", 1)
              .replace("<mre:Settings>", "<mre:Settings>&e;", 1),
    lambda t: t.replace('name="types3"', 'name="&undefined;"', 1),
    lambda t: t.replace("<mre:Settings>{", "<mre:Settings>{\"x\": " + "[" * 100_000 + "]" * 100_000 + ", ", 1),
], ids=["declared-entity", "undefined-entity", "deep-json"])
def test_hostile_ssd_text_is_a_problem_not_a_crash(typed3, tmp_path, edit):
    package = export_ssp(plan_scenario(scenario(tmp_path, typed3, INPUTS)), tmp_path / "t.ssp")
    edited = tmp_path / "edited.ssp"
    with zipfile.ZipFile(package) as zin, zipfile.ZipFile(edited, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            zout.writestr(item.filename, edit(data.decode()).encode() if item.filename.endswith(".ssd") else data)
    done = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), str(edited), "--out",
                           str(tmp_path / "out"), "--no-plots", "--quiet"], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    assert "SystemStructure.ssd" in done.stderr and not (tmp_path / "out").exists()
