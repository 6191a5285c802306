"""The master's algorithm with fake units: ordering, transfer timing, time grid, loops, teardown."""

from __future__ import annotations

import pytest

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.errors import SimulationError
from orchestration.master.execution import execute, time_grid
from orchestration.master.graph import AlgebraicLoopError, Link, gauss_seidel_order, propagation_order
from orchestration.master.recorder import Recorder

from ..support.fake_units import FakeUnit, clock, gain, sampler


def run(units, links, scheme, n=4, h=0.5, watched=(), inputs="hold"):
    algo = CouplingAlgorithm(units, links, watched, scheme, inputs=inputs)
    rec = Recorder(algo, list(watched), n)
    result = execute(algo, 0.0, n * h, h, [rec])
    return algo, rec, result


def test_gauss_seidel_passes_fresh_values_jacobi_passes_old_ones():
    link = [Link(("clock", "y"), ("sampler", "u"))]
    watched = [("clock", "y"), ("sampler", "z")]
    # Gauss-Seidel: the sampler steps after the clock and sees y(t + h)
    _, rec, _ = run([sampler(), clock()], link, "gauss-seidel", watched=watched)
    assert rec.column("clock.y").tolist() == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert rec.column("sampler.z").tolist() == [-1.0, 0.5, 1.0, 1.5, 2.0]
    # Jacobi: everyone uses the values at t
    _, rec, _ = run([sampler(), clock()], link, "jacobi", watched=watched)
    assert rec.column("sampler.z").tolist() == [-1.0, 0.0, 0.5, 1.0, 1.5]


def test_step_mean_inputs_use_the_trapezoid_of_fresh_sources():
    """Gauss-Seidel: the sampler steps after the clock, so it holds (y(t) + y(t + h)) / 2."""
    link = [Link(("clock", "y"), ("sampler", "u"))]
    _, rec, _ = run([sampler(), clock()], link, "gauss-seidel", watched=[("sampler", "z")], inputs="step-mean")
    assert rec.column("sampler.z").tolist() == [-1.0, 0.25, 0.75, 1.25, 1.75]


def test_step_mean_inputs_extrapolate_sources_that_have_not_stepped():
    """Jacobi: the mid-step value of the polynomial through the known values, of growing order.

    The clock is y = t^2 (h = 1): y = 0, 1, 4, 9 at t = 0..3. Mid-step estimates: step 0 constant
    y(0) = 0; step 1 linear 1.5*1 - 0.5*0 = 1.5; step 2 quadratic (15*4 - 10*1 + 3*0)/8 = 6.25 = 2.5^2
    (exact for a quadratic), step 3 (15*9 - 10*4 + 3*1)/8 = 12.25 = 3.5^2."""
    square = FakeUnit("sq", [], ["y"], lambda s, i: {"y": s["t"] ** 2}, lambda s, i, t, h: {"t": t + h},
                      state={"t": 0.0})
    _, rec, _ = run([sampler(), square], [Link(("sq", "y"), ("sampler", "u"))], "jacobi", n=4, h=1.0,
                    watched=[("sampler", "z")], inputs="step-mean")
    assert rec.column("sampler.z").tolist() == [-1.0, 0.0, 1.5, 6.25, 12.25]


def test_delayed_connections_pass_the_value_at_the_start_of_the_step():
    link = [Link(("clock", "y"), ("sampler", "u"), delayed=True)]
    for inputs in ("hold", "step-mean"):
        _, rec, _ = run([sampler(), clock()], link, "gauss-seidel", watched=[("sampler", "z")], inputs=inputs)
        assert rec.column("sampler.z").tolist() == [-1.0, 0.0, 0.5, 1.0, 1.5]


def test_gauss_seidel_order_follows_the_connections_not_the_declaration():
    units = [sampler("c"), sampler("b"), clock("a")]
    links = [Link(("a", "y"), ("b", "u")), Link(("b", "z"), ("c", "u"))]
    desc = {u.name: u.description for u in units}
    assert gauss_seidel_order(desc, links) == ["a", "b", "c"]


