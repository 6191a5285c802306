"""FMI 2.0 Model Exchange FMUs as units of the master (orchestration.master.fmi2_me_unit.MeUnit).

The FMUs are small C models of our own (tests/support/me/*.c, built by tests/support/me_build.py): a driven
damped oscillator (linear ODE), a bouncing ball (state events), a pulse-driven lag (time
events), and both-interface builds of the oscillator and the pulse. Each single unit is
compared with ``fmpy.simulate_fmu`` on the same FMU with the same solver settings (fmpy's
CVode, ``output_interval`` = the communication step) and with the analytic solution.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import ScenarioError, SimulationError, UnitCallError
from orchestration.master.execution import time_grid
from orchestration.master.fmi2_cosim_unit import FmuUnit
from orchestration.master.fmi2_me_unit import MeUnit
from orchestration.master.fmu_description import FmuFormatError, read_description
from orchestration.master.session import run_plan

from ..support.me_build import build_all

RTOL = 1e-10  # CVode relative tolerance for the analytic comparisons


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, Path]:
    return build_all(tmp_path_factory.mktemp("me"))


def drive(unit: MeUnit | FmuUnit, names: list[str], stop: float, h: float, inputs=None) -> np.ndarray:
    """Step ``unit`` on the master's grid (execution.time_grid) from 0 to ``stop``: rows (t, *outputs).

    ``inputs(t)`` gives the value of the input ``u`` held over the step starting at t.
    """
    unit.setup(0.0, stop)
    refs = unit.prepare([unit.description.variables[n].vr for n in names])
    u = unit.prepare([unit.description.variables["u"].vr]) if inputs else None
    if inputs:
        unit.set_real(u, np.array([inputs(0.0)]))
    unit.exit_initialization()
    n, t_of = time_grid(0.0, stop, h)
    rows = [[0.0, *unit.get_real(refs)]]
    try:
        for k in range(n):
            t, t_next = t_of(k), t_of(k + 1)
            if inputs:
                unit.set_real(u, np.array([inputs(t)]))
            unit.step(t, t_next - t)
            rows.append([t_next, *unit.get_real(refs)])
    finally:
        unit.terminate()
    return np.array(rows)


def fmpy_rows(path: Path, names: list[str], stop: float, h: float, rtol: float, **kwargs) -> np.ndarray:
    """fmpy's own Model Exchange simulation of the FMU, sampled at the communication points."""
    result = simulate_fmu(str(path), fmi_type="ModelExchange", stop_time=stop, output_interval=h,
                          relative_tolerance=rtol, record_events=False, output=names, **kwargs)
    return np.column_stack([result[c] for c in ("time", *names)])


def oscillator_segment(t: np.ndarray, x0: float, v0: float, u: float, m: float = 1.0, c: float = 0.4,
                       k: float = 4.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact x(t), v(t) of m x'' + c x' + k x = u (constant, underdamped) from x0, v0 at t = 0 [m, m/s]."""
    w = math.sqrt(k / m)
    zeta = c / (2.0 * m * w)
    wd = w * math.sqrt(1.0 - zeta**2)
    y0 = x0 - u / k
    decay = np.exp(-zeta * w * t)
    x = u / k + decay * (y0 * np.cos(wd * t) + (v0 + zeta * w * y0) / wd * np.sin(wd * t))
    v = decay * (v0 * np.cos(wd * t) - (zeta * w * v0 + w**2 * y0) / wd * np.sin(wd * t))
    return x, v


def test_the_test_fmus_are_valid(fmus):
    for path in fmus.values():
        assert validate_fmu(str(path)) == []
    assert read_description(fmus["Oscillator"], "o")[0].model_identifier == "Oscillator"


# -- a linear ODE ---------------------------------------------------------------------------------------


def test_free_oscillator_equals_fmpy_and_the_analytic_solution(fmus):
    path = fmus["Oscillator"]
    mine = drive(MeUnit("osc", path, relative_tolerance=RTOL), ["x", "v"], 5.0, 0.01)
    theirs = fmpy_rows(path, ["x", "v"], 5.0, 0.01, RTOL)
    # The same CVode calls on the same FMU: measured identical to the last bit; 1e-12 leaves room for nothing
    # but a different summation order.
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)
    x, v = oscillator_segment(mine[:, 0], 1.0, 0.0, 0.0)
    # rtol 1e-10 with unit nominals (absolute tolerance 1e-10): CVode's global error over 5 s was measured at
    # 4.0e-9 (x) and 7.7e-9 (v); 5e-8 leaves a factor 6 and is still 100 times below what rtol 1e-8 gives.
    np.testing.assert_allclose(mine[:, 1], x, rtol=0, atol=5e-8)
    np.testing.assert_allclose(mine[:, 2], v, rtol=0, atol=5e-8)


