"""The Jacobi example of docs/running.md: the extrapolated current stays within the bound the doc states."""

from __future__ import annotations

import json
import re

import pytest

from components.physics.sosm_controller_core import SosmGains
from orchestration.api import load_scenario, run

from ..conftest import PROJECT


@pytest.mark.slow
def test_jacobi_extrapolation_overshoots_the_current_limit_by_at_most_1_25_rho_h(tmp_path):
    # Under Jacobi + step-mean the isolator's current is the mid-step quadratic extrapolation
    # (15 i0 - 10 i1 + 3 i2) / 8 of the controller's last values. The controller changes i by at
    # most rho h per step (its rate is clipped to +-rho, then i to [0, i_max]), so the estimate
    # exceeds i_max by at most (7 + 3) / 8 rho h. Every clipped value the isolator reports must
    # be within that bound, plus the 4 significant digits the warning prints (0.5 mA).
    plan = load_scenario(PROJECT / "scenarios" / "kobe.yaml",
                         ["simulation.stop_time=20", "simulation.algorithm=jacobi"])
    res = run(plan, out=tmp_path / "run")
    assert res.complete
    messages = json.loads((res.folder / "manifest.json").read_text())["unit_messages"]
    seen = [float(m.group(1)) for text in messages
            if (m := re.search(r"current i = ([-0-9.e+]+) A left \[0, 3\] A", text))]
    assert seen, "the example is expected to reach the 3 A limit under Jacobi"
    h, rho = plan.loaded.scenario.simulation.step, SosmGains().rho
    bound = 3.0 + 1.25 * rho * h
    assert max(seen) <= bound + 5e-4, (max(seen), bound)
    assert min(seen) >= -1.25 * rho * h - 5e-4  # the same bound below 0 A
