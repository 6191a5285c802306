"""The native (C) executor runs the same program as the Python one: identical results and errors."""

from __future__ import annotations

import numpy as np
import pytest

from orchestration.engine_hooks import plan_scenario
from orchestration.master import native_stepper
from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.execution import execute
from orchestration.master.graph import Link
from orchestration.master.session import run_plan

from ..conftest import PROJECT
from ..support.fake_units import clock, sampler
from .test_reliability import failing_fmu, scenario_with_saboteur  # noqa: F401  (fixture)

KOBE = PROJECT / "scenarios" / "kobe.yaml"


def _run(tmp_path, scenario, executor, *overrides):
    plan = plan_scenario(scenario, (f"simulation.executor={executor}", *overrides))
    return run_plan(plan, out=tmp_path / executor, plots=False)


@pytest.mark.parametrize("coupling", [
    ("simulation.algorithm=gauss-seidel", "simulation.inputs=step-mean"),
    ("simulation.algorithm=gauss-seidel", "simulation.inputs=hold"),
    ("simulation.algorithm=jacobi", "simulation.inputs=step-mean"),
    ("simulation.algorithm=jacobi", "simulation.inputs=hold"),
])
@pytest.mark.slow
def test_native_and_python_executors_agree_bit_for_bit(tmp_path, coupling):
    runs = {ex: _run(tmp_path, KOBE, ex, "simulation.stop_time=4", *coupling) for ex in ("python", "native")}
    assert runs["python"].result.executor == "python" and runs["native"].result.executor == "native"
    py, nat = runs["python"].recorder, runs["native"].recorder
    assert py.count == nat.count == 4001
    assert np.array_equal(py.times, nat.times) and nat.times[-1] == 4.0
    assert np.array_equal(py.data[: py.count], nat.data[: nat.count])  # exactly, not approximately


@pytest.mark.parametrize("failure", ["discard", "nan", "raise"])
def test_a_unit_failure_reads_the_same_from_both_executors(tmp_path, failing_fmu, failure):  # noqa: F811
    scenario = scenario_with_saboteur(tmp_path, failing_fmu, failure)
    runs = {ex: _run(tmp_path, scenario, ex) for ex in ("python", "native")}
    py, nat = (runs[ex].result for ex in ("python", "native"))
    assert nat.executor == "native" and nat.status == py.status == "failed"
    assert str(nat.error) == str(py.error)
    assert (nat.error.unit, nat.error.variable, nat.error.time) == (py.error.unit, py.error.variable, py.error.time)
    assert (nat.steps_done, nat.end_time) == (py.steps_done, py.end_time)
    r_py, r_nat = runs["python"].recorder, runs["native"].recorder
    assert r_py.count == r_nat.count
    assert np.array_equal(r_py.data[: r_py.count], r_nat.data[: r_nat.count], equal_nan=True)


@pytest.mark.slow
def test_a_limit_stops_both_executors_at_the_same_step(tmp_path):
    limit = ("simulation.stop_time=5", "limits.max_abs={building.x_0: 0.002}")
    runs = {ex: _run(tmp_path, PROJECT / "scenarios" / "elcentro.yaml", ex, *limit) for ex in ("python", "native")}
    py, nat = (runs[ex].result for ex in ("python", "native"))
    assert nat.executor == "native" and "exceeds the limit 0.002" in str(nat.error)
    assert str(nat.error) == str(py.error) and nat.steps_done == py.steps_done
    assert runs["native"].recorder.count == runs["python"].recorder.count


def test_units_it_cannot_drive_fall_back_to_python_or_fail_when_native_is_required():
    def algorithm():
        return CouplingAlgorithm([clock(), sampler()], [Link(("clock", "y"), ("sampler", "u"))])

    auto = execute(algorithm(), 0.0, 1.0, 0.1, executor="auto")
    assert auto.complete and auto.executor == "python" and "not an FMI 2.0 co-simulation FMU" in auto.executor_note
    required = execute(algorithm(), 0.0, 1.0, 0.1, executor="native")
    assert required.status == "failed" and "native executor cannot run this system" in str(required.error)