def test_input_changes_are_events_as_fmpy_treats_input_jumps(fmus):
    """A held input that jumps at communication points: fmpy with the same piecewise-constant signal."""
    path = fmus["Oscillator"]
    levels = [0.0, 2.0, -1.0, 3.0, 0.5, 0.7, -2.0, 1.0]  # N, each held for 0.25 s

    def force(t: float) -> float:
        return levels[min(int(t / 0.25 + 1e-9), len(levels) - 1)]

    unit = MeUnit("osc", path, relative_tolerance=RTOL)
    mine = drive(unit, ["x", "v"], 2.0, 0.01, force)
    assert unit.events == len(levels) - 1
    rows = [(0.0, levels[0])]
    for j in range(1, len(levels)):
        rows += [(0.25 * j, levels[j - 1]), (0.25 * j, levels[j])]
    rows.append((2.0, levels[-1]))
    signal = np.array(rows, dtype=[("time", float), ("u", float)])
    theirs = fmpy_rows(path, ["x", "v"], 2.0, 0.01, RTOL, input=signal)
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)  # identical calls, as above
    # analytic: segment by segment from the exact state at each switch
    x0, v0 = 1.0, 0.0
    for j, level in enumerate(levels):
        inside = (mine[:, 0] >= 0.25 * j - 1e-9) & (mine[:, 0] <= 0.25 * (j + 1) + 1e-9)
        x, v = oscillator_segment(mine[inside, 0] - 0.25 * j, x0, v0, level)
        np.testing.assert_allclose(mine[inside, 1], x, rtol=0, atol=5e-8)  # as in the free case (measured 9.0e-9)
        np.testing.assert_allclose(mine[inside, 2], v, rtol=0, atol=5e-8)
        x0, v0 = (float(a[0]) for a in oscillator_segment(np.array([0.25]), x0, v0, level))


def test_set_values_makes_the_same_input_event_as_set_real(fmus):
    """The typed path (set_values) of a held input: the same event, the same trajectory as set_real."""
    path = fmus["Oscillator"]
    by_real = drive(MeUnit("osc", path, relative_tolerance=RTOL), ["x", "v"], 1.0, 0.01, lambda t: 2.0 * (t >= 0.5))
    unit = MeUnit("osc", path, relative_tolerance=RTOL)
    unit.setup(0.0, 1.0)
    refs = unit.prepare([unit.description.variables[n].vr for n in ("x", "v")])
    u_vr = unit.description.variables["u"].vr
    unit.exit_initialization()
    n, t_of = time_grid(0.0, 1.0, 0.01)
    rows = [[0.0, *unit.get_real(refs)]]
    for k in range(n):
        unit.set_values("Real", [u_vr], [2.0 * (t_of(k) >= 0.5)])
        unit.step(t_of(k), t_of(k + 1) - t_of(k))
        rows.append([t_of(k + 1), *unit.get_real(refs)])
    unit.terminate()
    assert unit.events == 1
    np.testing.assert_array_equal(np.array(rows), by_real)  # the same FMI and CVode calls


# -- events ---------------------------------------------------------------------------------------------


def bounce_times(h0: float, g: float, e: float, n: int) -> list[float]:
    """Analytic impact times of the ball [s]."""
    t = [math.sqrt(2.0 * h0 / g)]
    speed = g * t[0]
    for k in range(1, n):
        t.append(t[-1] + 2.0 * e**k * speed / g)
    return t