def test_gauss_seidel_breaks_a_feedback_loop_at_the_feedthrough_output():
    """building-like state unit <-> isolator-like feedthrough unit: the state unit steps first."""
    units = [gain("iso"), sampler("bld")]
    links = [Link(("bld", "z"), ("iso", "u")), Link(("iso", "w"), ("bld", "u"))]
    desc = {u.name: u.description for u in units}
    assert gauss_seidel_order(desc, links) == ["bld", "iso"]


def test_feedthrough_outputs_are_consistent_at_every_communication_point():
    """gain reads the clock: after each step its output equals k * y(t) at the same t, in both schemes."""
    links = [Link(("clock", "y"), ("gain", "u"))]
    watched = [("clock", "y"), ("gain", "w")]
    for scheme in ("gauss-seidel", "jacobi"):
        for inputs in ("hold", "step-mean"):
            _, rec, _ = run([gain(), clock()], links, scheme, watched=watched, inputs=inputs)
            assert rec.column("gain.w").tolist() == [2 * y for y in rec.column("clock.y")]


@pytest.mark.parametrize("scheme", ["gauss-seidel", "jacobi"])
def test_a_watched_local_is_read_with_the_end_of_step_inputs(scheme):
    """A local (FMI 2.0 declares no dependencies for it) that depends on an input, q = 3 u, recorded beside a
    feedthrough output w = 2 u and beside a state unit's local p = u: both equal the law at y(t) at every
    communication point, although the step held the step mean of y (the isolators' F_off beside F)."""
    links = [Link(("clock", "y"), ("gain", "u")), Link(("clock", "y"), ("sampler", "u"))]
    calls: list = []
    feedthrough = FakeUnit("gain", ["u"], ["w"], lambda s, i: {"w": 2 * i["u"], "q": 3 * i["u"]},
                           dependencies={"w": ("u",)}, local=["q"], calls=calls)
    state = FakeUnit("sampler", ["u"], ["z"], lambda s, i: {"z": s["z"], "p": i["u"]},
                     lambda s, i, t, h: {"z": i["u"]}, state={"z": -1.0}, local=["p"])
    watched = [("clock", "y"), ("gain", "w"), ("gain", "q"), ("sampler", "p")]
    _, rec, _ = run([feedthrough, state, clock()], links, scheme, watched=watched, inputs="step-mean")
    y = rec.column("clock.y").tolist()
    assert y == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert rec.column("gain.w").tolist() == [2 * v for v in y]
    assert rec.column("gain.q").tolist() == [3 * v for v in y]
    assert rec.column("sampler.p").tolist() == y
    # the gain's propagation sets all its inputs: q is read there with w, at no extra set
    assert [c for c in calls if c[0] == "get"][-1] == ("get", "gain", ("w", "q"))
    without: list = []
    plain = FakeUnit("gain", ["u"], ["w"], lambda s, i: {"w": 2 * i["u"], "q": 3 * i["u"]},
                     dependencies={"w": ("u",)}, local=["q"], calls=without)
    run([plain, clock()], links[:1], scheme, watched=[("gain", "w")], inputs="step-mean")
    assert sum(c[0] == "set" for c in calls) == sum(c[0] == "set" for c in without)


def test_propagation_levels_chain_feedthrough_units():
    units = [clock("c"), gain("g1"), gain("g2", k=3.0)]
    links = [Link(("c", "y"), ("g1", "u")), Link(("g1", "w"), ("g2", "u"))]
    desc = {u.name: u.description for u in units}
    assert propagation_order(desc, links) == [[("g1", "w")], [("g2", "w")]]
    _, rec, _ = run(units, links, "jacobi", watched=[("c", "y"), ("g2", "w")])
    assert rec.column("g2.w").tolist() == [6 * y for y in rec.column("c.y")]


def test_algebraic_loop_is_reported_with_its_path():
    units = [gain("a"), gain("b")]
    links = [Link(("a", "w"), ("b", "u")), Link(("b", "w"), ("a", "u"))]
    with pytest.raises(AlgebraicLoopError) as err:
        CouplingAlgorithm(units, links)
    text = str(err.value)
    assert "algebraic loop" in text and "a.w" in text and "b.u" in text and "b.w" in text and "a.u" in text


def test_a_delayed_connection_breaks_the_loop():
    units = [gain("a"), gain("b")]
    links = [Link(("a", "w"), ("b", "u")), Link(("b", "w"), ("a", "u"), delayed=True)]
    CouplingAlgorithm(units, links)  # no error


