"""What a study does with a strategy is said by its entry, never by its name (scenarios/strategies.yaml).

``uncontrolled`` (the indices' baseline), ``radau_reference`` (checked against Radau), ``paper_figures`` (Fig. 15,
16, the claims), ``${best_current}`` (needs the sweep) and ``style``. The slow test renames every strategy of a
small case study and expects the same numbers under the new names: the independent expectation is the study with
the shipped names.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from orchestration.building_studies.strategies import builtin_strategies, read_strategy_file
from orchestration.case_study.case_config import load_study
from orchestration.engine_hooks import PROJECT_DIR as PROJECT
from orchestration.master.errors import ScenarioError

SCENARIOS = PROJECT / "scenarios"
CLI = [sys.executable, str(PROJECT / "orchestration" / "study.py")]


def _study(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "study.yaml"
    p.write_text(f"records: {{elcentro: {SCENARIOS / 'elcentro.yaml'}}}\nreference: {{enabled: false}}\n" + text)
    return p


def _problems(path: Path) -> str:
    with pytest.raises(ScenarioError) as err:
        load_study(path)
    return err.value.report()


def test_the_shipped_flags() -> None:
    shipped = builtin_strategies()
    assert [n for n, s in shipped.items() if s.entry.uncontrolled] == ["passive-off"]
    assert [n for n, s in shipped.items() if s.entry.radau_reference] == ["passive-off", "passive-on"]
    assert [n for n, s in shipped.items() if s.needs_sweep] == ["best-constant"]
    assert {n: s.entry.paper_figures for n, s in shipped.items() if s.entry.paper_figures} == {
        "passive-on": "passive", "sosm": "controlled", "sosm-fig15": "controlled"}
    assert all(s.entry.style is not None for s in shipped.values())


def test_a_study_needs_exactly_one_uncontrolled_strategy(tmp_path: Path) -> None:
    report = _problems(_study(tmp_path, "strategies: [passive-on, sosm]\n"))
    assert "study.yaml:3: strategies" in report and "none is marked uncontrolled" in report
    two = _study(tmp_path, "strategies: [passive-off, zero]\nstrategy_definitions:\n"
                           "  zero: {parameters: {mode: passive, i_passive: 0.0}, uncontrolled: true}\n")
    assert "several are marked uncontrolled (passive-off, zero)" in _problems(two)


def test_a_strategy_that_takes_the_best_current_brings_the_sweep(tmp_path: Path) -> None:
    """``${best_current}`` in any listed entry runs the sweep (a study without best-constant was refused before)."""
    from orchestration.case_study.case_run import count_jobs

    text = "strategy_definitions:\n  x: {parameters: {mode: passive, i_passive: '${best_current}'}}\n"
    with_x = load_study(_study(tmp_path, "strategies: [passive-off, x]\n" + text))
    without = load_study(_study(tmp_path, "strategies: [passive-off, passive-on]\n" + text))
    assert with_x.needs_sweep and not without.needs_sweep
    assert count_jobs(with_x, verify=False) == count_jobs(without, verify=False) + 1  # the one record's sweep


def test_a_radau_reference_needs_a_constant_current(tmp_path: Path) -> None:
    path = _study(tmp_path, "strategies: [passive-off, mine]\nstrategy_definitions:\n"
                            "  mine: {parameters: {mode: sosm}, radau_reference: true}\n")
    report = _problems(path)
    assert "strategies.1" in report and "'mine' is marked radau_reference" in report


@pytest.mark.parametrize(("style", "says"), [
    ("{color: not-a-colour}", "is not a matplotlib colour"),
    ("{line: '~~'}", "line must be one of"),
    ("{line: [1, 2, 3]}", "dashes are pairs of positive"),
    ("{line: [1, -2]}", "dashes are pairs of positive"),
    ("{marker: '$x$'}", "marker must be one of"),
    ("{colour: red}", "colour"),
])
def test_a_bad_style_is_refused_at_its_line(tmp_path: Path, style: str, says: str) -> None:
    f = tmp_path / "mine.yaml"
    f.write_text(f"strategies:\n  mine:\n    parameters: {{mode: passive, i_passive: 1.0}}\n    style: {style}\n")
    with pytest.raises(ScenarioError) as err:
        read_strategy_file(f)
    assert says in err.value.report() and "mine.yaml:4" in err.value.report()


def test_an_unknown_j6_reference_is_refused(tmp_path: Path) -> None:
    path = _study(tmp_path, "strategies: [passive-off, passive-on]\nbenchmark: {j6_reference: passive-of}\n")
    assert "benchmark.j6_reference" in _problems(path) and "unknown strategy 'passive-of'" in _problems(path)


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_renamed_strategies_give_the_same_study(tmp_path: Path) -> None:
    """The shipped passive-off, passive-on, best-constant and sosm copied under other names (their flags with
    them): the same peaks, indices, sweep and Radau references, under the new names; Fig. 15 and 16 drawn."""
    shipped = builtin_strategies()
    names = {"passive-off": "zero-amps", "passive-on": "full-amps", "best-constant": "hindsight", "sosm": "paper-law"}
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml_entries({new: shipped[old].entry.model_dump(exclude_defaults=True)
                                  for old, new in names.items()}))
    common = ["--set", "overrides=[simulation.stop_time=2]", "--set", "records={elcentro: elcentro.yaml}",
              "--set", "sweep={start: 0.0, step: 1.0}", "--quiet", "--verify"]
    for folder, strategies, extra in (("old", list(names), []),
                                      ("new", list(names.values()), ["--set", f"strategy_files=[{mine}]"])):
        done = subprocess.run([*CLI, str(SCENARIOS / "case_study.yaml"), *common, *extra,
                               "--set", f"strategies=[{', '.join(strategies)}]", "--out", str(tmp_path / folder)],
                              capture_output=True, text=True, timeout=600, cwd=SCENARIOS)
        assert done.returncode == 0, done.stderr
    for table in ("peaks.csv", "indices.csv", "reference.csv"):
        old, new = _rows(tmp_path / "old" / table), _rows(tmp_path / "new" / table)
        assert [{**r, "strategy": names[r["strategy"]]} for r in old] == new, table
    assert _rows(tmp_path / "old" / "sweep.csv") == _rows(tmp_path / "new" / "sweep.csv")
    doc = json.loads((tmp_path / "new" / "study.json").read_text())
    assert doc["strategy_flags"]["zero-amps"]["uncontrolled"] is True
    report = (tmp_path / "new" / "report.md").read_text()
    assert "**paper-law** vs **hindsight" in report and "Ratios are SOSM / zero-amps" in report
    for fig in ("fig15_current", "fig16_top_acceleration"):
        assert (tmp_path / "new" / "figures" / f"{fig}.png").stat().st_size > 0


def yaml_entries(entries: dict) -> str:
    import yaml

    return yaml.safe_dump({"description": "the shipped entries under other names", "strategies": entries})
