"""End to end: shipped scenarios from the CLI, FMU co-simulation vs in-process physics, vs Radau."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from components.physics.ground_motion_core import GroundMotion, read_record
from components.physics.monolithic import SystemSetup, simulate_radau
from orchestration.engine_hooks import run_scenario
from orchestration.inprocess import simulate_coupled

from ..conftest import PROJECT

RUN = [sys.executable, str(PROJECT / "orchestration" / "run.py")]
SCENARIOS = ["kobe", "elcentro", "hachinohe", "northridge"]


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*RUN, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("name", SCENARIOS)
@pytest.mark.parametrize("variant", [(), ("--set", "controller.mode=passive")], ids=["sosm", "passive"])
def test_shipped_scenarios_run_from_the_cli(tmp_path, name, variant):
    out = tmp_path / "run"
    proc = cli(str(PROJECT / "scenarios" / f"{name}.yaml"), "--set", "simulation.stop_time=2", *variant,
               "--out", str(out), "--quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    manifest = json.loads((out / "manifest.json").read_text())
    assert summary["complete"] and summary["steps_done"] == 2000
    assert manifest["complete"] and len(manifest["fmus"]) == 4
    assert all(len(f["sha256"]) == 64 for f in manifest["fmus"].values())
    assert manifest["scenario"]["units"]["ground"]["parameters"]["scale"] == 0.5
    with open(out / "timeseries.csv") as f:
        header = next(csv.reader(f))
    assert header[0] == "time" and "building.a_3" in header and "controller.i" in header
    assert {"top_floor_acceleration.png", "drifts.png", "current.png", "isolator_hysteresis.png"} <= {
        p.name for p in out.iterdir()}
    for key in ("peak_base_displacement_m", "peak_drift_m", "peak_abs_acceleration_m_s2", "peak_current_A",
                "mean_current_A", "wall_time_s"):
        assert key in summary
    if variant:
        assert summary["peak_current_A"] == 0.0
    assert "periods: fixed base " in proc.stdout and summary["periods"]["fixed_base_s"]


def test_cli_scenario_error_exits_2_and_writes_nothing(tmp_path):
    out = tmp_path / "run"
    proc = cli(str(PROJECT / "scenarios" / "kobe.yaml"), "--set", "simulation.step=-1", "--set",
               "ground.record=!data nowhere.csv", "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2
    assert "simulation.step" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


def test_cli_never_overwrites_a_run(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("earlier results")
    proc = cli(str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "simulation.stop_time=0.01", "--out",
               str(out), cwd=tmp_path)
    assert proc.returncode == 2 and "not empty" in proc.stderr
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_default_run_folders_are_unique(tmp_path):
    args = ("simulation.stop_time=0.01", f"results.dir={tmp_path / 'runs'}")
    a = run_scenario(PROJECT / "scenarios" / "elcentro.yaml", args, plots=False)
    b = run_scenario(PROJECT / "scenarios" / "elcentro.yaml", args, plots=False)
    assert a.folder != b.folder and a.folder.parent == b.folder.parent


def setup_for(record: Path, mode: str, current: float = 0.0) -> SystemSetup:
    motion = GroundMotion(read_record(record), scale=0.5)
    return SystemSetup(motion, passive_current=None if mode == "sosm" else current)


COMPARED = {"building.x_0": ("x", 0), "building.x_3": ("x", 3), "building.v_0": ("v", 0),
            "building.a_0": ("a", 0), "building.a_3": ("a", 3), "building.arel_0": ("arel", 0),
            "isolator.F": ("F", None), "controller.i": ("i", None)}


@pytest.mark.parametrize(("scheme", "inputs"), [("gauss-seidel", "step-mean"), ("jacobi", "step-mean"),
                                               ("gauss-seidel", "hold"), ("jacobi", "hold")])
@pytest.mark.parametrize(("mode", "overrides"), [("sosm", ()), ("passive", ("controller.mode=passive",)),
                                                  ("passive3", ("controller.mode=passive", "controller.i_passive=3"))])
@pytest.mark.slow
def test_fmu_cosimulation_equals_the_in_process_physics(tmp_path, elcentro, scheme, inputs, mode, overrides):
    """Same cores, same step, same order and input estimate, no FMUs: agreement to 1e-9 proves the wrapping."""
    T = 4.0
    outcome = run_scenario(PROJECT / "scenarios" / "elcentro.yaml",
                           (f"simulation.stop_time={T}", f"simulation.algorithm={scheme}",
                            f"simulation.inputs={inputs}", *overrides),
                           out=tmp_path / "run", plots=False)
    assert outcome.result.complete
    setup = setup_for(elcentro, "sosm" if mode == "sosm" else "passive", 3.0 if mode == "passive3" else 0.0)
    ref = simulate_coupled(setup, 1e-3, round(T / 1e-3), scheme, inputs)
    assert outcome.recorder.times == pytest.approx(ref.t, abs=1e-12)
    for name, (field, j) in COMPARED.items():
        expected = getattr(ref, field) if j is None else getattr(ref, field)[:, j]
        got = outcome.recorder.column(name)
        scale = max(np.max(np.abs(expected)), 1e-300)
        assert np.max(np.abs(got - expected)) <= 1e-9 * scale, name
    if mode == "sosm":
        assert 0 < np.max(ref.i) <= 3.0


@pytest.mark.slow
def test_explicit_coupling_error_is_first_order(elcentro):
    """Holding the isolator force over each step (inputs: hold) lags it by half a step: a first-order
    coupling error, large at 1 ms (docs/master.md, Coupling accuracy) and about halved when the step is halved."""
    T = 6.0
    setup = setup_for(elcentro, "passive", 0.0)
    ref = simulate_radau(setup, T, np.arange(0, round(T / 2.5e-4) + 1) * 2.5e-4)
    errors = {}
    for h in (1e-3, 5e-4, 2.5e-4):
        peaks = simulate_coupled(setup, h, round(T / h), inputs="hold").peaks()
        ref_peaks = peaks_on_grid(ref, h)
        errors[h] = max(abs(peaks[k] - ref_peaks[k]) / ref_peaks[k] for k in ref_peaks)
    assert errors[1e-3] > 0.05  # explicit coupling is far off at 1 ms
    assert 1.5 < errors[1e-3] / errors[5e-4] < 2.6 and 1.5 < errors[5e-4] / errors[2.5e-4] < 2.6


def peaks_on_grid(traj, h):
    """Peaks of a reference trajectory sampled on the grid of step h (a multiple of its own)."""
    stride = round(h / (traj.t[1] - traj.t[0]))
    sub = type(traj)(traj.t[::stride], traj.x[::stride], traj.v[::stride], traj.a[::stride],
                     traj.arel[::stride], traj.F[::stride], traj.i[::stride], traj.ag[::stride])
    return sub.peaks()


def test_swapping_the_controller_for_a_constant_current_unit(tmp_path):
    """The scenario swaps the SOSM unit for the ConstantCurrent FMU; at the same current the results
    equal the SOSM unit's passive mode exactly."""
    swapped = run_scenario(PROJECT / "scenarios" / "elcentro_constant_current.yaml",
                           ("simulation.stop_time=2", "controller.current=3.0"), out=tmp_path / "a", plots=False)
    passive = run_scenario(PROJECT / "scenarios" / "elcentro.yaml",
                           ("simulation.stop_time=2", "controller.mode=passive", "controller.i_passive=3.0"),
                           out=tmp_path / "b", plots=False)
    assert swapped.result.complete and passive.result.complete
    for name in ("building.x_0", "building.a_3", "isolator.F", "controller.i"):
        assert np.array_equal(swapped.recorder.column(name), passive.recorder.column(name)), name