def test_bouncing_ball_state_events_at_the_analytic_times(fmus):
    path = fmus["BouncingBall"]
    unit = MeUnit("ball", path, relative_tolerance=RTOL)
    stop = 2.2  # five bounces (the sixth is at 2.20 s; Zeno time 2.56 s)
    unit.setup(0.0, stop)
    refs = unit.prepare([unit.description.variables[n].vr for n in ("h", "v", "t_bounce")])
    bounces_vr = unit.description.variables["bounces"].vr
    unit.exit_initialization()
    n, t_of = time_grid(0.0, stop, 0.01)
    seen: list[float] = []
    rows = [[0.0, *unit.get_real(refs)[:2]]]
    for k in range(n):
        unit.step(t_of(k), t_of(k + 1) - t_of(k))
        h, v, t_bounce = unit.get_real(refs)
        rows.append([t_of(k + 1), h, v])
        (count,) = unit.get_values("Integer", [bounces_vr])
        if count > len(seen):
            assert count == len(seen) + 1 and t_of(k) < t_bounce <= t_of(k + 1)  # the event inside the step
            seen.append(float(t_bounce))
        assert h >= -1e-9  # never below the floor at a communication point
    unit.terminate()
    expected = [t for t in bounce_times(1.0, 9.81, 0.7, 20) if t < stop]
    assert len(seen) == len(expected) == 5
    # CVode locates each root to its root tolerance; the trajectory error (rtol 1e-10) shifts it by far more:
    # measured 6.1e-10 s at most, hence 1e-8 s.
    np.testing.assert_allclose(seen, expected, rtol=0, atol=1e-8)
    theirs = fmpy_rows(path, ["h", "v"], stop, 0.01, RTOL)
    np.testing.assert_allclose(np.array(rows), theirs, rtol=0, atol=1e-12)  # the same calls as fmpy's


def test_terminate_simulation_from_the_fmu_is_a_simulation_error(fmus):
    unit = MeUnit("ball", fmus["BouncingBall"], {"max_bounces": 2}, relative_tolerance=RTOL)
    with pytest.raises(SimulationError) as info:
        drive(unit, ["h"], 2.0, 0.01)
    assert info.value.unit == "ball" and "asked to terminate" in str(info.value)
    assert info.value.time == pytest.approx(bounce_times(1.0, 9.81, 0.7, 2)[1], abs=1e-8)  # as above
    assert unit.freed


