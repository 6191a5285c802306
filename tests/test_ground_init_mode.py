"""The ground-motion unit takes its parameters in the Instantiated state and in Initialization mode alike."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np

from components.physics.ground_motion_core import GroundMotion, read_record

from .conftest import PROJECT

# Driven with fmpy's low-level API in a child process (one pythonfmu FMU per interpreter
# here, as a third-party host such as ecos would load it): set record and scale before
# fmi2EnterInitializationMode (as our master does) or after it (as ecos does).
_DRIVER = textwrap.dedent("""
    import json, shutil, sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    fmu, record, when = sys.argv[1], sys.argv[2], sys.argv[3]
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    folder = extract(fmu)
    unit = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName="ground")
    unit.instantiate()
    unit.setupExperiment(startTime=0.0)
    def parameters():
        unit.setString([vr["record"]], [record])
        unit.setReal([vr["scale"]], [0.5])
    if when == "instantiated":
        parameters()
    unit.enterInitializationMode()
    if when == "initialization":
        parameters()
    unit.exitInitializationMode()
    out = []
    for k in range(2000):
        ok = unit.doStep(currentCommunicationPoint=k * 0.01, communicationStepSize=0.01)
        out.append(unit.getReal([vr["ag"]])[0])
    unit.terminate()
    unit.freeInstance()
    shutil.rmtree(folder, ignore_errors=True)
    print(json.dumps(out))
""")


def _drive(fmu, record, when: str) -> np.ndarray:
    done = subprocess.run([sys.executable, "-c", _DRIVER, str(fmu), str(record), when], capture_output=True,
                          text=True, timeout=120, cwd=PROJECT)
    assert done.returncode == 0, done.stderr[-2000:]
    return np.asarray(json.loads(done.stdout.strip().splitlines()[-1]))


def test_parameters_set_in_initialization_mode_are_used(fmu_dir, elcentro):
    before = _drive(fmu_dir / "GroundMotionSource.fmu", elcentro, "instantiated")
    during = _drive(fmu_dir / "GroundMotionSource.fmu", elcentro, "initialization")
    # The record played by the physics core at the step ends (t = k h + h, as the unit forms
    # it): the same interpolation on the same times, so equal to the last bit. Before this fix
    # the unit played zeros in the second case.
    motion = GroundMotion(read_record(elcentro), 0.5, 1.0)
    expected = np.array([motion.acceleration(k * 0.01 + 0.01) for k in range(2000)])
    np.testing.assert_array_equal(before, expected)
    np.testing.assert_array_equal(during, expected)
    assert np.max(np.abs(expected)) > 1.0  # the record is not silent over these 20 s
