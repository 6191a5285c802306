"""The robustness variants' units: the current lag and the sensor channels, against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from components.physics.current_lag_core import CurrentLag, lag_factor
from components.physics.sensor_channels_core import SensorChannels


@pytest.mark.parametrize("tau", [0.010, 0.030])
def test_lag_step_response_is_one_minus_exp(tau):
    """A unit step of the command: i(t_n) = 1 - exp(-t_n / tau) at every communication point (exact discretisation)."""
    h = 1e-3
    lag = CurrentLag(tau, i0=0.0)
    for n in range(1, 301):
        i = lag.step(1.0, h)
        assert i == pytest.approx(1.0 - math.exp(-n * h / tau), rel=1e-12, abs=1e-15)


def test_lag_with_varying_step_and_command_follows_the_ode():
    """Piecewise-constant commands with unequal steps: the solution of tau di/dt = i_cmd - i, step by step."""
    tau, i_exact = 0.02, 0.5
    lag = CurrentLag(tau, i0=0.5)
    rng = np.random.default_rng(3)
    for _ in range(200):
        h, cmd = float(rng.uniform(1e-4, 5e-3)), float(rng.uniform(0.0, 3.0))
        i_exact = cmd + (i_exact - cmd) * math.exp(-h / tau)
        assert lag.step(cmd, h) == pytest.approx(i_exact, rel=1e-12)


def test_lag_zero_tau_is_no_lag_and_negative_tau_is_refused():
    lag = CurrentLag(0.0, i0=1.0)
    assert [lag.step(c, 1e-3) for c in (3.0, 0.0, 1.7)] == [3.0, 0.0, 1.7]
    assert lag_factor(1e-3, 0.0) == 1.0
    with pytest.raises(ValueError, match="tau must be >= 0"):
        CurrentLag(-0.01)
    with pytest.raises(ValueError, match="tau must be >= 0"):
        lag_factor(1e-3, -1.0)


def test_noise_rms_within_statistical_bound_and_seeded():
    """Sample RMS of each channel's noise within 4 standard errors of the stated RMS; mean within 4 SE of 0."""
    rms = [1e-4, 1e-3, 0.05, 10.0]
    n = 20_000
    ch = SensorChannels(rms, delay=0, seed=7)
    ch.start([0.0] * 4)
    samples = []
    for _ in range(n):
        ch.step([0.0] * 4)
        samples.append(ch.outputs([0.0] * 4))
    y = np.array(samples)
    got = np.sqrt(np.mean(y ** 2, axis=0))
    # the sample mean square of n Gaussian values has relative standard error sqrt(2/n); the RMS half of it
    assert np.all(np.abs(got / np.array(rms) - 1.0) < 4 * math.sqrt(0.5 / n))
    assert np.all(np.abs(y.mean(axis=0)) < 4 * np.array(rms) / math.sqrt(n))
    assert abs(np.corrcoef(y[:, 0], y[:, 1])[0, 1]) < 4 / math.sqrt(n)  # channels independent
    again = SensorChannels(rms, seed=7)
    again.start([0.0] * 4)
    again.step([0.0] * 4)
    assert np.array_equal(again.outputs([0.0] * 4), y[0])  # the same seed, the same noise
    other = SensorChannels(rms, seed=8)
    other.start([0.0] * 4)
    other.step([0.0] * 4)
    assert not np.array_equal(other.outputs([0.0] * 4), y[0])


def test_noise_is_held_over_a_sample():
    """The noise of a sample does not change between reads (the master may read an output twice)."""
    ch = SensorChannels([0.1], seed=1)
    ch.start([0.0])
    ch.step([0.0])
    assert ch.outputs([2.0])[0] == ch.outputs([2.0])[0]
    assert ch.outputs([2.0])[0] - 2.0 == pytest.approx(ch.outputs([0.0])[0])


@pytest.mark.parametrize("delay", [1, 3])
def test_delay_shifts_by_whole_steps(delay):
    """y(t_n) = u(t_{n-d}) exactly (no noise); before the start the signal sat at its initial value."""
    u = np.sin(0.37 * np.arange(50)) + 2.0
    ch = SensorChannels([0.0, 0.0], delay=delay, seed=0)
    ch.start([u[0], -u[0]])
    out = [ch.outputs([u[0], -u[0]])[0]]
    for n in range(1, len(u)):
        ch.step([u[n - 1], -u[n - 1]])  # stepped from t_{n-1}: the sample u(t_{n-1})
        out.append(ch.outputs([np.nan, np.nan])[0])  # the live input is not used with a delay
    expected = [u[max(n - delay, 0)] for n in range(len(u))]
    assert out == expected


def test_no_delay_no_noise_is_exact_pass_through():
    ch = SensorChannels([0.0, 0.0, 0.0])
    ch.start([1.0, 2.0, 3.0])
    ch.step([1.0, 2.0, 3.0])
    assert list(ch.outputs([0.1, -2.5e-7, 1e9])) == [0.1, -2.5e-7, 1e9]


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"rms": [0.1, -0.1]}, "channel 2: noise RMS must be >= 0"),
    ({"rms": [math.nan]}, "channel 1: noise RMS must be >= 0"),
    ({"rms": [0.1], "delay": -1}, "delay must be a whole number"),
    ({"rms": [0.1], "delay": 1.5}, "delay must be a whole number"),
    ({"rms": [0.1], "seed": -3}, "seed must be an integer"),
    ({"rms": [0.1], "seed": 2**31}, r"seed must be an integer in \[0, 2\^31 - 1\]"),  # the FMI Integer's range
    ({"rms": [0.1], "seed": True}, "seed must be an integer"),
])
def test_channels_refuse_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SensorChannels(**kwargs)


def test_the_largest_seed_is_the_fmi_integers_and_the_studys():
    from orchestration.case_study.robustness_config import MAX_SEED

    assert SensorChannels([0.1], seed=MAX_SEED).seed == 2**31 - 1