def test_swapping_in_the_bouc_wen_isolator(tmp_path):
    """The Bouc-Wen isolator FMU drops in through the scenario file alone and runs the whole system."""
    out = run_scenario(PROJECT / "scenarios" / "elcentro_bouc_wen.yaml", ("simulation.stop_time=2",),
                       out=tmp_path / "run", plots=False)
    assert out.result.complete
    assert out.units[2].description.model_identifier == "BoucWenIsolator"
    F, x = out.recorder.column("isolator.F"), out.recorder.column("building.x_0")
    assert np.max(np.abs(F)) > 0 and np.max(np.abs(x)) > 0
    # a restoring force: it opposes the displacement over most of the run
    assert np.mean(np.sign(F[x != 0]) == np.sign(x[x != 0])) > 0.5
    # no periods for an isolator the in-process model lacks: the section says why
    assert "isolator is BoucWenIsolator" in out.summary["periods"]["note"] and len(out.summary["periods"]) == 1


def test_the_run_folder_csv_is_the_recorded_data_formatted_exactly(tmp_path):
    """timeseries.csv holds every recorded value as '%.12g' formats it, however the run folder writes
    it; the recorder's own (compiled) writer gives the same bytes."""
    outcome = run_scenario(PROJECT / "scenarios" / "kobe.yaml", ("simulation.stop_time=3",), out=tmp_path / "run",
                           plots=False)
    assert outcome.result.complete
    rec = outcome.recorder
    written = (outcome.folder / "timeseries.csv").read_bytes()
    rows = np.column_stack([rec.times, rec.data[: rec.count]]).tolist()
    line = ",".join(["%.12g"] * (len(rec.names) + 1)) + "\n"
    expected = ",".join(["time", *rec.names]) + "\n" + "".join(line % tuple(r) for r in rows)
    assert written == expected.encode()
    rec.write_csv(tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_bytes() == written

    # the same Kobe run's summary.json has the building's periods: fixed base, and T1 at 0 A and i_max (8 mm)
    periods = json.loads((outcome.folder / "summary.json").read_text())["periods"]
    assert periods["fixed_base_s"] == pytest.approx([0.1838, 0.06325, 0.04232], rel=1e-3)
    assert periods["isolated_0A_s"] == pytest.approx(0.8396, rel=1e-3)
    assert periods["isolated_i_max_s"] == pytest.approx(0.2106, rel=1e-3)
    assert periods["i_max_A"] == 3.0 and periods["reference_displacement_m"] == 0.008
