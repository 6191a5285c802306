"""Unit errors reach a host that did not turn debug logging on (issue #12).

pythonfmu 0.7 hands a message to the host only when the host instantiated the unit with
``loggingOn`` (and only in the categories it named), and reports a failed ``do_step`` as
fmi2Discard. So ``fmpy simulate`` (no debug logging) ran a missing record to the end with
exit 0 and rows of zeros, and a host without scipy saw only "Failed to instantiate model".
The build's logging shim (components/build/fmi2_log_shim.c) forwards warnings and errors
always and makes our units' failed steps fmi2Error. Checked with fmpy, in child processes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from .conftest import PROJECT


def _fmpy(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fmpy.cli", *args], capture_output=True, text=True, timeout=120,
                          cwd=PROJECT, env=env)


def test_a_missing_record_fails_fmpy_simulate_with_the_path(fmu_dir, tmp_path):
    missing = tmp_path / "no_such_record.csv"
    done = _fmpy("simulate", str(fmu_dir / "GroundMotionSource.fmu"), "--start-values", "record", str(missing),
                 "--stop-time", "0.05", "--output-file", str(tmp_path / "out.csv"))
    output = done.stdout + done.stderr
    assert done.returncode != 0, output  # before: exit 0 and a file of zeros
    # fmpy prints the units' messages on stdout, its own exception on stderr
    assert f"[ERROR] cannot use the ground-motion record: {missing}: no such file" in done.stdout
    assert "fmi2DoStep failed with status 3 (error)" in done.stderr


_CATEGORIES = textwrap.dedent("""
    import shutil, sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    fmu, record, categories = sys.argv[1], sys.argv[2], sys.argv[3:]
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    folder = extract(fmu)
    unit = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName="ground")
    unit.instantiate(loggingOn=False)
    if categories:
        unit.setDebugLogging(True, categories)
    unit.setupExperiment(startTime=0.0)
    unit.setString([vr["record"]], [record])
    unit.enterInitializationMode()
    unit.exitInitializationMode()
    try:
        unit.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
    except Exception as exc:
        print("STEP FAILED:", getattr(exc, "status", exc), flush=True)
    unit.terminate()
    unit.freeInstance()
    shutil.rmtree(folder, ignore_errors=True)
""")


@pytest.mark.slow
def test_errors_reach_the_logger_whatever_the_categories(fmu_dir, tmp_path):
    missing = tmp_path / "gone.csv"
    for categories in ([], ["logStatusWarning"], ["logAll"], ["noSuchCategory"]):
        done = subprocess.run([sys.executable, "-c", _CATEGORIES, str(fmu_dir / "GroundMotionSource.fmu"),
                               str(missing), *categories], capture_output=True, text=True, timeout=120, cwd=PROJECT)
        assert done.returncode == 0, done.stderr[-2000:]
        errors = [line for line in done.stdout.splitlines() if line.startswith("[ERROR]")]
        # logged on leaving initialization mode and again by the failing step, both with the path
        assert len(errors) == 2 and all(str(missing) in line for line in errors), (categories, done.stdout)
        assert "STEP FAILED: 3" in done.stdout, (categories, done.stdout)


def test_a_host_without_scipy_is_told_why_the_building_cannot_start(fmu_dir, tmp_path):
    hide = tmp_path / "hide"
    (hide / "scipy").mkdir(parents=True)
    (hide / "scipy" / "__init__.py").write_text("raise ModuleNotFoundError(\"No module named 'scipy'\")\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(hide)  # before site-packages: the host's scipy is hidden
    check = subprocess.run([sys.executable, "-c", "import scipy"], capture_output=True, text=True, env=env)
    assert check.returncode != 0  # the hiding works
    done = _fmpy("simulate", str(fmu_dir / "ShearBuilding.fmu"), "--stop-time", "0.01",
                 "--output-file", str(Path(tmp_path) / "out.csv"), env=env)
    assert done.returncode != 0
    assert "[FATAL]" in done.stdout, done.stdout + done.stderr  # before: nothing but "Failed to instantiate model"
    assert "the ShearBuilding unit needs the Python packages numpy and scipy" in done.stdout
    assert "No module named 'scipy'" in done.stdout
