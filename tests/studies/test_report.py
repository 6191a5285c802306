"""A run's figures and manifest say what was run: caption, labels, strong-motion window, provenance."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from orchestration.api import ScenarioError, load_scenario, run
from orchestration.building_report import strong_motion_window
from orchestration.master.report import RunDescription, decimate
from orchestration.master.session import describe_run

from ..conftest import PROJECT

SCENARIOS = PROJECT / "scenarios"


def test_strong_motion_window_of_a_burst_is_its_arias_5_95_span_widened():
    # Constant-amplitude motion on [10, 20) s, silence elsewhere: the Arias intensity grows
    # linearly over the burst, so 5 % is reached at 10.5 s and 95 % at 19.5 s (D = 9 s).
    # The window adds D/4 before and D/2 after; one sample (1 ms) of grid tolerance.
    t = np.arange(0, 60.0005, 0.001)
    ag = np.where((t >= 10) & (t < 20), 1.0, 0.0)
    lo, hi = strong_motion_window(t, ag)
    assert lo == pytest.approx(10.5 - 9 / 4, abs=2e-3)
    assert hi == pytest.approx(19.5 + 9 / 2, abs=2e-3)
    assert strong_motion_window(t, np.zeros_like(t)) is None  # no motion, no window


def test_decimation_keeps_every_peak_and_time_order():
    rng = np.random.default_rng(1)
    t = np.linspace(0, 150, 150_001)
    y = rng.standard_normal(t.size)
    y[77_777] = 50.0  # a single-sample spike must survive
    td, yd = decimate(t, y, 4000)
    assert len(td) <= 4000 and np.all(np.diff(td) > 0)
    assert yd.max() == y.max() and yd.min() == y.min()
    short = np.arange(10.0)
    assert decimate(short, short, 4000)[0] is short  # short lines are drawn as they are


def test_caption_fills_values_follows_labels_and_names_a_swapped_unit():
    run_ = RunDescription(
        values={"ground": {"record": "/data/kobe.csv", "scale": 0.5}, "controller": {"mode": "passive",
                                                                                      "i_passive": 3.0}},
        model_names={"ground": "GroundMotionSource", "controller": "ConstantCurrent"},
        labels={"controller.mode=passive": "passive, {controller.i_passive} A", "ground.record=kobe.csv": "Kobe",
                "building.a_3": "top floor"},
    )
    assert run_.render("{ground.record} ×{ground.scale} · {controller.mode}") == "Kobe ×0.5 · passive, 3 A"
    assert run_.render("{controller.gain}") == "ConstantCurrent"  # a parameter the unit does not have
    assert run_.label("building.a_3") == "top floor" and run_.label("building.a_2") == "building.a_2"


@pytest.mark.parametrize(("overrides", "expected"), [
    ((), "Kobe 1995, JMA Kobe N-S ×0.5 · SOSM control"),
    (("controller.mode=passive", "controller.i_passive=3", "ground.scale=1"),
     "Kobe 1995, JMA Kobe N-S ×1 · passive, 3 A"),
])
def test_the_shipped_scenarios_caption_says_record_scale_and_strategy(overrides, expected):
    plan = load_scenario(SCENARIOS / "kobe.yaml", list(overrides))
    from orchestration.master.report import caption

    assert caption(plan.report, describe_run(plan), "kobe") == expected


def test_a_caption_naming_an_unknown_unit_is_a_scenario_error():
    with pytest.raises(ScenarioError) as info:
        load_scenario(SCENARIOS / "kobe.yaml", ["report.caption=x{grund.scale}"])
    assert [p.key for p in info.value.problems] == ["report.caption"]
    assert "no unit named 'grund'" in info.value.problems[0].message


@pytest.mark.slow
def test_run_folder_names_the_run_and_its_source_revision(tmp_path):
    plan = load_scenario(SCENARIOS / "northridge.yaml", ["simulation.stop_time=2", "controller.mode=passive"])
    res = run(plan, out=tmp_path / "run", plots=True)
    assert res.complete
    summary = json.loads((res.folder / "summary.json").read_text())
    assert summary["caption"] == "Northridge 1994, Sylmar N-S ×0.5 · passive, 0 A"
    manifest = json.loads((res.folder / "manifest.json").read_text())
    prov = manifest["provenance"]
    import tomllib

    assert prov["version"] == tomllib.loads((PROJECT / "pyproject.toml").read_text())["project"]["version"]
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=PROJECT, capture_output=True, text=True)
    if head.returncode == 0:  # a git checkout (CI clones one); an unpacked archive has no commit
        assert prov["commit"] == head.stdout.strip() and isinstance(prov["dirty"], bool)
    else:
        assert prov["commit"] is None
    pngs = sorted(p.name for p in res.folder.glob("*.png"))
    assert pngs == ["current.png", "drifts.png", "isolator_hysteresis.png", "top_floor_acceleration.png"]


@pytest.mark.slow
def test_a_spilled_recording_gives_the_same_results_and_leaves_nothing(tmp_path, monkeypatch):
    # With a zero threshold every run records into unlinked memory-mapped files in its folder
    # (a long run's memory does not grow with its length); the CSV must be byte-identical to
    # the in-memory recording and the folder must hold only the usual files.
    from orchestration.master.recorder import SPILL_ENV

    plan = load_scenario(SCENARIOS / "elcentro.yaml", ["simulation.stop_time=1"])
    in_memory = run(plan, out=tmp_path / "memory")
    monkeypatch.setenv(SPILL_ENV, "0")
    from orchestration.master.session import run_plan

    outcome = run_plan(plan, tmp_path / "spilled", plots=False)
    assert isinstance(outcome.recorder.data, np.memmap) and outcome.recorder.spilled
    assert outcome.result.complete
    assert (tmp_path / "spilled" / "timeseries.csv").read_bytes() == (in_memory.folder / "timeseries.csv").read_bytes()
    assert sorted(p.name for p in (tmp_path / "spilled").iterdir()) == [
        ".mre-cosim-run", "manifest.json", "summary.json", "timeseries.csv"]


def test_the_engine_alone_refuses_the_buildings_report_keys_with_file_and_line():
    # Without the application's report hook the engine knows only caption and labels: every
    # role of scenarios/isolated_building.yaml is an unknown key at its own line of that file.
    from dataclasses import replace

    from orchestration.engine_hooks import HOOKS
    from orchestration.master.resolve import resolve
    from orchestration.master.scenario import load_scenario as load_file

    base = SCENARIOS / "isolated_building.yaml"
    roles = ["ground_acceleration", "base_displacement", "drifts", "floor_accelerations", "current",
             "isolator_force", "displacement_limits"]
    lines = base.read_text().splitlines()
    expected = {f"report.{role}": (str(base), next(n for n, text in enumerate(lines, 1)
                                                   if text.startswith(f"  {role}:"))) for role in roles}
    with pytest.raises(ScenarioError) as info:
        resolve(load_file(SCENARIOS / "kobe.yaml"), hooks=replace(HOOKS, report=None))  # FMUs built if needed
    found = {p.key: (p.file, p.line) for p in info.value.problems}
    assert found == expected
    assert all(p.message == "unknown key" for p in info.value.problems)


def test_a_misspelt_role_in_a_file_is_refused_with_its_line_and_a_suggestion(tmp_path):
    path = tmp_path / "typo.yaml"
    path.write_text(f"extends: {SCENARIOS / 'kobe.yaml'}\nreport:\n  drfits: [building.drift_1]\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    (problem,) = info.value.problems
    assert (problem.key, problem.file, problem.line) == ("report.drfits", str(path), 3)
    assert problem.message == "unknown key (did you mean 'drifts' or 'drift_unit'?)"


def test_the_engines_summary_is_every_variables_peak_and_a_hook_cannot_replace_its_keys():
    from types import SimpleNamespace

    from orchestration.master.report import ReportHook, report_summary
    from orchestration.master.scenario import ReportSpec

    data = np.array([[0.0, 5.0], [-3.0, 1.0], [2.0, 4.0]])
    rec = SimpleNamespace(names=["a.x", "a.s", "b.y"], kinds=["real", "string", "real"], count=3,
                          data=np.column_stack([data[:, 0], np.zeros(3), data[:, 1]]))
    hook = ReportHook(ReportSpec, summarize=lambda spec, rec, run: {"status": "mine", "variables": 0, "extra": 1})
    out = report_summary(rec, ReportSpec(), hook, RunDescription({}, {}), reserved={"status"})
    assert out == {"valid": True, "invalid_reasons": [], "extra": 1,
                   "variables": {"a.x": {"max_abs": 3.0, "min": -3.0, "max": 2.0},
                                 "b.y": {"max_abs": 5.0, "min": 1.0, "max": 5.0}}}
    assert report_summary(rec, ReportSpec(), None, RunDescription({}, {}))["variables"] == out["variables"]
