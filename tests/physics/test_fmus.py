"""Per-FMU tests: each FMU built, loaded with fmpy, stepped, equal to its physics core; its errors reach any host.

The isolator's own checks run against both of its implementations in test_c_isolator.py; what each
FMU declares (a valid model description, its units) is checked in test_fmu_descriptions.py.

The last section: unit errors reach a host that did not turn debug logging on.
pythonfmu 0.7 hands a message to the host only when the host instantiated the unit with
``loggingOn`` (and only in the categories it named), and reports a failed ``do_step`` as
fmi2Discard. So ``fmpy simulate`` (no debug logging) ran a missing record to the end with
exit 0 and rows of zeros, and a host without scipy saw only "Failed to instantiate model".
The build's logging shim (components/build/fmi2_log_shim.c) forwards warnings and errors
always and makes our units' failed steps fmi2Error. Checked with fmpy, in child processes.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from components.build.pythonfmu_units import build, discover
from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.mre_isolator_core import TABLE2, isolator_force
from components.physics.shear_building_core import BuildingParams, ShearBuilding
from components.physics.sosm_controller_core import SosmController, SosmGains

from ..conftest import PROJECT
from ..support.fmu_driver import Driven

STATEFUL = {
    "ShearBuilding": {},
    "SosmCurrentController": {},
    "MreIsolator": {},
    "GroundMotionSource": None,  # parameters need the record: filled in by the test
}


@pytest.mark.parametrize("name", sorted(STATEFUL))
def test_fmu_state_round_trip_reproduces_a_run(fmu_dir, elcentro, name):
    """Save the state at step 40, run to 100, restore, run again with the same inputs: identical."""
    params = STATEFUL[name] if STATEFUL[name] is not None else {"record": str(elcentro), "scale": 0.5}
    unit = Driven(fmu_dir / f"{name}.fmu", "u", params)
    inputs = [v.name for v in unit.md.modelVariables if v.causality == "input"]
    rng = np.random.default_rng(14)
    sequence = [{n: float(rng.normal(0, 5e-3)) for n in inputs} for _ in range(100)]
    try:
        def run(first: int) -> list[list[float]]:
            out = []
            for k in range(first, 100):
                if sequence[k]:
                    unit.set(**sequence[k])
                unit.step(k * 1e-3, 1e-3)
                out.append(unit.get(*unit.outputs()))
            return out

        for k in range(40):
            if sequence[k]:
                unit.set(**sequence[k])
            unit.step(k * 1e-3, 1e-3)
        state = unit.fmu.getFMUstate()
        first = run(40)
        unit.fmu.setFMUstate(state)
        second = run(40)
        unit.fmu.freeFMUstate(state)
        assert first == second
        assert first[0] != first[-1]  # the run did move
    finally:
        unit.close()


def _building_outputs(bld: ShearBuilding, ag: float, F: float) -> dict[str, float]:
    out = {}
    arel = bld.relative_acceleration(ag, F)
    shears = bld.storey_shears()
    for j in range(bld.n_levels):
        out[f"x_{j}"], out[f"v_{j}"] = bld.x[j], bld.v[j]
        out[f"a_{j}"], out[f"arel_{j}"] = arel[j] + ag, arel[j]
    for j in range(1, bld.n_levels):
        out[f"drift_{j}"] = bld.x[j] - bld.x[j - 1]
        out[f"shear_{j}"] = shears[j - 1]
    return out


def _check_building(fmu, params: BuildingParams, steps: int = 200) -> None:
    core = ShearBuilding(params)
    rng = np.random.default_rng(11)
    names = fmu.outputs()
    for k in range(steps):
        ag, F = rng.normal(0, 3), rng.normal(0, 300)
        fmu.set(ag=ag, F=F)
        expected = _building_outputs(core, ag, F)
        got = dict(zip(names, fmu.get(*names), strict=True))
        assert got == pytest.approx(expected, rel=1e-13, abs=1e-15)
        fmu.step(k * 1e-3, 1e-3)
        core.step(ag, F, 1e-3)
    got = dict(zip(names, fmu.get(*names), strict=True))
    assert got == pytest.approx(_building_outputs(core, ag, F), rel=1e-13, abs=1e-15)


def test_building_fmu_equals_core(fmu_dir):
    bld = Driven(fmu_dir / "ShearBuilding.fmu", "bld")
    try:
        _check_building(bld, BuildingParams.dyke())
    finally:
        bld.close()


def test_building_fmu_parameters(fmu_dir):
    params = BuildingParams(m=(150.0, 98.3, 90.0, 80.0), k=(1e3, 516e3, 600e3, 700e3), c=(10.0, 125.0, 60.0, 40.0))
    values = {}
    for j in range(4):
        values |= {f"m_{j}": params.m[j], f"k_{j}": params.k[j], f"c_{j}": params.c[j]}
    bld = Driven(fmu_dir / "ShearBuilding.fmu", "bld", values)
    try:
        _check_building(bld, params, steps=50)
    finally:
        bld.close()


def test_storey_count_is_chosen_at_build_time(tmp_path):
    # --storeys N renders a variant of every shell with N_STOREYS (the shear building and the OpenSees building,
    # whose script's FLOOR_NODES must match its storey count); this test builds and steps the shear building's
    variants = {s.class_name: s for s in discover((5,)) if s.storeys == 5}
    assert set(variants) == {"ShearBuilding", "OpenSeesBuilding"}
    assert variants["OpenSeesBuilding"].fmu_name == "OpenSeesBuilding5.fmu"
    source = variants["ShearBuilding"]
    path = build(source, tmp_path)
    assert path.name == "ShearBuilding5.fmu"
    bld = Driven(path, "bld5")
    try:
        assert "x_5" in bld.outputs() and "drift_5" in bld.outputs() and "x_6" not in bld.outputs()
        _check_building(bld, BuildingParams.uniform(5), steps=30)
    finally:
        bld.close()


_BUILD_AFTER_AN_INSTANCE = """
import sys, zipfile
from pathlib import Path
from tests.support.fmu_driver import Driven
unit = Driven(Path(sys.argv[1]), "first", {})  # pythonfmu is not imported yet: the FMU's own copy becomes it
assert "resources" in sys.modules["pythonfmu"].__file__
unit.close()  # frees the instance and deletes its folder, the copy's too
from components.build.pythonfmu_units import build, discover
source = next(s for s in discover() if s.class_name == "ConstantCurrent")
names = zipfile.ZipFile(build(source, Path(sys.argv[2]))).namelist()
print(sorted(n for n in names if n.startswith("binaries/linux64/")))
"""


def test_a_build_after_an_fmu_instance_in_the_same_process_still_ships_binaries(fmu_dir, tmp_path):
    """A pythonfmu FMU instantiated before pythonfmu is imported makes its bundled copy (no builder binaries)
    the process's pythonfmu; a build afterwards must still use the installed package's binaries."""
    project = Path(__file__).resolve().parents[2]
    proc = subprocess.run([sys.executable, "-c", _BUILD_AFTER_AN_INSTANCE, str(fmu_dir / "ConstantCurrent.fmu"),
                           str(tmp_path)], capture_output=True, text=True, timeout=120, cwd=project)
    assert proc.returncode == 0, proc.stderr
    shipped = "['binaries/linux64/ConstantCurrent.pythonfmu.so', 'binaries/linux64/ConstantCurrent.so']"
    assert proc.stdout.strip().splitlines()[-1] == shipped


def test_controller_fmu_equals_core(fmu_dir):
    gains = SosmGains(lam=4.0, rho=30.0, zeta=15.0, theta=0.8, i_max=2.5)
    ctrl = Driven(fmu_dir / "SosmCurrentController.fmu", "ctrl",
                  {"lambda": 4.0, "rho": 30.0, "zeta": 15.0, "theta": 0.8, "i_max": 2.5})
    core = SosmController(gains, TABLE2)
    rng = np.random.default_rng(12)
    try:
        for k in range(400):
            x, v, a = rng.normal(0, 5e-3), rng.normal(0, 0.05), rng.normal(0, 1.0)
            ctrl.set(x=x, v=v, a=a)
            ctrl.step(k * 1e-3, 1e-3)
            core.update(x, v, a, 1e-3)
            assert ctrl.get("i")[0] == core.i
        assert 0 < core.i  # the sequence exercised the law, not only the lower bound
    finally:
        ctrl.close()


def test_controller_passive_mode_holds_the_current(fmu_dir):
    ctrl = Driven(fmu_dir / "SosmCurrentController.fmu", "ctrl", {"mode": "passive", "i_passive": 1.7})
    try:
        for k in range(10):
            ctrl.set(x=0.01 * k, v=0.1, a=1.0)
            ctrl.step(k * 1e-3, 1e-3)
            assert ctrl.get("i")[0] == 1.7
    finally:
        ctrl.close()


def test_ground_fmu_equals_core(fmu_dir, elcentro):
    gm = GroundMotion(read_record(elcentro), scale=0.5)
    src = Driven(fmu_dir / "GroundMotionSource.fmu", "gm", {"record": str(elcentro), "scale": 0.5})
    try:
        h = 0.0037
        assert src.get("ag")[0] == gm.acceleration(0.0)
        for k in range(2000):
            src.step(k * h, h)
            assert src.get("ag")[0] == pytest.approx(gm.acceleration((k + 1) * h), rel=1e-12, abs=1e-12)
        src.step(2000 * h, 60.0)  # past the end of the record
        assert src.get("ag")[0] == 0.0
        assert src.get("duration")[0] == pytest.approx(53.74)
    finally:
        src.close()


def test_constant_current_fmu(fmu_dir):
    cc = Driven(fmu_dir / "ConstantCurrent.fmu", "cc", {"current": 2.5})
    try:
        cc.step(0.0, 1e-3)
        assert cc.get("i") == [2.5]
    finally:
        cc.close()


def test_all_fmus_together_in_one_process(fmu_dir, elcentro):
    """Every FMU instantiated at once (two isolators too), interleaved, each equal to its core."""
    units = {
        "gm": Driven(fmu_dir / "GroundMotionSource.fmu", "gm", {"record": str(elcentro), "scale": 0.5}),
        "bld": Driven(fmu_dir / "ShearBuilding.fmu", "bld"),
        "iso1": Driven(fmu_dir / "MreIsolator.fmu", "iso1", {"n_isolators": 1}),
        "iso2": Driven(fmu_dir / "MreIsolator.fmu", "iso2", {"n_isolators": 1}),
        "ctrl": Driven(fmu_dir / "SosmCurrentController.fmu", "ctrl"),
        "cc": Driven(fmu_dir / "ConstantCurrent.fmu", "cc", {"current": 1.0}),
    }
    gm = GroundMotion(read_record(elcentro), scale=0.5)
    bld, ctrl = ShearBuilding(BuildingParams.dyke()), SosmController()
    try:
        F = 0.0
        h = 1e-3
        for k in range(500):
            t = k * h
            ag = units["gm"].get("ag")[0]
            assert ag == pytest.approx(gm.acceleration(t), rel=1e-12, abs=1e-12)
            units["bld"].set(ag=ag, F=F)
            x, v, arel = units["bld"].get("x_0", "v_0", "arel_0")
            assert (x, v) == (bld.x[0], bld.v[0])
            units["ctrl"].set(x=x, v=v, a=arel)
            i = units["ctrl"].get("i")[0]
            assert i == ctrl.i
            units["iso1"].set(x=x, v=v, i=i)
            units["iso2"].set(x=x, v=v, i=units["cc"].get("i")[0])
            F = units["iso1"].get("F")[0] + units["iso2"].get("F")[0]
            assert F == isolator_force(x, v, i, TABLE2, 0.0, 1) + isolator_force(x, v, 1.0, TABLE2, 0.0, 1)
            units["bld"].set(F=F)
            for unit in units.values():
                unit.step(t, h)
            ctrl.update(x, v, arel, h)
            bld.step(ag, F, h)
    finally:
        for unit in units.values():
            unit.close()


def _every_fmu_run(fmu_dir: Path, names: list[str], together: bool, steps: int = 120, h: float = 0.01):
    """Outputs of each FMU of test_init_mode_all.UNITS driven by its signal, alone one after another or all at once."""
    from .test_init_mode_all import UNITS

    record = str(PROJECT / "scenarios" / "records" / "elcentro_1940_ns.csv")

    def start(name: str) -> Driven:
        spec = UNITS[name]
        params = {**spec["values"], **{k: record if v == "ELCENTRO" else v for k, v in spec["required"].items()}}
        return Driven(fmu_dir / f"{name}.fmu", name, params)

    rows: dict[str, list[list[float]]] = {n: [] for n in names}
    groups = [names] if together else [[n] for n in names]
    for group in groups:
        units = {n: start(n) for n in group}
        try:
            for k in range(steps):
                t = k * h
                for n, unit in units.items():  # interleaved: every unit steps once per communication point
                    signal = UNITS[n]["signal"]
                    if signal:
                        unit.set(**{v: a * math.sin(w * t) + c for v, (a, w, c) in signal.items()})
                    unit.step(t, h)
                    rows[n].append(unit.get(*unit.outputs()))
        finally:
            for unit in units.values():
                unit.close()
    return rows


@pytest.mark.slow
def test_every_fmu_together_in_one_process_steps_as_it_does_alone(fmu_dir):
    """All our FMUs at once in one interpreter (pythonfmu FMUs share it): each gives exactly its outputs alone.

    OpenSeesBuilding is left out: OpenSees keeps one model per process, so it refuses a second instance.
    """
    names = sorted(p.stem for p in fmu_dir.glob("*.fmu") if p.stem != "OpenSeesBuilding")
    assert {"ClippedOptimalCurrentController", "LyapunovCurrentController", "FrequencyCurrentController",
            "BoucWenIsolator", "MreIsolatorC", "SensorChannels", "CurrentLag"} <= set(names)
    alone = _every_fmu_run(fmu_dir, names, together=False)
    together = _every_fmu_run(fmu_dir, names, together=True)
    for name in names:
        assert np.all(np.isfinite(alone[name])), name
        assert together[name] == alone[name], name


@pytest.mark.parametrize("name", ["ShearBuilding", "SosmCurrentController", "MreIsolator"])
def test_same_inputs_give_the_same_outputs(fmu_dir, name):
    """Two instances fed the same inputs agree exactly: no state leaks through the shared interpreter."""
    a, b = Driven(fmu_dir / f"{name}.fmu", "a"), Driven(fmu_dir / f"{name}.fmu", "b")
    inputs = [v.name for v in a.md.modelVariables if v.causality == "input"]
    rng = np.random.default_rng(13)
    try:
        for k in range(100):
            values = {n: float(rng.normal(0, 1e-2)) for n in inputs}
            for unit in (a, b):
                unit.set(**values)
                unit.step(k * 1e-3, 1e-3)
            assert a.get(*a.outputs()) == b.get(*b.outputs())
    finally:
        a.close()
        b.close()


@pytest.mark.parametrize(("name", "variable"), [("MreIsolator", "x"), ("ShearBuilding", "F"),
                                                ("SosmCurrentController", "a")])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_input_gives_an_fmi_error_status(fmu_dir, capfd, name, variable, bad):
    unit = Driven(fmu_dir / f"{name}.fmu", "u")
    try:
        unit.set(**{variable: bad})
        with pytest.raises(FMICallException) as err:
            unit.step(0.5, 1e-3)
        assert err.value.status >= 2  # discard or worse
        logged = capfd.readouterr().out
        assert "not finite at t = 0.5 s" in logged and "[ERROR]" in logged
    finally:
        unit.close()


def _fails_at_first_step(unit: Driven) -> None:
    """A problem found at initialization is logged there and fails the first step with fmi2Error
    (the shell returns False, which the build's logging shim turns from pythonfmu's discard into
    error; pythonfmu would make an exception fmi2Fatal, after which the instance cannot even be freed)."""
    try:
        with pytest.raises(FMICallException) as err:
            unit.step(0.0, 1e-3)
        assert err.value.status == 3
    finally:
        unit.close()


def test_ground_fmu_reports_a_bad_record(fmu_dir, tmp_path, capfd):
    bad = tmp_path / "bad.csv"
    bad.write_text("0,0\n0.02,0.1\n0.01,0.2\n")
    _fails_at_first_step(Driven(fmu_dir / "GroundMotionSource.fmu", "gm", {"record": str(bad)}))
    assert "bad.csv:3: time 0.01 s does not increase" in capfd.readouterr().out


def test_controller_rejects_an_unknown_mode(fmu_dir, capfd):
    _fails_at_first_step(Driven(fmu_dir / "SosmCurrentController.fmu", "c", {"mode": "magic"}))
    assert "mode = 'magic'" in capfd.readouterr().out


def test_building_rejects_a_zero_mass(fmu_dir, capfd):
    _fails_at_first_step(Driven(fmu_dir / "ShearBuilding.fmu", "b", {"m_2": 0.0}))
    assert "masses must be positive" in capfd.readouterr().out


@pytest.mark.parametrize("name", ["ShearBuilding", "SosmCurrentController", "MreIsolator"])
def test_fast_exchange_paths_equal_the_generic_ones(fmu_dir, name):
    """The shells' fast set/get paths (the value references the master exchanges every step) give
    what pythonfmu's per-variable paths give: inputs set together or one by one, in any order;
    outputs read together, in reverse, in subsets or one at a time."""
    a, b = Driven(fmu_dir / f"{name}.fmu", "a"), Driven(fmu_dir / f"{name}.fmu", "b")
    inputs = [v.name for v in a.md.modelVariables if v.causality == "input"]
    outputs = a.outputs()
    rng = np.random.default_rng(15)
    try:
        for k in range(60):
            values = {n: float(rng.normal(0, 1e-2)) for n in inputs}
            a.set(**values)  # declared order: the fast path
            for n in reversed(inputs):  # one at a time, reversed: the generic path
                b.set(**{n: values[n]})
            all_a = a.get(*outputs)
            assert all_a == b.get(*outputs)
            assert a.get(*reversed(outputs)) == all_a[::-1]
            assert [b.get(n)[0] for n in outputs] == all_a
            subset = sorted(rng.choice(len(outputs), size=max(1, len(outputs) // 3), replace=False), reverse=True)
            assert a.get(*(outputs[j] for j in subset)) == [all_a[j] for j in subset]
            for unit in (a, b):
                unit.step(k * 1e-3, 1e-3)
    finally:
        a.close()
        b.close()


def _products_agree(fast: np.ndarray, matrix: np.ndarray, z: np.ndarray) -> None:
    """``fast`` equals ``matrix @ z`` computed along another path, to within floating-point summation error.

    The two are the same products summed by different BLAS calls (ndarray.dot on reused buffers vs @ on a
    stacked matrix); which kernel runs, its summation order and its use of FMA depend on the CPU (OpenBLAS
    picks its kernels per CPU), so only the rounding bound holds everywhere: each element is a sum of m
    products, and any two orders of it differ by at most 2 m eps sum_j |a_ij z_j| (Higham, Accuracy and
    Stability of Numerical Algorithms, 2nd ed., eq. 3.5). A wrong matrix or input misses it by far more."""
    m = matrix.shape[1]
    bound = 2 * m * np.finfo(float).eps * (np.abs(matrix) @ np.abs(z))
    assert np.all(np.abs(fast - matrix @ z) <= bound), np.max(np.abs(fast - matrix @ z) - bound)


def test_scalar_fast_paths_of_the_cores_give_the_same_numbers():
    """force_law is isolator_force with the coefficients bound (bit for bit, overflow included); the
    building's products (ndarray.dot into reused buffers) equal the matrix formulation with @ within the
    rounding bound of two summation orders (two BLAS paths: bits may differ on another CPU)."""
    from components.physics.mre_isolator_core import force_law

    rng = np.random.default_rng(16)
    coeffs = TABLE2
    for F0, n in ((0.0, 2), (0.7, 1), (-1.5, 3)):
        law = force_law(coeffs, F0, n)
        for x, v, i in zip(rng.normal(0, 0.01, 3000), rng.normal(0, 0.1, 3000), rng.uniform(-0.5, 3.5, 3000),
                           strict=True):
            assert law(x, v, i) == isolator_force(x, v, i, coeffs, F0, n)
        assert law(10.0, 0.0, 3.0) == isolator_force(10.0, 0.0, 3.0, coeffs, F0, n) == math.inf  # sinh overflows
        assert law(-10.0, 0.0, 3.0) == -math.inf
    for params in (BuildingParams.dyke(), BuildingParams.uniform(10)):
        bld = ShearBuilding(params)
        n = 2 * bld.n_levels
        rows = bld._output_matrix()
        for _ in range(500):
            ag, F, h = rng.normal(0, 3), rng.normal(0, 300), float(rng.choice([1e-3, 5e-4, 2e-3]))
            z = np.concatenate([bld.q, [ag, F]])
            _products_agree(bld.output_vector(ag, F), rows, z)
            _products_agree(bld.relative_acceleration(ag, F), np.hstack([bld.A[n // 2:], bld.B[n // 2:]]), z)
            fused = np.hstack(bld.discretization(h))
            bld.step(ag, F, h)
            _products_agree(bld.q, fused, z)


# ----------------------------------------------------------------------------- errors reach every host

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