def test_undeclared_dependencies_mean_feedthrough_from_all_inputs():
    a = FakeUnit("a", ["u"], ["w"], lambda s, i: {"w": i["u"]}, dependencies={"w": None})
    b = gain("b")
    with pytest.raises(AlgebraicLoopError):
        CouplingAlgorithm([a, b], [Link(("a", "w"), ("b", "u")), Link(("b", "w"), ("a", "u"))])


@pytest.mark.parametrize(("start", "stop", "h", "n"),
                         [(0.0, 150.0, 1e-3, 150_000), (0.0, 53.76, 1e-3, 53_760), (1.1, 1.4, 0.1, 3)])
def test_time_grid_lands_exactly_on_the_stop_time(start, stop, h, n):
    count, t = time_grid(start, stop, h)
    assert count == n and t(0) == start and t(n) == stop
    assert all(t(k) == start + k * h for k in range(0, n, max(1, n // 1000)))
    # a float accumulator drifts; the grid does not
    acc = start
    for _ in range(n):
        acc += h
    assert acc != stop


def test_time_grid_rejects_a_span_that_is_not_whole_steps():
    with pytest.raises(ValueError, match="whole number"):
        time_grid(0.0, 1.0, 0.3)


def test_execution_counts_steps_and_records_every_point():
    calls: list = []
    units = [clock(calls=calls)]
    algo = CouplingAlgorithm(units, [], [("clock", "y")])
    rec = Recorder(algo, [("clock", "y")], 3)
    result = execute(algo, 0.0, 0.3, 0.1, [rec])
    assert result.complete and result.steps_done == 3 and result.end_time == 0.3
    assert rec.times.tolist() == [0.0, 0.1, 0.2, 0.3]  # t_k = k * h, the last exactly the stop time
    steps = [c for c in calls if c[0] == "step"]
    assert [c[2] for c in steps] == [0.0, 0.1, 0.2]
    assert sum(c[2] + c[3] == 0.3 for c in steps[-1:]) == 1  # last step ends exactly on stop


def test_teardown_after_a_failing_unit():
    calls: list = []
    units = [clock("a", calls=calls), clock("b", calls=calls, fail_at=0.25), sampler("c", calls=calls)]
    algo = CouplingAlgorithm(units, [Link(("a", "y"), ("c", "u"))], [("a", "y")])
    rec = Recorder(algo, [("a", "y")], 10)
    result = execute(algo, 0.0, 1.0, 0.1, [rec])
    assert result.status == "failed" and isinstance(result.error, SimulationError)
    assert result.error.unit == "b" and result.error.time == pytest.approx(0.3)
    assert all(u.terminated == 1 for u in units)
    assert result.steps_done == 3 and rec.count == 4  # rows 0..3 were recorded before the failure


def test_teardown_after_an_interrupt():
    class Interrupting:
        def record(self, k, t):
            if k == 2:
                raise KeyboardInterrupt

    units = [clock("a")]
    algo = CouplingAlgorithm(units, [], [("a", "y")])
    result = execute(algo, 0.0, 1.0, 0.1, [Interrupting()])
    assert result.status == "interrupted" and units[0].terminated == 1


def test_teardown_when_setup_fails():
    class BadSetup(FakeUnit):
        def setup(self, start_time, stop_time):
            raise SimulationError("cannot instantiate", unit=self.name)

    good = clock("good")
    bad = BadSetup("bad", [], ["y"], lambda s, i: {"y": 0.0})
    algo = CouplingAlgorithm([good, bad], [])
    result = execute(algo, 0.0, 1.0, 0.1)
    assert result.status == "failed" and good.terminated == 1 and bad.terminated == 1


def test_calls_per_step_are_batched():
    calls: list = []
    units = [clock(calls=calls), sampler(calls=calls)]
    algo = CouplingAlgorithm(units, [Link(("clock", "y"), ("sampler", "u"))], [("sampler", "z")])
    execute(algo, 0.0, 1.0, 1.0)
    one_step = calls[calls.index(("step", "clock", 0.0, 1.0)) - 0:]
    kinds = [c[0] for c in one_step if c[0] in ("set", "get", "step")]
    # clock: step, get; sampler: set, step, get
    assert kinds == ["step", "get", "set", "step", "get"]
