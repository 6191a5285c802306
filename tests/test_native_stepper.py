"""The native (C) executor runs the same program as the Python one: identical results and errors."""

from __future__ import annotations

import numpy as np
import pytest

from orchestration.master import native_stepper
from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.execution import execute
from orchestration.master.graph import Link
from orchestration.master.session import run_plan
from orchestration.project import plan_scenario

from .conftest import PROJECT
from .fake_units import clock, sampler
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
    assert auto.complete and auto.executor == "python" and "FmuUnit" in auto.executor_note
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
