"""Every FMU the project builds takes parameters and input start values in the Instantiated
state and in Initialization mode alike, as FMI 2.0 allows (ecos sets them after
fmi2EnterInitializationMode).

Each unit is driven with fmpy's low-level API (FMU2Slave) in a child process (pythonfmu
units share one interpreter per process, as in a third-party host), three times: the
values set before ``fmi2EnterInitializationMode``, the same values set after it, and
without them (defaults). The same input signal drives all three runs from the second
step on (the first step runs on the start values). The first two must give the same
outputs to the last bit; the third must differ, so the test sees whether the values
were used at all. For the ground-motion unit, the values are also checked against the record as
the physics core plays it (the unit once played zeros when its parameters came in
Initialization mode).
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from components.physics.ground_motion_core import GroundMotion, read_record

from ..conftest import PROJECT, shipped_record

pytestmark = pytest.mark.slow  # each FMU driven three times in child processes: seconds per unit

_DRIVER = textwrap.dedent("""
    import json, math, shutil, sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    fmu, spec, when = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3]
    md = read_model_description(fmu)
    var = {v.name: v for v in md.modelVariables}
    folder = extract(fmu)
    unit = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName="unit")
    unit.instantiate(loggingOn=True)
    unit.setupExperiment(startTime=0.0)
    def put(values):
        for name, value in values.items():
            v = var[name]
            setter = {"Real": unit.setReal, "Integer": unit.setInteger, "String": unit.setString}[v.type]
            setter([v.valueReference], [value])
    def values():
        put(spec["required"])
        if when != "defaults":
            put(spec["values"])
    if when in ("instantiated", "defaults"):
        values()
    unit.enterInitializationMode()
    if when == "initialization":
        values()
    unit.exitInitializationMode()
    outputs = [var[n].valueReference for n in spec["outputs"]]
    h, rows = spec["h"], [unit.getReal(outputs)]
    for k in range(spec["steps"]):
        t = k * h
        if k:  # the first step runs on the start values
            put({n: a * math.sin(w * t) + c for n, (a, w, c) in spec["signal"].items()})
        unit.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        rows.append(unit.getReal(outputs))
    unit.terminate()
    unit.freeInstance()
    shutil.rmtree(folder, ignore_errors=True)
    print(json.dumps(rows))
