"""Strategies as entries of a strategy file (scenarios/strategies.yaml): parsed, turned into runs, refused by line.

The slow test runs a tiny controller benchmark end to end (two records, three strategies, 2 s).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from orchestration.building_studies.strategies import (
    SHIPPED,
    builtin_strategies,
    read_strategy_file,
    strategy_overrides,
)
from orchestration.case_study.case_config import load_study
from orchestration.case_study.case_plan import prepare
from orchestration.engine_hooks import PROJECT_DIR as PROJECT
from orchestration.master.errors import ScenarioError

SCENARIOS = PROJECT / "scenarios"
GAINS = {"lambda": 1.5, "rho": 2.5, "zeta": 3.5, "theta": 4.5, "i_max": 2.5, "s_release": 0.01}


def _study(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "study.yaml"
    p.write_text(f"records: {{elcentro: {SCENARIOS / 'elcentro.yaml'}}}\nreference: {{enabled: false}}\n" + text)
    return p


def test_shipped_names() -> None:
    assert list(builtin_strategies()) == ["passive-off", "passive-on", "best-constant", "sosm", "sosm-fig15", "on-off",
                                          "clipped-optimal", "clipped-optimal-inverse", "lyapunov", "frequency"]


def test_builtin_overrides_are_the_hard_coded_ones_of_before() -> None:
    """The overrides the strategies were hard-coded to before they became entries (commit 2f29943)."""
    assert strategy_overrides("passive-off", 3.0, None, None) == ("controller.mode=passive", "controller.i_passive=0.0")
    assert strategy_overrides("passive-on", 3.0, None, None) == ("controller.mode=passive", "controller.i_passive=3.0")
    assert strategy_overrides("best-constant", 3.0, None, 1.25) == ("controller.mode=passive",
                                                                     "controller.i_passive=1.25")
    assert strategy_overrides("sosm", 3.0, GAINS, None) == (
        "controller.mode=sosm", "controller.lambda=1.5", "controller.rho=2.5", "controller.zeta=3.5",
        "controller.theta=4.5", "controller.s_release=0.01")
    assert strategy_overrides("sosm-fig15", 3.0, GAINS, None) == (
        "controller.mode=sosm", "controller.lambda=1.5", "controller.rho=2.5", "controller.zeta=3.5",
        "controller.theta=4.5", "controller.i_max=2.5", "controller.s_release=0.01")
    assert strategy_overrides("on-off", 3.0, None, None) == (
        f"units.controller.fmu={PROJECT / 'fmus' / 'SwitchingCurrentController.fmu'}", "controller.i_high=3.0",
        "controller.i_low=0.0")


def test_connections_replace_those_into_the_controller() -> None:
    lyap = builtin_strategies()["lyapunov"]
    scenario = ["ground.ag -> building.ag", "controller.i -> isolator.i",
                {"source": "building.arel_0", "target": "controller.a", "delayed": True}]
    conns = lyap.connections(scenario)
    assert conns[:2] == scenario[:2]  # the controller's output stays, its old sensor is gone
    assert [c["target"] for c in conns[2:]] == ["controller.x", "controller.v", "controller.a_0", "controller.a_1",
                                                "controller.a_2", "controller.a_3", "controller.F"]
    assert builtin_strategies()["sosm"].connections(scenario) is None  # no connections: the scenario's stay
    assert lyap.overrides(3.0, None, None) == (
        f"units.controller.fmu={PROJECT / 'fmus' / 'LyapunovCurrentController.fmu'}", "controller.i_max=3.0")
    assert builtin_strategies()["clipped-optimal-inverse"].overrides(2.0, None, None)[1:] == (
        "controller.law=inverse", "controller.i_max=2.0")


def test_unknown_strategy_is_named_with_its_line(tmp_path: Path) -> None:
    p = _study(tmp_path, "strategies:\n  - passive-off\n  - lqr\n")
    with pytest.raises(ScenarioError) as exc:
        load_study(p)
    (problem,) = exc.value.problems
    assert (problem.key, problem.file, problem.line) == ("strategies.1", str(p), 5)
    assert "unknown strategy 'lqr'" in problem.message


def test_malformed_entry_and_missing_strategy_file(tmp_path: Path) -> None:
    bad = tmp_path / "mine.yaml"
    bad.write_text(f"extends: {SHIPPED}\nstrategies:\n  mine:\n    fmu: X.fmu\n    paramters: {{a: 1}}\n")
    with pytest.raises(ScenarioError) as exc:
        read_strategy_file(bad)
    (problem,) = exc.value.problems
    assert (problem.key, problem.line) == ("strategies.mine.paramters", 5)
    study = _study(tmp_path, "strategies: [passive-off]\nstrategy_files: [nowhere.yaml]\n")
    with pytest.raises(ScenarioError, match=r"strategy file .*nowhere\.yaml does not exist"):
        load_study(study)


def test_study_strategy_file_extends_the_shipped_one(tmp_path: Path) -> None:
    mine = tmp_path / "mine.yaml"
    mine.write_text(f"extends: {SHIPPED}\nstrategies:\n  lyapunov:\n    parameters: {{i_max: 2.0}}\n"
                    "  mine:\n    fmu: X.fmu\n")
    study = load_study(_study(tmp_path, "strategies: [passive-off, lyapunov, mine]\nstrategy_files: [mine.yaml]\n"))
    assert study.strategy("lyapunov").entry.parameters == {"i_max": 2.0}  # merged over the shipped entry
    assert study.strategy("lyapunov").entry.fmu == "../fmus/LyapunovCurrentController.fmu"
    assert study.strategy("mine").fmu_path == tmp_path / "X.fmu"


def test_missing_fmu_and_missing_variable_refused_at_their_lines(tmp_path: Path) -> None:
    p = _study(tmp_path, """strategies: [passive-off, my-lyapunov, no-fmu]
