"""The strategy tuner (orchestration/case_study/strategy_tuner.py): ranges, budget, optimiser, bad input.

The quick tests need no FMU run: the range mapping round-trips, the optimiser finds the known minimum of a shifted
quadratic and of a Rosenbrock valley over log and linear ranges within stated tolerances for a stated budget, and
every bad input (a range empty, inverted, not finite, log through zero; a parameter the FMU lacks; a budget below
the parameters + 1) is a ScenarioError naming its key and line, exit 2 through tune.py. The slow test tunes the
on-off law on 1 s of El Centro with a budget of 6 and runs the tuned entry it wrote.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from orchestration.building_studies.strategies import TunableRange, read_strategy_file
from orchestration.case_study import strategy_tuner as st
from orchestration.case_study.case_config import load_study
from orchestration.engine_hooks import PROJECT_DIR as PROJECT
from orchestration.master.errors import ScenarioError

SCENARIOS = PROJECT / "scenarios"
LOG = TunableRange(low=1e-6, high=1e-2, scale="log")
LIN = TunableRange(low=-5.0, high=5.0)


def test_range_mapping_round_trips() -> None:
    for rng in (LOG, LIN, TunableRange(low=0.0, high=1.0), TunableRange(low=0.05, high=20.0, scale="log")):
        assert st.to_value(0.0, rng) == rng.low and st.to_value(1.0, rng) == rng.high  # the ends exactly
        for u in np.linspace(0.0, 1.0, 11):
            assert st.to_unit(st.to_value(u, rng), rng) == pytest.approx(u, abs=1e-12)
    assert st.to_value(0.5, LOG) == pytest.approx(1e-4)  # geometric middle
    assert st.to_value(0.5, LIN) == 0.0
    assert st.to_value(-1.0, LIN) == -5.0 and st.to_value(2.0, LIN) == 5.0  # clipped to the cube
    assert st.parameter_values([0.5, 0.25], {"w": TunableRange(low=500, high=8000, scale="log"), "x": LIN},
                               frozenset({"w"})) == {"w": 2000, "x": -2.5}


def test_budget_check_and_population() -> None:
    assert st.budget_problem(3, 3) is not None and "at least 4" in st.budget_problem(3, 3)
    assert st.budget_problem(3, 4) is None
    for n in (1, 2, 3, 4):
        for budget in range(n + 1, 120):
            p = st.population_size(n, budget)
            assert n + 1 <= p <= budget
    assert st.population_size(2, 40) == 8 and st.population_size(4, 40) == 8  # five generations of 8
    with pytest.raises(ValueError, match="at least 3"):
        st.optimise(lambda pts: [0.0] * len(pts), 2, 2, 1)


def _quadratic(points: np.ndarray) -> list[float]:
    """Minimum 0 at a = 3e-4 (log range LOG) and b = 1.7 (linear range LIN)."""
    ranges = {"a": LOG, "b": LIN}
    out = []
    for q in points:
        v = st.parameter_values(q, ranges)
        out.append((math.log10(v["a"]) - math.log10(3e-4)) ** 2 + (v["b"] - 1.7) ** 2)
    return out


def test_finds_a_shifted_quadratic_in_log_and_linear_ranges() -> None:
    """Budget 200 (population 20, 9 generations): within 2 % of a in log10 and 0.05 of b."""
    found = st.optimise(_quadratic, 2, 200, seed=1)
    assert len(found.points) <= 200 and found.population == 20 and found.generations == 9
    v = st.parameter_values(found.best, {"a": LOG, "b": LIN})
    assert abs(math.log10(v["a"]) - math.log10(3e-4)) < 0.02 and abs(v["b"] - 1.7) < 0.05
    again = st.optimise(_quadratic, 2, 200, seed=1)
    assert again.value == found.value and np.array_equal(again.best, found.best)  # deterministic for a seed


def test_finds_the_rosenbrock_minimum() -> None:
    """Rosenbrock (1 - x)^2 + 100 (y - x^2)^2 with x on a linear range [-2, 2] and y = log10 of a log range
    [1e-2, 1e2] (minimum at x = 1, y = 1): budget 600 (population 20, 29 generations), J < 1e-2, within 0.1."""
    ranges = {"x": TunableRange(low=-2.0, high=2.0), "y": TunableRange(low=1e-2, high=1e2, scale="log")}

    def rosenbrock(points: np.ndarray) -> list[float]:
        vals = [st.parameter_values(q, ranges) for q in points]
        return [(1 - v["x"]) ** 2 + 100 * (math.log10(v["y"]) - v["x"] ** 2) ** 2 for v in vals]

    found = st.optimise(rosenbrock, 2, 600, seed=1)
    v = st.parameter_values(found.best, ranges)
    assert found.value < 1e-2 and abs(v["x"] - 1) < 0.1 and abs(math.log10(v["y"]) - 1) < 0.2


def test_the_start_point_is_tried_first_and_a_small_budget_is_kept() -> None:
    calls: list[int] = []

    def f(points: np.ndarray) -> list[float]:
        calls.append(len(points))
        return _quadratic(points)

    start = [st.to_unit(3e-4, LOG), st.to_unit(1.7, LIN)]
    found = st.optimise(f, 2, 4, seed=3, start=start)  # below 5: the Latin hypercube only
    assert calls == [4] and found.value == pytest.approx(0.0, abs=1e-20) and found.generations == 0
    assert np.allclose(found.points[0], start)


# -- bad input ----------------------------------------------------------------------------------------------------
def _files(tmp_path: Path, tunable: str, budget: int = 10) -> Path:
    (tmp_path / "mine.yaml").write_text(
        "strategies:\n"
        "  onoff:\n"
        f"    fmu: {PROJECT / 'fmus' / 'SwitchingCurrentController.fmu'}\n"
        "    parameters: {i_high: 3.0, i_low: 0.0}\n"
        f"    tunable: {tunable}\n")
    study = tmp_path / "study.yaml"
    study.write_text(f"records: {{elcentro: {SCENARIOS / 'elcentro.yaml'}}}\nreference: {{enabled: false}}\n"
                     "strategy_files: [mine.yaml]\nstrategies: [passive-off, onoff]\n"
                     f"strategy_tuning:\n  strategies: [onoff]\n  stop_time: 1.0\n  budget: {budget}\n")
    return study


@pytest.mark.parametrize(("tunable", "words"), [
    ("{i_high: {low: 2.0, high: 2.0}}", "empty"),
    ("{i_high: {low: 3.0, high: 1.0}}", "inverted"),
    ("{i_high: {low: 1.0, high: .inf}}", "finite"),
    ("{i_high: {low: .nan, high: 2.0}}", "finite"),
    ("{i_high: {low: 0.0, high: 3.0, scale: log}}", "above 0"),
    ("{i_high: {low: -1.0, high: 3.0, scale: log}}", "above 0"),
])
def test_a_bad_range_names_its_key_and_line(tmp_path: Path, tunable: str, words: str) -> None:
    study = _files(tmp_path, tunable)
    with pytest.raises(ScenarioError) as err:
        read_strategy_file(tmp_path / "mine.yaml")
    (p,) = err.value.problems
    assert p.key == "strategies.onoff.tunable.i_high" and p.line == 5 and words in p.message
    with pytest.raises(ScenarioError):
        load_study(study)


def test_a_parameter_the_fmu_lacks_names_its_key_and_line(tmp_path: Path) -> None:
    study = load_study(_files(tmp_path, "{i_high: {low: 1.0, high: 3.0}, R_weight: {low: 1e-6, high: 1e-2}}"))
    with pytest.raises(ScenarioError) as err:
        st.plan_targets(study)
    (p,) = [q for q in err.value.problems if "R_weight" in q.message]
    assert p.key == "strategies.onoff.tunable.R_weight" and p.line == 5 and p.file == str(tmp_path / "mine.yaml")
    assert "SwitchingCurrentController has no variable 'R_weight'" in p.message


def test_an_output_is_not_tunable(tmp_path: Path) -> None:
    study = load_study(_files(tmp_path, "{i: {low: 1.0, high: 3.0}}"))
    with pytest.raises(ScenarioError, match=r"not a numeric .* parameter"):
        st.plan_targets(study)


def test_a_budget_below_the_parameters_plus_one(tmp_path: Path) -> None:
    study = load_study(_files(tmp_path, "{i_high: {low: 1.0, high: 3.0}, i_low: {low: 0.0, high: 1.0}}", budget=2))
    with pytest.raises(ScenarioError) as err:
        st.plan_targets(study)
    (p,) = err.value.problems
    assert p.key == "strategy_tuning.budget" and p.line == 8 and "at least 3 (the parameters + 1)" in p.message


def test_a_strategy_without_tunable_and_an_unknown_one(tmp_path: Path) -> None:
    path = _files(tmp_path, "{i_high: {low: 1.0, high: 3.0}}")
    with pytest.raises(ScenarioError, match="declares no tunable"):
        st.plan_targets(load_study(path, ("strategy_tuning.strategies=[passive-on]",)))
    with pytest.raises(ScenarioError) as err:
        load_study(path, ("strategy_tuning.strategies=[nope]",))
    assert err.value.problems[0].key == "strategy_tuning.strategies.0"


def test_tune_py_exits_2_and_picks_its_tuner(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from orchestration.tune import main

    study = _files(tmp_path, "{i_high: {low: 1.0, high: 3.0}, i_low: {low: 0.0, high: 1.0}}", budget=2)
    assert st.declares_tuning([str(study)]) and not st.declares_tuning([str(SCENARIOS / "case_study.yaml")])
    assert st.declares_tuning([str(SCENARIOS / "case_study.yaml"), "--set", "strategy_tuning.strategies=[sosm]"])
    assert main([str(study), "--out", str(tmp_path / "t.yaml")]) == 2
    err = capsys.readouterr().err
    assert "strategy_tuning.budget" in err and f"{study}:8" in err
    assert not (tmp_path / "t.yaml").exists()


def test_the_shipped_ranges_fit_their_fmus() -> None:
    study = load_study(SCENARIOS / "strategy_tuning.yaml")
    library = study.library
    for name in study.spec.strategy_tuning.strategies:  # type: ignore[union-attr]
        assert library[name].entry.tunable, name
    from orchestration.building_studies.strategies import tunable_problems

    assert [p for s in library.values() for p in tunable_problems(s)] == []


@pytest.mark.slow
def test_tune_on_off_briefly_and_run_the_tuned_entry(tmp_path: Path) -> None:
    from orchestration.tune import main

    study = _files(tmp_path, "{i_high: {low: 1.0, high: 3.0}, i_low: {low: 0.0, high: 1.0}}", budget=6)
    out = tmp_path / "tuned.yaml"
    assert main([str(study), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    tuned = read_strategy_file(out)
    entry = tuned["onoff-tuned"].entry
    assert entry.tuned is not None and entry.tuned["budget"] == 6 and entry.tuned["seed"] == 1
    assert entry.tuned["records"] == ["elcentro"] and entry.tuned["evaluations"] <= 6
    assert math.isfinite(entry.tuned["J"]) and entry.tuned["J"] <= entry.tuned["J_start"]
    assert 1.0 <= entry.parameters["i_high"] <= 3.0 and 0.0 <= entry.parameters["i_low"] <= 1.0
    from orchestration.engine_hooks import plan_scenario
    from orchestration.master.session import run_plan

    overrides = (*tuned["onoff-tuned"].overrides(3.0, None, None), "simulation.stop_time=0.5")
    plan = plan_scenario(SCENARIOS / "elcentro.yaml", overrides)
    assert plan.parameters["controller"]["i_high"] == entry.parameters["i_high"]
    assert run_plan(plan, tmp_path / "run", plots=False, progress=False).result.complete


def test_a_tuned_file_records_paths_below_the_current_folder_relative(tmp_path: Path, monkeypatch) -> None:
    """What a checkout run from its root ships (``scenarios/...``) is the same on every machine; a path elsewhere
    stays absolute, so the record still finds it."""
    from orchestration.case_study.strategy_tuner import shown_path

    (tmp_path / "project" / "scenarios").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "project")
    assert shown_path(tmp_path / "project" / "scenarios" / "a.yaml") == "scenarios/a.yaml"
    assert shown_path("scenarios/../scenarios/a.yaml") == "scenarios/a.yaml"
    assert shown_path(tmp_path / "elsewhere.yaml") == str((tmp_path / "elsewhere.yaml").resolve())
