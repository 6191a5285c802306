"""Input estimates that respect jumps: an extrapolated output that depends on a held (piecewise-constant) input
restarts its history when that input changes, so a jump is not amplified by the mid-step extrapolation."""

from __future__ import annotations

import numpy as np
import pytest

from orchestration.master.algorithm import CouplingAlgorithm
from orchestration.master.execution import execute
from orchestration.master.graph import Link

from ..support.fake_units import FakeUnit

H = 0.01
K, C = 1000.0, 50.0  # the force F = K * i + C * t [N]: linear in time, a jump where the current jumps
T_JUMP = 0.1  # the current goes 0 -> 3 A over the step that starts here


def _system(discrete: bool, scheme: str):
    """switch (current 0 -> 3 A) -> device (F = K i + C t, feedthrough from i) -> consumer (records what it got).

    The consumer steps before the device (Gauss-Seidel order given, or Jacobi): it gets the device's force
    extrapolated to mid-step from F(t), F(t - h), F(t - 2h).
    """
    switch = FakeUnit("switch", [], ["i"], lambda s, i: {"i": s["i"]},
                      lambda s, i, t, h: {"i": 3.0 if t + 1e-12 >= T_JUMP else 0.0}, state={"i": 0.0},
                      discrete=("i",) if discrete else ())
    device = FakeUnit("device", ["i"], ["F"], lambda s, i: {"F": K * i["i"] + C * s["t"]},
                      lambda s, i, t, h: {"t": t + h}, dependencies={"F": ("i",)}, state={"t": 0.0})
    consumer = FakeUnit("consumer", ["F"], ["n"], lambda s, i: {"n": float(len(s["seen"]))},
                        lambda s, i, t, h: {"seen": [*s["seen"], i["F"]]}, state={"seen": []})
    links = [Link(("switch", "i"), ("device", "i")), Link(("device", "F"), ("consumer", "F"))]
    order = ["switch", "consumer", "device"] if scheme == "gauss-seidel" else None
    algo = CouplingAlgorithm([switch, device, consumer], links, scheme=scheme, order=order)
    assert execute(algo, 0.0, 0.2, H, executor="python").complete
    return np.asarray(consumer.state["seen"]), algo


@pytest.mark.parametrize("scheme", ["gauss-seidel", "jacobi"])
def test_the_force_after_a_current_jump_is_not_overshot(scheme):
    seen, _ = _system(True, scheme)
    t = np.arange(len(seen)) * H
    # Gauss-Seidel: the switch steps first and the device runs on the new current from T_JUMP on; the consumer,
    # stepping before the device, gets the device's force evaluated at T_JUMP with the new current (the value
    # at T_JUMP+, one set and one get), then the line through that value and F(T_JUMP + h), then the quadratic.
    # Jacobi: the device reads the current at t, so 3 A from T_JUMP + h on: the force there is the first value
    # with it (the feedthrough propagation), and the consumer's estimate restarts at it.
    gauss_seidel = scheme == "gauss-seidel"
    first_new = round(T_JUMP / H) + (0 if gauss_seidel else 1)
    restarted = {first_new}
    i_at = np.where(np.arange(len(seen)) >= first_new, 3.0, 0.0)  # the current the device runs on in step k
    mean_exact = K * i_at + C * (t + H / 2)  # the mean of the force over [t, t + h]
    for k, value in enumerate(seen):
        if k in restarted:  # the value at t with the present current: off by C h / 2 only, not 7/8 of the jump
            assert value == pytest.approx(K * i_at[k] + C * t[k], rel=1e-12), k
        elif k > 0:  # linear from two values, then the quadratic through three: exact for a linear signal
            assert value == pytest.approx(mean_exact[k], rel=1e-12), k
    # the old rule, for contrast: a continuous current is extrapolated straight through the jump
    old, _ = _system(False, scheme)
    overshoot = old[round(T_JUMP / H) + 1] - (K * 3.0 + C * (t[round(T_JUMP / H) + 1] + H / 2))
    assert overshoot == pytest.approx(7 / 8 * K * 3.0, rel=1e-9)  # (15 F_k - 10 F_k-1 + 3 F_k-2) / 8
    assert np.max(seen) <= K * 3.0 + C * 0.2 + 1e-9  # never above the largest true force


def test_the_restart_is_planned_for_outputs_that_depend_on_a_held_input_only():
    _, algo = _system(True, "gauss-seidel")
    plan = algo._input_plans["consumer"]
    assert [(r.position, r.slot, list(r.drivers), list(r.fresh)) for r in plan.restarting] == [
        (0, algo.slot[("device", "F")], [algo.slot[("switch", "i")]], [algo.slot[("switch", "i")]])]
    assert [op.kind for op in algo.program()].count("peek") == 1
    _, continuous = _system(False, "gauss-seidel")
    assert continuous._input_plans["consumer"].restarting == []
