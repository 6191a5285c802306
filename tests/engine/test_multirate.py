"""Multi-rate stepping (``units.NAME.step``): a unit with its own step of m base steps.

Against independent expectations: the hand-written oracle (tests/support/monolithic_oracle.py) for the isolated
building with the controller at its own step, a call log of fake units for what a coarse unit is given and
when its outputs are seen, and the native executor against the Python one, bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from orchestration.engine_hooks import plan_scenario
from orchestration.inprocess import simulate_coupled
from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.errors import ScenarioError
from orchestration.master.execution import execute
from orchestration.master.graph import Link
from orchestration.master.session import run_plan

from ..conftest import PROJECT
from ..support.fake_units import FakeUnit, clock
from ..support.monolithic_oracle import simulate_coupled as oracle
from .test_inprocess import SCHEMES, assert_identical, setup_for


@pytest.mark.parametrize(("scheme", "inputs"), SCHEMES)
@pytest.mark.parametrize("current", [None, 3.0], ids=["sosm", "passive-3A"])
def test_the_controller_at_its_own_step_equals_the_oracle_bit_for_bit(elcentro, scheme, inputs, current):
    setup = setup_for(elcentro, current)
    h, m, n = 2.5e-4, 4, 8000
    got = simulate_coupled(setup, h, n, scheme, inputs, controller_every=m)
    assert_identical(got, oracle(setup, h, n, scheme, inputs, controller_every=m))
    assert np.max(np.abs(got.x[:, 0])) > 1e-3
    if current is None:  # the recorded current (its latest value) changes only when the controller stepped
        changes = np.flatnonzero(np.diff(got.i)) + 1
        assert len(changes) > 10 and np.all(changes % m == 1)


def test_the_scalar_executor_equals_the_engine_step_with_a_coarse_controller(elcentro):
    setup = setup_for(elcentro, None)
    for scheme, inputs in SCHEMES:
        scalar = simulate_coupled(setup, 5e-4, 2000, scheme, inputs, executor="scalar", controller_every=2)
        engine = simulate_coupled(setup, 5e-4, 2000, scheme, inputs, executor="python", controller_every=2)
        assert_identical(scalar, engine)


def _probe(calls: list) -> FakeUnit:
    """Records the input u it was given at each of its steps (a state z = the last u)."""
    return FakeUnit("probe", ["u"], ["z"], lambda s, i: {"z": s["z"]},
                    lambda s, i, t, h: {"z": i["u"]}, state={"z": -1.0}, calls=calls)


def _run(h: float, m: int, scheme: str = "gauss-seidel", delayed: bool = False, stop: float = 0.08):
    """clock (base step h) -> coarse (own step m h: samples u, outputs z = the u it sampled) -> probe (base step)."""
    calls: list = []
    coarse = FakeUnit("coarse", ["u"], ["z"], lambda s, i: {"z": s["z"]},
                      lambda s, i, t, dt: {"z": i["u"]}, state={"z": -1.0}, calls=calls)
    links = [Link(("clock", "y"), ("coarse", "u"), delayed), Link(("coarse", "z"), ("probe", "u"))]
    algo = CouplingAlgorithm([clock(calls=calls), coarse, _probe(calls)], links, [("coarse", "z")], scheme,
                             periods={"coarse": m})
    seen = []

    class Watch:
        def record(self, k: int, t: float) -> None:
            seen.append((t, algo.value(("coarse", "z"))))

    assert execute(algo, 0.0, stop, h, [Watch()], executor="python").complete
    return calls, seen


def test_a_coarse_unit_steps_only_on_its_grid_with_its_own_step_and_samples_its_inputs():
    h, m = 0.01, 4
    calls, _ = _run(h, m, delayed=True)
    steps = [(t, dt) for kind, name, *rest in calls if kind == "step" and name == "coarse" for t, dt in [rest]]
    assert [round(t / h) for t, _ in steps] == [0, 4]  # 8 base steps: two of its own
    assert all(dt == pytest.approx(m * h, rel=1e-12) for _, dt in steps)
    first_step = min(k for k, c in enumerate(calls) if c[0] == "step")
    running = calls[first_step:]  # the steps (the clock steps first)
    coarse_calls = [c[0] for c in running if c[1] == "coarse" and c[0] in ("set", "get", "step")]
    assert coarse_calls == ["set", "step", "get"] * 2  # per own step: set, step, get; nothing in between


@pytest.mark.parametrize("scheme", ["gauss-seidel", "jacobi"])
def test_the_delay_of_a_coarse_unit_does_not_depend_on_the_base_step(scheme):
    """A fast probe sees a coarse unit's output at the same times whether the base step is H/4 or H/8."""
    H = 0.04
    fine, coarse = (_probe_values(H / m, m, scheme) for m in (8, 4))
    assert len(fine) == 2 * len(coarse) == 32
    for t, value in coarse.items():
        assert fine[t] == value, t
    # Gauss-Seidel (the coarse unit steps before the probe): the value it sampled at T is seen from T on;
    # Jacobi: from T + H, the end of its step
    lag = 0.0 if scheme == "gauss-seidel" else H
    for t, value in fine.items():
        expected = H * np.floor((t - lag) / H + 1e-9) if t >= lag - 1e-12 else -1.0
        assert value == pytest.approx(expected, abs=1e-12), t


