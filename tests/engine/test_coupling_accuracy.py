"""Coupling accuracy: the default co-simulation against a monolithic Radau reference of the same physics.

Windows cover each record's strong motion; every peak of the full record falls inside them
(El Centro 4.6 s, Hachinohe 4.2 s, Northridge 4.3 s, Kobe 11.8 s; docs/master.md, Coupling accuracy).
The co-simulation is evaluated in-process with orchestration.inprocess.simulate_coupled (the engine's
coupling algorithm over the physics cores), which equals the FMU co-simulation (test_inprocess,
test_end_to_end); one case runs the FMUs directly.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.monolithic import SystemSetup, Trajectory, simulate_radau
from orchestration.engine_hooks import run_scenario
from orchestration.inprocess import simulate_coupled

from ..conftest import PROJECT, shipped_record

pytestmark = pytest.mark.slow  # Radau references of 6-13 s windows: seconds to minutes each

H = 1e-3
WINDOWS = {  # record: simulated window [s]
    "elcentro_1940_ns.csv": 6.0,
    "hachinohe_1968_ns.csv": 6.0,
    "northridge_1994_sylmar_ns.csv": 6.0,
    "kobe_1995_jma_ns.csv": 13.0,
}


def setup_for(record: str, current: float | None) -> SystemSetup:
    return SystemSetup(GroundMotion(read_record(shipped_record(record)), scale=0.5), passive_current=current)


def relative_errors(got: dict[str, float], ref: dict[str, float]) -> dict[str, float]:
    return {k: abs(got[k] - ref[k]) / ref[k] for k in ref}


def reference(setup: SystemSetup, T: float, **tol) -> Trajectory:
    return simulate_radau(setup, T, np.arange(round(T / H) + 1) * H, **tol)


CASES = [(record, current) for record in WINDOWS for current in (0.0, 3.0, None)]


@pytest.mark.parametrize(("record", "current"), CASES,
                         ids=[f"{r.split('_')[0]}-{'sosm' if c is None else f'{c:g}A'}" for r, c in CASES])
def test_default_coupling_is_within_one_percent_of_radau(record, current):
    T = WINDOWS[record]
    setup = setup_for(record, current)
    ref = reference(setup, T).peaks()
    got = simulate_coupled(setup, H, round(T / H)).peaks()
    errors = relative_errors(got, ref)
    assert max(errors.values()) < 0.01, {k: f"{100 * e:.3f} %" for k, e in errors.items()}


def test_hand_picked_gains_make_sosm_on_kobe_ill_conditioned():
    """With the hand-picked gains (before tuning) the SOSM loop under Kobe chatters at the current
    limit and is ill-conditioned: two tight Radau solutions (rtol 1e-8 and 1e-10) differ by more
    than 5 % on some peak, so no coupling can be held to 1 % there. The tuned default gains are
    well-conditioned (previous test)."""
    from components.physics.sosm_controller_core import HAND_PICKED_GAINS

    record = "kobe_1995_jma_ns.csv"
    T = WINDOWS[record]
    base = setup_for(record, None)
    setup = SystemSetup(base.motion, passive_current=None, gains=HAND_PICKED_GAINS)
    tight = reference(setup, T).peaks()
    tighter = reference(setup, T, rtol=1e-10, atol=1e-14).peaks()
    assert max(relative_errors(tight, tighter).values()) > 0.05


def test_fmu_cosimulation_within_one_percent_of_radau(tmp_path: Path):
    """The same check straight through the FMUs and the master (El Centro, SOSM, default scheme)."""
    T = WINDOWS["elcentro_1940_ns.csv"]
    setup = setup_for("elcentro_1940_ns.csv", None)
    out = run_scenario(PROJECT / "scenarios" / "elcentro.yaml", (f"simulation.stop_time={T}",),
                       out=tmp_path / "run", plots=False)
    ref = reference(setup, T).peaks()
    s = out.summary
    got = {"x_0": s["peak_base_displacement_m"],
           **{f"drift_{j}": s["peak_drift_m"][f"building.drift_{j}"] for j in (1, 2, 3)},
           **{f"a_{j}": s["peak_abs_acceleration_m_s2"][f"building.a_{j}"] for j in range(4)}}
    errors = relative_errors(got, ref)
    assert max(errors.values()) < 0.01, errors