""")

_ISOLATOR_SIGNAL = {"x": (0.01, 6.0, 0.0), "v": (0.06, 6.0, 0.0), "i": (1.2, 3.0, 1.5)}
_ISOLATOR_STARTS = {"x": 0.004, "v": 0.02, "i": 1.0}
_CONTROLLER_SIGNAL = {"x": (0.01, 6.0, 0.0), "v": (0.06, 6.0, 0.01), "a": (0.4, 6.0, 0.0)}
_CONTROLLER_STARTS = {"x": 0.003, "v": -0.02, "a": 0.1}
# the model-based controllers: base motion, floor accelerations and isolator force
_ESTIMATOR_SIGNAL = {"x": (0.004, 6.0, 0.0), "v": (0.024, 6.0, 0.0), "F": (80.0, 6.0, 0.0),
                     **{f"a_{j}": (1.0 + 0.2 * j, 6.0, 0.0) for j in range(4)}}
_ESTIMATOR_STARTS = {"x": 0.003, "v": -0.02, "F": 50.0, "a_1": 0.3}

# FMU -> parameters and input start values set (all non-default), parameters every run needs,
# and the input signal {input: (amplitude, angular frequency [rad/s], offset)}.
UNITS: dict[str, dict] = {
    "GroundMotionSource": {
        "values": {"scale": 0.5, "time_scale": 1.5},
        "required": {"record": "ELCENTRO"},
        "signal": {},
    },
    "ShearBuilding": {
        "values": {"m_0": 150.0, "k_0": 2.0e4, "c_0": 80.0, "k_2": 6.0e5, "ag": 0.8, "F": 40.0},
        "required": {},
        "signal": {"ag": (2.0, 8.0, 0.0), "F": (60.0, 5.0, 0.0)},
    },
    "MreIsolator": {
        "values": {"n_isolators": 3, "alpha_1": 12.0, "k0_1": 4000.0, "i_max": 2.0, **_ISOLATOR_STARTS},
        "required": {},
        "signal": _ISOLATOR_SIGNAL,
    },
    "MreIsolatorC": {
        "values": {"n_isolators": 3, "alpha_1": 12.0, "k0_1": 4000.0, "i_max": 2.0, **_ISOLATOR_STARTS},
        "required": {},
        "signal": _ISOLATOR_SIGNAL,
    },
    "BoucWenIsolator": {
        "values": {"n_isolators": 3, "F0": 1.5, "i_max": 2.0, "dx_max": 1e-5, **_ISOLATOR_STARTS},
        "required": {},
        "signal": _ISOLATOR_SIGNAL,
    },
    "SosmCurrentController": {
        "values": {"lambda": 20.0, "rho": 5.0, "i_start": 1.0, "i_max": 2.5, "s_release": 0.05, **_CONTROLLER_STARTS},
        "required": {},
        "signal": _CONTROLLER_SIGNAL,
    },
    "SwitchingCurrentController": {
        "values": {"i_high": 2.0, "i_low": 0.5, **_CONTROLLER_STARTS},
        "required": {},
        "signal": _CONTROLLER_SIGNAL,
    },
    "ConstantCurrent": {"values": {"current": 1.7}, "required": {}, "signal": {}},
    "OpenSeesBuilding": {  # needs openseespy (the extra "opensees"); skipped without it
        "values": {"substeps": 2, "ag": 0.8, "F": 40.0},
        "required": {"script": str(PROJECT / "scenarios" / "structures" / "dyke_linear.py")},
        "signal": {"ag": (2.0, 8.0, 0.0), "F": (60.0, 5.0, 0.0)},
    },
    "ClippedOptimalCurrentController": {
        "values": {"law": "inverse", "i_nom": 1.0, "q_x": 2.0e4, "s_ground": 0.02, **_ESTIMATOR_STARTS},
        "required": {},
        "signal": _ESTIMATOR_SIGNAL,
    },
    "LyapunovCurrentController": {
        "values": {"i_max": 2.5, "q_drift": 1.0e5, "r_acc": 2e-5, **_ESTIMATOR_STARTS},
        "required": {},
        "signal": _ESTIMATOR_SIGNAL,
    },
    "FrequencyCurrentController": {
        "values": {"window": 50, "update_every": 5, "i_start": 1.0, "f_hi": 8.0, "ag": 0.3},
        "required": {},
        "signal": {"ag": (2.0, 9.0, 0.0)},
    },
    "SensorChannels": {  # robustness variants: sensor noise and delay
        "values": {"delay": 2, "seed": 5, "rms_disp_1": 1e-4, "rms_acc_3": 0.05, "u_disp_1": 0.001, "u_acc_3": 0.2},
        "required": {},
        "signal": {"u_disp_1": (0.002, 7.0, 0.0), "u_acc_3": (1.0, 11.0, 0.0), "u_force_2": (100.0, 3.0, 0.0)},
    },
    "CurrentLag": {  # robustness variants: coil-current lag
        "values": {"tau": 0.02, "i_cmd": 1.5},
        "required": {},
        "signal": {"i_cmd": (1.0, 6.0, 1.5)},
    },
}


def test_every_built_fmu_is_covered(fmu_dir):
    assert {p.stem for p in fmu_dir.glob("*.fmu")} == set(UNITS)


def _drive(fmu, spec: dict, when: str) -> np.ndarray:
    done = subprocess.run([sys.executable, "-c", _DRIVER, str(fmu), json.dumps(spec), when], capture_output=True,
                          text=True, timeout=120, cwd=PROJECT)
    assert done.returncode == 0, (when, done.stdout[-2000:], done.stderr[-2000:])
    return np.asarray(json.loads(done.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize("name", sorted(UNITS))
def test_values_set_in_initialization_mode_are_used(fmu_dir, name):
    from fmpy import read_model_description

    if name == "OpenSeesBuilding":
        from components.physics.opensees_building_core import OpenSeesUnavailable, import_opensees

        try:
            import_opensees()
        except OpenSeesUnavailable as exc:
            pytest.skip(f"openseespy cannot be imported here: {exc}")
    fmu = fmu_dir / f"{name}.fmu"
    md = read_model_description(str(fmu))
    record = str(shipped_record("elcentro_1940_ns.csv"))
    spec = {key: {k: (record if v == "ELCENTRO" else v) for k, v in value.items()} if isinstance(value, dict) else value
            for key, value in UNITS[name].items()}
    spec.update(outputs=[v.name for v in md.modelVariables if v.causality == "output"], h=0.01, steps=200)
    assert set(spec["values"]) <= {v.name for v in md.modelVariables}
    before = _drive(fmu, spec, "instantiated")
    during = _drive(fmu, spec, "initialization")
    defaults = _drive(fmu, spec, "defaults")
    assert before.shape == (201, len(spec["outputs"]))
    assert np.all(np.isfinite(before))
    # the same calls with the same values in another order of modes: the same numbers, to the last bit
    np.testing.assert_array_equal(during, before)
    # and the values matter: without them the unit computes something else
    assert np.max(np.abs(defaults - before)) > 1e-6 * max(1.0, np.max(np.abs(before)))


def test_the_ground_motion_unit_plays_the_record_whichever_state_takes_its_parameters(fmu_dir, elcentro):
    """Not only equal to each other: with record and scale set before or after fmi2EnterInitializationMode
    (as our master and as ecos do), the unit's ag is the record as the physics core plays it at the step ends
    t = k h + h: the same interpolation on the same times, so equal to the last bit."""
    spec = {"values": {"scale": 0.5}, "required": {"record": str(elcentro)}, "signal": {},
            "outputs": ["ag"], "h": 0.01, "steps": 2000}
    motion = GroundMotion(read_record(elcentro), 0.5, 1.0)
    expected = np.array([motion.acceleration(k * 0.01 + 0.01) for k in range(2000)])
    assert np.max(np.abs(expected)) > 1.0  # the record is not silent over these 20 s
    for when in ("instantiated", "initialization"):
        played = _drive(fmu_dir / "GroundMotionSource.fmu", spec, when)[1:, 0]  # row 0: before the first step
        np.testing.assert_array_equal(played, expected)