def _probe_values(h: float, m: int, scheme: str) -> dict[float, float]:
    """The input the probe was given over each base step, by the step's start time (rounded to 1e-9 s)."""
    calls: list = []
    coarse = FakeUnit("coarse", ["u"], ["z"], lambda s, i: {"z": s["z"]},
                      lambda s, i, t, dt: {"z": i["u"]}, state={"z": -1.0})
    probe = FakeUnit("probe", ["u"], ["z"], lambda s, i: {"z": s["z"]},
                     lambda s, i, t, dt: (calls.append((round(t, 9), i["u"])), {"z": i["u"]})[1], state={"z": -1.0})
    links = [Link(("clock", "y"), ("coarse", "u"), True), Link(("coarse", "z"), ("probe", "u"))]
    algo = CouplingAlgorithm([clock(), coarse, probe], links, scheme=scheme, periods={"coarse": m})
    assert execute(algo, 0.0, 0.16, h, executor="python").complete
    return dict(calls)


def test_a_run_length_that_is_not_a_whole_number_of_own_steps_is_refused_by_the_algorithm():
    algo = CouplingAlgorithm([clock(), _probe([])], [Link(("clock", "y"), ("probe", "u"))], periods={"probe": 3})
    with pytest.raises(ValueError, match="10 base steps are not a whole number of the own steps of probe"):
        execute(algo, 0.0, 0.1, 0.01, executor="python")  # a programming error: scenarios are refused before


KOBE = PROJECT / "scenarios" / "kobe.yaml"
CLIPPED = PROJECT / "scenarios" / "elcentro_clipped_optimal.yaml"


@pytest.mark.parametrize(("scenario", "m"), [(KOBE, 4), (CLIPPED, 4), (CLIPPED, 1)],
                         ids=["sosm", "clipped-optimal", "clipped-optimal-single-rate"])
def test_native_and_python_agree_bit_for_bit_with_a_coarse_controller(tmp_path, scenario, m):
    """Multi-rate, and the restart of the force estimate after the (discrete) clipped-optimal current jumps."""
    overrides = ("simulation.stop_time=0.5", f"simulation.step={0.001 / m}", "units.controller.step=0.001")
    runs = {ex: run_plan(plan_scenario(scenario, (f"simulation.executor={ex}", *overrides)), out=tmp_path / ex,
                         plots=False) for ex in ("python", "native")}
    assert runs["native"].result.executor == "native"
    py, nat = runs["python"].recorder, runs["native"].recorder
    assert py.count == nat.count == 500 * m + 1
    assert np.array_equal(py.data[: py.count], nat.data[: nat.count], equal_nan=True)
    current = py.data[: py.count, py.ports.index(("controller", "i"))]
    changes = np.flatnonzero(np.diff(current))
    assert len(changes) >= 2 and np.all(changes % m == 0)  # new values only when the controller stepped