def pulse_response(t: np.ndarray, tau: float = 0.2, amplitude: float = 1.0, t_on: float = 0.1234,
                   width: float = 0.3333, period: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact lag output y(t) and level(t) of the pulse model (switch times summed as the C model does)."""
    switches, s, on = [], t_on, True
    while s <= t[-1] + period:
        switches.append(s)
        s += width if on else period - width
        on = not on
    y = np.zeros_like(t)
    level = np.zeros_like(t)
    y_s, t_s, lev = 0.0, 0.0, 0.0
    for s in [*switches, math.inf]:
        inside = (t >= t_s) & (t < s)
        y[inside] = lev + (y_s - lev) * np.exp(-(t[inside] - t_s) / tau)
        level[inside] = lev
        if s == math.inf:
            break
        y_s, t_s = lev + (y_s - lev) * math.exp(-(s - t_s) / tau), s
        lev = amplitude - lev
    return y, level


def test_pulse_time_events_between_communication_points(fmus):
    path = fmus["Pulse"]
    unit = MeUnit("pulse", path, relative_tolerance=RTOL)
    mine = drive(unit, ["y", "level"], 3.0, 0.01)
    assert unit.events == 6  # on at 0.1234, 1.1234, 2.1234 s; off 0.3333 s later
    y, level = pulse_response(mine[:, 0])
    np.testing.assert_array_equal(mine[:, 2], level)
    # the solver stops exactly at each switch; rtol 1e-10 on a unit-scale lag: measured error 2.5e-9
    np.testing.assert_allclose(mine[:, 1], y, rtol=0, atol=2e-8)
    theirs = fmpy_rows(path, ["y", "level"], 3.0, 0.01, RTOL)
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)


def test_an_fmi_error_inside_the_solver_names_unit_function_and_time(fmus):
    unit = MeUnit("osc", fmus["Oscillator"], {"fail_at": 0.5}, relative_tolerance=RTOL)
    with pytest.raises(UnitCallError) as info:
        drive(unit, ["x"], 2.0, 0.01)
    err = info.value
    assert err.unit == "osc" and err.function == "fmi2GetDerivatives" and err.status == "error"
    assert 0.5 < err.time < 0.52  # CVode's first evaluation past 0.5 s, within the step that crosses it
    assert any("injected failure at t = " in d for d in err.details)
    assert unit.freed


# -- both interfaces, scenarios, the master ---------------------------------------------------------------


def write_scenario(tmp_path: Path, units: str, connections: str = "", simulation: str = "") -> Path:
    path = tmp_path / "me.yaml"
    path.write_text(f"name: me_test\nunits:\n{units}\nconnections: [{connections}]\n"
                    f"simulation: {{step: 0.01, stop_time: 2.0{simulation}}}\nresults: {{dir: {tmp_path / 'runs'}}}\n")
    return path


@pytest.mark.parametrize(("interface", "kind", "cosim"), [
    ("", FmuUnit, 1.0), ("    interface: co-simulation\n", FmuUnit, 1.0),
    ("    interface: model-exchange\n", MeUnit, 0.0)], ids=["default", "co-simulation", "model-exchange"])
def test_a_both_interface_fmu_runs_as_co_simulation_unless_asked(fmus, tmp_path, interface, kind, cosim):
    path = write_scenario(tmp_path, f"  osc:\n    fmu: {fmus['OscillatorBoth']}\n{interface}")
    plan = plan_scenario(path)
    (unit,) = plan.create_units()
    assert type(unit) is kind
    outcome = run_plan(plan, tmp_path / "run", plots=False)
    assert outcome.result.status == "complete", outcome.result.error
    rec = outcome.recorder
    assert np.all(rec.column("osc.cosim") == cosim)  # the FMU says how it was instantiated
    x, _ = oscillator_segment(rec.times, 1.0, 0.0, 0.0)
    # CS: RK4 with 1 ms sub-steps (measured error 3.4e-13); ME: CVode at the default rtol 1e-6 (measured 4.9e-6)
    np.testing.assert_allclose(rec.column("osc.x"), x, rtol=0, atol=5e-5)


def test_a_model_exchange_unit_with_a_co_simulation_unit_in_the_master(fmus, tmp_path):
    """Pulse (co-simulation) drives the oscillator (model exchange): fmpy given the inputs the master set."""
    units = (f"  source:\n    fmu: {fmus['PulseBoth']}\n"
             f"  osc:\n    fmu: {fmus['Oscillator']}\n    relative_tolerance: 1.0e-8\n    interface: model-exchange\n")
    plan = plan_scenario(write_scenario(tmp_path, units, "source.y -> osc.u", ", inputs: hold"))
    held: list[tuple[float, float]] = []
    create = plan.create_units

    def spy(on_log=None):
        made = create(on_log)
        osc = next(u for u in made if u.name == "osc")
        set_real, step = osc.set_real, osc.step
        last: list[float] = []

        def spy_set(handle, values):
            last[:] = list(values)
            set_real(handle, values)

        def spy_step(t, h):
            held.append((t, last[0]))
            step(t, h)

        osc.set_real, osc.step = spy_set, spy_step
        return made

    plan.create_units = spy
    outcome = run_plan(plan, tmp_path / "run", plots=False)
    assert outcome.result.status == "complete", outcome.result.error
    assert outcome.summary["executor"] == "python"  # the native executor steps co-simulation units only
    assert [type(u) for u in outcome.units] == [FmuUnit, MeUnit] and all(u.freed for u in outcome.units)
    rec = outcome.recorder
    # inputs: hold under Gauss-Seidel: the oscillator holds the pulse's output after the pulse stepped
    np.testing.assert_array_equal([u for _, u in held], rec.column("source.y")[1:])
    rows, last = [(0.0, held[0][1])], held[0][1]
    for t, value in held[1:]:
        if value != last:  # fmpy makes an input event at every repeated time point
            rows += [(t, last), (t, value)]
        last = value
    rows.append((2.0, last))
    signal = np.array(rows, dtype=[("time", float), ("u", float)])
    theirs = fmpy_rows(fmus["Oscillator"], ["x", "v"], 2.0, 0.01, 1e-8, input=signal)
    mine = np.column_stack([rec.times, rec.column("osc.x"), rec.column("osc.v")])
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)  # the same CVode calls, as for single units
    assert np.ptp(rec.column("osc.x")) > 0.5  # it did move


def test_executor_native_refuses_a_model_exchange_unit(fmus, tmp_path):
    """Known before the first step, so a scenario error (exit 2, nothing written), not a failed run."""
    path = write_scenario(tmp_path, f"  osc:\n    fmu: {fmus['Oscillator']}\n", simulation=", executor: native")
    with pytest.raises(ScenarioError, match=r"native: unit\(s\) osc are not FMI 2\.0 co-simulation FMUs"):
        plan_scenario(path)
    assert not (tmp_path / "run").exists()


# -- what is refused ------------------------------------------------------------------------------------------


def test_model_exchange_of_a_co_simulation_only_fmu_is_refused(fmus, tmp_path):
    cs_only = fmus["OscillatorCS"]
    with pytest.raises(FmuFormatError) as info:
        read_description(cs_only, "c", "model-exchange")
    assert str(info.value) == f"{cs_only}: interface model-exchange requested, but the FMU has co-simulation only"
    with pytest.raises(FmuFormatError, match="co-simulation only"):
        MeUnit("c", cs_only)
    from ..support.fmi3_build import MODEL_IDENTIFIER, model_description, write_fmu

    both3 = model_description("{t}").replace("<CoSimulation", f'<ModelExchange modelIdentifier="{MODEL_IDENTIFIER}"/>'
                                                                 "\n  <CoSimulation")
    fmu3 = write_fmu(tmp_path / "both3.fmu", {"modelDescription.xml": both3})
    assert read_description(fmu3, "c")[0].model_identifier == MODEL_IDENTIFIER  # runs as co-simulation
    with pytest.raises(FmuFormatError) as info:
        read_description(fmu3, "c", "model-exchange")
    assert str(info.value) == (f"{fmu3}: FMI 3.0 model exchange is not supported (FMI 3.0 FMUs run as "
                               "co-simulation; model exchange: FMI 2.0)")


def test_asking_model_exchange_of_a_co_simulation_only_fmu_is_a_scenario_error(fmus, tmp_path):
    path = write_scenario(tmp_path, f"  osc:\n    fmu: {fmus['OscillatorCS']}\n    interface: model-exchange\n")
    with pytest.raises(ScenarioError) as info:
        plan_scenario(path)
    (problem,) = info.value.problems
    assert problem.key == "units.osc.fmu" and "co-simulation only" in problem.message


@pytest.mark.parametrize(("spec", "text"), [
    ("    interface: me\n", "Input should be 'co-simulation' or 'model-exchange'"),
    ("    relative_tolerance: 1.0e-8\n", "relative_tolerance is the model-exchange solver's"),
    ("    interface: model-exchange\n    relative_tolerance: 2\n", "less than 1"),
], ids=["unknown-interface", "tolerance-without-me", "tolerance-range"])
def test_bad_interface_settings_are_scenario_errors(fmus, tmp_path, spec, text):
    path = write_scenario(tmp_path, f"  osc:\n    fmu: {fmus['Oscillator']}\n{spec}")
    with pytest.raises(ScenarioError) as info:
        plan_scenario(path)
    (problem,) = info.value.problems
    assert problem.key.startswith("units.osc") and text in problem.message and problem.line is not None


def test_the_interface_travels_through_an_ssp_package(fmus, tmp_path, monkeypatch):
    """A both-interface FMU run as model exchange comes back from SSP export and import as model exchange,
    with its tolerance, and runs to the same values (the settings ride in an org.mre-cosim.unit annotation)."""
    from orchestration.interop.ssp_package import export_ssp, load_ssp
    from orchestration.master.resolve import resolve

    units = (f"  osc:\n    fmu: {fmus['OscillatorBoth']}\n    interface: model-exchange\n"
             "    relative_tolerance: 1.0e-8\n")
    monkeypatch.chdir(tmp_path)  # an imported package's results folder must be relative
    plan = plan_scenario(write_scenario(tmp_path, units), ("results.dir=runs",))
    loaded = load_ssp(export_ssp(plan, tmp_path / "me.ssp"))
    spec = loaded.scenario.units["osc"]
    assert (spec.interface, spec.relative_tolerance) == ("model-exchange", 1.0e-8)
    again = resolve(loaded)
    (unit,) = again.create_units()
    assert type(unit) is MeUnit and unit.relative_tolerance == 1.0e-8
    first = run_plan(plan, tmp_path / "a", plots=False).recorder
    second = run_plan(again, tmp_path / "b", plots=False).recorder
    assert np.all(second.column("osc.cosim") == 0.0)  # instantiated as model exchange
    np.testing.assert_array_equal(second.column("osc.x"), first.column("osc.x"))  # same FMU, same solver, same steps
