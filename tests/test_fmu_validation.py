"""A malformed model description is a scenario error (exit 2) that quotes fmpy's validation."""

from __future__ import annotations

import re
import zipfile

import pytest

from orchestration.api import ScenarioError, load_scenario

from .conftest import PROJECT


def _with_duplicate_variable(src, dest) -> None:
    """Copy an FMU, declaring its parameter ``current`` a second time under another value reference."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                xml = data.decode()
                m = re.search(r'<ScalarVariable\s+name="current".*?</ScalarVariable>', xml, re.S)
                duplicate = re.sub(r'valueReference="\d+"', 'valueReference="999"', m.group(0))
                xml = xml.replace("</ModelVariables>", duplicate + "\n</ModelVariables>")
                data = xml.encode()
            zout.writestr(item, data)


def test_an_fmu_declaring_a_variable_twice_is_refused_with_fmpys_reason(tmp_path, fmu_dir):
    # fmpy's own validation rejects this FMU; before, the master bound one of the two and ran.
    bad = tmp_path / "ConstantCurrent.fmu"
    _with_duplicate_variable(fmu_dir / "ConstantCurrent.fmu", bad)
    with pytest.raises(ScenarioError) as info:
        load_scenario(PROJECT / "scenarios" / "elcentro_constant_current.yaml", [f"units.controller.fmu={bad}"])
    [problem] = info.value.problems
    assert problem.key == "units.controller.fmu"
    assert "invalid modelDescription.xml" in problem.message and "current" in problem.message