@pytest.mark.parametrize(("value", "text"), [
    ("0.0015", "not a whole multiple of simulation.step"),
    ("0.0005", "smaller than simulation.step"),
    ("0", "greater than 0"),
    ("-0.002", "greater than 0"),
    ("0.003", "does not divide the simulated span"),
    ("true", "number"),
])
def test_a_bad_unit_step_is_a_scenario_error_naming_key_and_line(value, text):
    with pytest.raises(ScenarioError) as info:
        plan_scenario(KOBE, ("simulation.stop_time=0.01", f"units.controller.step={value}"))
    (problem,) = info.value.problems
    assert problem.key == "units.controller.step" and text in problem.message, str(problem)
    assert problem.file.startswith("--set") or problem.line is not None


def test_a_model_exchange_unit_cannot_have_its_own_step(tmp_path):
    from ..support.me_build import build_all

    (tmp_path / "me").mkdir()
    fmus = build_all(tmp_path / "me")
    path = tmp_path / "me.yaml"
    path.write_text(f"name: me_test\nunits:\n  osc:\n    fmu: {fmus['OscillatorBoth']}\n    interface: model-exchange\n"
                    "    step: 0.02\nsimulation: {step: 0.01, stop_time: 2.0}\n")
    with pytest.raises(ScenarioError) as info:
        plan_scenario(path)
    (problem,) = info.value.problems
    assert problem.key == "units.osc.step" and "model-exchange unit has no communication step" in problem.message
    assert problem.line == 6
    path.write_text(path.read_text().replace("interface: model-exchange", "interface: co-simulation"))
    assert plan_scenario(path).periods == {"osc": 2}


@pytest.mark.slow
def test_ssp_carries_the_unit_step_and_libcosim_steps_it_as_our_master_does(tmp_path):
    """The package's osp:StepSizeHint is libcosim's decimation factor: libcosim and our master in libcosim's
    scheme (Jacobi, every connection delayed) give the plant bit for bit (dyadic steps: the same time points)."""
    from orchestration.engine_hooks import resolve_scenario
    from orchestration.interop.libcosim_export import libcosim_available, libcosim_scheme, run_libcosim
    from orchestration.interop.ssp_package import export_ssp, load_ssp

    if libcosim_available() is not None:
        pytest.skip(libcosim_available())
    overrides = ("simulation.algorithm=jacobi", "simulation.stop_time=10", "simulation.step=0.001953125",
                 "units.controller.step=0.0078125")  # 2^-9 s and 2^-7 s: four base steps
    package = export_ssp(plan_scenario(KOBE, overrides), tmp_path / "kobe.ssp")
    loaded = load_ssp(package)
    assert loaded.scenario.units["controller"].step == 0.0078125
    plan = resolve_scenario(libcosim_scheme(loaded))
    assert plan.periods == {"controller": 4}
    ours = run_plan(plan, out=tmp_path / "ours", plots=False).recorder
    sim = loaded.scenario.simulation
    lc = run_libcosim(package, tmp_path / "lc", plan.recorded, sim.step, sim.stop_time, sim.start_time)
    data = ours.data[: ours.count]
    assert lc.data.shape == data.shape and np.max(np.abs(lc.column("building.x_0"))) > 2e-3
    for k, name in enumerate(lc.names):
        if name.startswith("controller."):  # recorded at its own steps by libcosim: equal there
            assert np.array_equal(lc.data[::4, k], data[::4, k], equal_nan=True), name
        else:
            assert np.array_equal(lc.data[:, k], data[:, k], equal_nan=True), name
