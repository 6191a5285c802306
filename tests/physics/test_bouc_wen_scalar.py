"""The FMU's plain-float Bouc-Wen step (bouc_wen_advance_scalar) against the broadcast one it replaces there."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from components.physics.bouc_wen_core import SYNTHETIC_DEFAULT, bouc_wen_advance, bouc_wen_advance_scalar
from components.physics.mre_isolator_core import CURRENT_MAX_A

# the nominal plant's law over its current range, in SI (the joint fit the studies run)
MODEL = SYNTHETIC_DEFAULT


@settings(max_examples=400, deadline=None)
@given(y=st.floats(-1.5, 1.5), dx=st.floats(-2e-3, 2e-3), i=st.floats(0.0, CURRENT_MAX_A),
       dx_max=st.sampled_from([1e-6, 1e-5, 1e-4]))
def test_the_plain_float_step_equals_the_broadcast_one_bit_for_bit_on_the_device(y, dx, i, dx_max):
    """Same formulas in the same order: the same float64 result, on this machine, for the nominal law at any
    current, state and increment (sub-step counts from 1 to the cap of 64)."""
    p = MODEL.at_current(i)
    expected = float(bouc_wen_advance(y, dx, p.beta, p.gamma, p.delta, p.n, dx_max))
    assert bouc_wen_advance_scalar(y, dx, p.beta, p.gamma, p.delta, p.n, dx_max) == expected


def test_random_laws_far_from_the_device_agree_or_fall_back():
    """5,000 random laws (beta of either sign, n from 0.3 to 2.5, increments from 1 nm to 1 mm): equal results,
    and where the float arithmetic overflows the broadcast version's inf/NaN (the shell reports those)."""
    rng = np.random.default_rng(1)
    for _ in range(5_000):
        y, dx = rng.uniform(-1.2, 1.2), rng.normal() * 10 ** rng.uniform(-9, -3)
        beta = 10 ** rng.uniform(1, 5) * rng.choice([1.0, 1.0, -0.3])
        gamma, delta, n = 10 ** rng.uniform(1, 5), 10 ** rng.uniform(2, 5), rng.uniform(0.3, 2.5)
        dx_max = 10 ** rng.uniform(-6, -4)
        with np.errstate(all="ignore"):
            expected = float(bouc_wen_advance(y, dx, beta, gamma, delta, n, dx_max))
        got = bouc_wen_advance_scalar(y, dx, beta, gamma, delta, n, dx_max)
        assert got == expected or (math.isnan(got) and math.isnan(expected)), (y, dx, beta, gamma, delta, n)