def test_without_a_c_compiler_the_run_still_completes_in_python(tmp_path, monkeypatch):
    monkeypatch.setattr(native_stepper, "_LIBRARY", None)
    monkeypatch.setenv("MRE_COSIM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    outcome = _run(tmp_path, KOBE, "auto", "simulation.stop_time=0.2")
    assert outcome.result.complete and outcome.result.executor == "python"
    assert "no C compiler" in outcome.result.executor_note
    assert not list((tmp_path / "cache").glob("*.so"))  # no half-written library left behind


def test_the_step_program_reads_no_output_it_overwrites_unread():
    """Kobe, Gauss-Seidel: 14 FMI calls per step. The isolator's force is read once (by the
    propagation, with the end-of-step inputs), not also right after its step; the building's
    accelerations likewise. Every value a get writes is read before the next write."""
    plan = plan_scenario(KOBE, ())
    algorithm = plan.create_algorithm(plan.create_units())
    program = algorithm.program()
    assert len(program) == 14
    gets = [(op.unit.name, len(op.slots)) for op in program if op.kind == "get"]
    assert gets.count(("isolator", 1)) == 1
    written: dict[int, int] = {}
    for k, op in enumerate(program):
        if op.kind == "get":
            for s in op.slots.tolist():
                assert s not in written, f"op {k} overwrites slot {s} that op {written[s]} wrote and nothing read"
                written[s] = k
        elif op.kind == "set":
            for s, rule in zip(op.slots.tolist(), op.rules.tolist(), strict=True):
                if rule in (1, 2):  # fresh, mean: they read the latest values
                    written.pop(s, None)


def _python_g12(values) -> list[str]:
    return ["%.12g" % x for x in np.asarray(values, dtype=float).ravel().tolist()]  # noqa: UP031 (the CSV's own format)


def test_the_compiled_csv_formatter_writes_numbers_exactly_as_python():
    formatter = native_stepper.csv_formatter()
    assert formatter is not None
    rng = np.random.default_rng(17)
    ties = rng.integers(10**11, 10**12, size=20000).astype(float) + 0.5  # exact halves at the 12th digit
    powers = 10.0 ** np.arange(-40, 41)
    samples = [
        rng.normal(size=200000) * 10.0 ** rng.integers(-45, 45, size=200000),
        rng.integers(0, 2**63, size=200000, dtype=np.int64).view(np.float64),  # every exponent, NaN and inf
        ties, np.nextafter(ties, 0), np.nextafter(ties, np.inf), ties * 10.0 ** rng.integers(-30, 30, size=20000),
        powers, np.nextafter(powers, 0), np.nextafter(powers, np.inf), powers * 0.9999999999995,
        np.array([0.0, -0.0, np.inf, -np.inf, np.nan, -np.nan, 5e-324, 2.2250738585072014e-308,
                  1.7976931348623157e308, 1e-5, 1e-4, 123456789012.0, 999999999999.5, 0.1, 1 / 3]),
    ]
    for values in samples:
        block = np.ascontiguousarray(values.reshape(-1, 1))
        assert formatter(block).decode().splitlines() == _python_g12(values)
    block = rng.normal(size=(300, 7))
    assert formatter(block).decode() == "".join(",".join(_python_g12(r)) + "\n" for r in block)


@pytest.mark.parametrize("compiled", [True, False])
def test_the_timeseries_writer_writes_what_row_by_row_formatting_writes(tmp_path, monkeypatch, compiled):
    from orchestration.master.recorder import write_timeseries

    if not compiled:
        monkeypatch.setattr(native_stepper, "csv_formatter", lambda: None)
    rng = np.random.default_rng(18)
    time = np.arange(12001) * 1e-3
    data = rng.normal(size=(12001, 5)) * 10.0 ** rng.integers(-20, 6, size=(12001, 5))
    data[7, 2], data[9, 0], data[11, 4] = np.nan, -np.inf, -0.0
    names = ["a.x", "b.y", "c.z", "d.w", "e.v"]
    write_timeseries(tmp_path / "timeseries.csv", time, names, data)
    rows = np.column_stack([time, data])
    expected = ",".join(["time", *names]) + "\n" + "".join(",".join(_python_g12(r)) + "\n" for r in rows)
    assert (tmp_path / "timeseries.csv").read_bytes() == expected.encode()
    assert not [p.name for p in tmp_path.iterdir() if p.name != "timeseries.csv"]  # no temporary file left


def test_every_unit_type_the_engine_creates_has_the_whole_unit_protocol():
    """What native_stepper calls (time, native_functions, raise_status) is part of the Unit protocol."""
    from orchestration.master.fmi2_cosim_unit import FmuUnit
    from orchestration.master.fmi2_me_unit import MeUnit
    from orchestration.master.fmi3_cosim_unit import Fmu3Unit
    from orchestration.master.resolve import UnloadableUnit
    from orchestration.master.unit import Unit

    members = [name for name in vars(Unit) if not name.startswith("_")]
    assert {"time", "native_functions", "raise_status"} <= set(members)
    for cls in (FmuUnit, MeUnit, Fmu3Unit, UnloadableUnit):
        assert [m for m in members if not hasattr(cls, m) and m not in ("name", "description")] == [], cls
    assert Fmu3Unit.native_functions is not FmuUnit.native_functions  # FMI 3.0: the kernel cannot drive it
    fake = clock()
    assert all(hasattr(fake, m) for m in members) and fake.native_functions() is None