strategy_definitions:
  my-lyapunov:
    fmu: ../fmus/LyapunovCurrentController.fmu
    parameters: {i_max: "${i_max}"}
    connections:
      - {source: building.x_0, target: controller.x, delayed: true}
      - {source: building.a_3, target: controller.a_9, delayed: true}
  no-fmu:
    fmu: nowhere/Mine.fmu
""".replace("../fmus", str(PROJECT / "fmus")))
    with pytest.raises(ScenarioError) as exc:
        prepare(load_study(p, ("overrides=[simulation.stop_time=0.01]",)))
    problems = {pr.key: pr for pr in exc.value.problems}
    conn = problems["strategy_definitions.my-lyapunov.connections[1]"]
    assert (conn.file, conn.line) == (str(p), 10) and "no variable 'a_9'" in conn.message
    fmu = problems["strategy_definitions.no-fmu.fmu"]
    assert (fmu.file, fmu.line) == (str(p), 12) and "does not exist" in fmu.message


def test_cli_exit_2_names_the_strategy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from orchestration.study import main

    p = _study(tmp_path, "strategies: [passive-off, nope]\n")
    assert main([str(p), "--out", str(tmp_path / "out")]) == 2
    assert "strategies.1: unknown strategy 'nope'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_tiny_benchmark_end_to_end(tmp_path: Path) -> None:
    """Two records, three strategies, 2 s: criteria.csv against peaks.csv's peaks, the report's verdicts."""
    from orchestration.study import main

    out = tmp_path / "bench"
    code = main([str(SCENARIOS / "controller_benchmark.yaml"), "--out", str(out), "--quiet", "--workers", "2",
                 "--set", "overrides=[simulation.stop_time=2]",
                 "--set", "records={elcentro: elcentro.yaml, kobe: kobe.yaml}",
                 "--set", "strategies=[passive-off, best-constant, lyapunov]"])
    assert code == 0
    with open(out / "criteria.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0])[:14] == ["record", "strategy", *(f"J{k}" for k in range(1, 10)), "mean_current_A",
                                  "joule_A2s", "switching_rate_A_s"]  # then the criteria's extra columns, if any
    assert {(r["record"], r["strategy"]) for r in rows} == {(r, s) for r in ("elcentro", "kobe")
                                                           for s in ("passive-off", "best-constant", "lyapunov")}
    with open(out / "peaks.csv") as f:
        peaks = {(r["record"], r["strategy"]): r for r in csv.DictReader(f)}
    for r in rows:
        key, off = (r["record"], r["strategy"]), (r["record"], "passive-off")
        assert float(r["J3"]) == pytest.approx(float(peaks[key]["x_base_mm"]) / float(peaks[off]["x_base_mm"]),
                                               rel=1e-9)
        j5 = max(float(peaks[key][f"acc_{j}"]) for j in (1, 2, 3)) / max(float(peaks[off][f"acc_{j}"])
                                                                          for j in (1, 2, 3))
        assert float(r["J5"]) == pytest.approx(j5, rel=1e-9)
        assert math.isfinite(float(r["J9"]))
        if r["strategy"] == "passive-off":
            assert all(float(r[f"J{k}"]) == 1.0 for k in (1, 2, 3, 4, 5, 7, 8, 9))
            assert math.isnan(float(r["J6"]))  # J6 is over passive-on's, which this study does not run
            assert float(r["mean_current_A"]) == 0.0 and float(r["switching_rate_A_s"]) == 0.0
        if r["strategy"] == "best-constant":
            assert float(r["switching_rate_A_s"]) == 0.0 and 0.0 <= float(r["mean_current_A"]) <= 3.0
    html = (out / "report.html").read_text()
    assert "beats the best constant current on" in html and "Ranking per record" in html
    assert (out / "figures" / "benchmark_pareto_J3_J5.png").is_file()
