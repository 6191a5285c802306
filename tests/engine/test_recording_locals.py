"""A scenario's ``outputs:`` list may name an FMI local variable (recorded only when named)."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from components.physics.shear_building_core import BuildingParams
from orchestration import run as run_tool
from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import ScenarioError

from ..conftest import PROJECT

NAMED = [f"building.{v}_{j}" for v in ("drift", "shear", "residual_drift") for j in (1, 2, 3)]
NAMED += [f"building.v_{j}" for j in (0, 1, 2, 3)]


@pytest.mark.slow  # the yielding building for 12 s of Kobe
@pytest.mark.parametrize("executor", ["native", "python"])
def test_residual_drift_is_recorded_when_named_and_equals_the_law(tmp_path, executor):
    """residual_drift_j = drift_j - (shear_j - c_j (v_j - v_{j-1})) / k_j at every sample (docs/structures.md)."""
    out = tmp_path / "run"
    code = run_tool.main([str(PROJECT / "scenarios" / "kobe_yielding.yaml"), "--set", f"outputs=[{', '.join(NAMED)}]",
                          "--set", "simulation.stop_time=12", "--set", f"simulation.executor={executor}",
                          "--set", "controller.mode=passive", "--set", "controller.i_passive=0",
                          "--out", str(out), "--quiet", "--no-plots"])
    assert code == 0
    with open(out / "timeseries.csv", newline="") as f:
        rows = list(csv.reader(f))
    col = {name: np.array([float(r[i]) for r in rows[1:]]) for i, name in enumerate(rows[0])}
    dyke = BuildingParams.dyke()
    for j in (1, 2, 3):
        force = col[f"building.shear_{j}"] - dyke.c[j] * (col[f"building.v_{j}"] - col[f"building.v_{j - 1}"])
        expected = col[f"building.drift_{j}"] - force / dyke.k[j]
        assert np.max(np.abs(col[f"building.residual_drift_{j}"] - expected)) < 1e-9  # CSV's 12 digits of mm-size
    assert abs(col["building.residual_drift_1"][-1]) > 1e-4  # storey 1 yields at 0 A: a set of more than 0.1 mm


def test_a_local_is_not_recorded_by_outputs_all_and_is_no_output_elsewhere():
    plan = plan_scenario(PROJECT / "scenarios" / "kobe_yielding.yaml", ())
    assert not any(name.startswith("residual_drift") for _, name in plan.recorded)
    with pytest.raises(ScenarioError, match=r"building.residual_drift_1 is local, expected output"):
        plan_scenario(PROJECT / "scenarios" / "kobe_yielding.yaml",
                      ("limits.max_abs={building.residual_drift_1: 1.0}",))


@pytest.mark.slow  # two 1 s runs of the nominal plant (0.25 ms steps)
@pytest.mark.parametrize("executor", ["native", "python"])
def test_f_off_is_read_with_the_inputs_f_is_read_with(tmp_path, executor):
    """At 0 A throughout, the Bouc-Wen unit's F_off (a local: the force at 0 A along the same motion) equals
    its F at every sample, exactly: both are read with the inputs at t + h, through the stop contact too
    (El Centro passes 15 mm near 1.86 s). Read right after the step, F_off paired the state at t + h with
    the step-mean inputs and differed by up to 2.2 kN at the stop."""
    out = tmp_path / "run"
    code = run_tool.main([str(PROJECT / "scenarios" / "nominal_plant_elcentro.yaml"), "--out", str(out), "--quiet",
                          "--no-plots", "--set", "simulation.stop_time=2", "--set", f"simulation.executor={executor}",
                          "--set", "controller.mode=passive", "--set", "controller.i_passive=0",
                          "--set", "outputs=[isolator.F, isolator.F_off, building.x_0]"])
    assert code == 0
    with open(out / "timeseries.csv", newline="") as f:
        rows = list(csv.reader(f))
    col = {name: np.array([float(r[i]) for r in rows[1:]]) for i, name in enumerate(rows[0])}
    assert np.max(np.abs(col["building.x_0"])) > 0.015  # the motion reaches the stop
    assert np.array_equal(col["isolator.F"], col["isolator.F_off"])
