"""MRE_COSIM_* numbers: refused with the variable named (never ignored or turned into another number)."""

from __future__ import annotations

import zipfile

import pytest

from mre_common.env_settings import EnvSettingError, env_megabytes, env_switch
from orchestration import run as run_tool
from orchestration.engine_hooks import plan_scenario
from orchestration.master import safe_archive
from orchestration.master.errors import ScenarioError
from orchestration.master.recorder import SPILL_ENV, spill_threshold
from orchestration.master.resolve import ENGINE_SETTINGS, environment_problems
from orchestration.master.scenario import CSV_PROCESS_ENV, MEMORY_ENV, SimulationSpec, result_size_problem

from ..conftest import PROJECT

NAME = "MRE_COSIM_TEST_MB"
MEANINGLESS = ["abc", "nan", "NaN", "-1", "-0.5", "inf", "-inf", "1e300", "0x10", "1,5", "5 MB"]


@pytest.mark.parametrize("text", MEANINGLESS)
def test_a_value_that_means_nothing_is_refused_naming_the_variable(monkeypatch, text):
    monkeypatch.setenv(NAME, text)
    with pytest.raises(EnvSettingError, match=NAME) as err:
        env_megabytes(NAME, 256)
    assert repr(text) in str(err.value)


def test_zero_is_refused_unless_it_means_something(monkeypatch):
    monkeypatch.setenv(NAME, "0")
    with pytest.raises(EnvSettingError, match="more than 0"):
        env_megabytes(NAME, 256)
    assert env_megabytes(NAME, 256, zero_ok=True) == 0


@pytest.mark.parametrize(("text", "expected"), [("", 256 << 20), ("  ", 256 << 20), ("1", 1 << 20), (" 0.5 ", 1 << 19),
                                                ("1e3", 1000 << 20)])
def test_numbers_and_unset_values_are_read_in_mib(monkeypatch, text, expected):
    monkeypatch.setenv(NAME, text)
    assert env_megabytes(NAME, 256) == expected
    monkeypatch.delenv(NAME)
    assert env_megabytes(NAME, 256) == 256 << 20 and env_megabytes(NAME, None) is None


def test_the_archive_limit_is_read_when_an_archive_is_checked_not_at_import(monkeypatch, tmp_path):
    path = tmp_path / "a.zip"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("x.bin", bytes(3 << 20))  # 3 MiB unpacked
    monkeypatch.setenv(safe_archive.UNPACKED_ENV, "2")
    with zipfile.ZipFile(path) as z, pytest.raises(safe_archive.ArchiveError, match="more than the 2,097,152"):
        safe_archive.check_archive(z, path)
    monkeypatch.setenv(safe_archive.UNPACKED_ENV, "4")
    with zipfile.ZipFile(path) as z:
        assert safe_archive.check_archive(z, path) == 3 << 20
    monkeypatch.setenv(safe_archive.UNPACKED_ENV, "-1")
    with zipfile.ZipFile(path) as z, pytest.raises(safe_archive.ArchiveError, match=safe_archive.UNPACKED_ENV):
        safe_archive.check_archive(z, path)


def test_the_spill_threshold_takes_zero_as_always_spill(monkeypatch):
    monkeypatch.setenv(SPILL_ENV, "0")
    assert spill_threshold() == 0
    monkeypatch.setenv(SPILL_ENV, "abc")
    with pytest.raises(EnvSettingError, match=SPILL_ENV):
        spill_threshold()


def test_a_meaningless_result_budget_is_a_problem_not_a_negative_size(monkeypatch, tmp_path):
    sim = SimulationSpec(stop_time=1.0, step=0.001)
    monkeypatch.setenv(MEMORY_ENV, "-1")
    text = result_size_problem(sim, 3, tmp_path)
    assert MEMORY_ENV in text and "-1" in text and "-1.05e+06" not in text
    monkeypatch.setenv(MEMORY_ENV, "0.0009765625")  # 1 KiB: 1001 rows x 4 columns x 28 B = 112,112 B do not fit
    assert "up to 109 KiB on disk, more than 1 KiB" in result_size_problem(sim, 3, tmp_path)
    monkeypatch.setenv(MEMORY_ENV, "0.107")  # 112,197 B: just enough
    assert result_size_problem(sim, 3, tmp_path) is None


def test_every_engine_variable_is_checked_at_once(monkeypatch):
    for name, _, _ in ENGINE_SETTINGS:
        monkeypatch.setenv(name, "nan")
    problems = [p.message for p in environment_problems()]
    assert len(problems) == len(ENGINE_SETTINGS) == 3
    assert all(name in text for (name, _, _), text in zip(ENGINE_SETTINGS, problems, strict=True))


@pytest.mark.parametrize("name", [s[0] for s in ENGINE_SETTINGS])
def test_a_scenario_is_refused_before_anything_is_read(monkeypatch, name):
    monkeypatch.setenv(name, "abc")
    with pytest.raises(ScenarioError, match=name):
        plan_scenario(PROJECT / "scenarios" / "elcentro.yaml", ("simulation.stop_time=0.05",))


def test_run_py_exits_2_and_writes_nothing(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv(SPILL_ENV, "-3")
    out = tmp_path / "out"
    code = run_tool.main([str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "simulation.stop_time=0.05",
                          "--out", str(out), "--quiet", "--no-plots"])
    assert code == 2 and not out.exists()
    assert f"environment variable {SPILL_ENV}='-3'" in capsys.readouterr().err


@pytest.mark.parametrize("text", ["yes", "true", "2", "-1", "nan", "on"])
def test_an_on_off_switch_takes_only_0_or_1(monkeypatch, tmp_path, capsys, text):
    monkeypatch.setenv(CSV_PROCESS_ENV, text)
    with pytest.raises(EnvSettingError, match=CSV_PROCESS_ENV):
        env_switch(CSV_PROCESS_ENV, True)
    out = tmp_path / "out"
    code = run_tool.main([str(PROJECT / "scenarios" / "elcentro.yaml"), "--set", "simulation.stop_time=0.05",
                          "--out", str(out), "--quiet", "--no-plots"])
    assert code == 2 and not out.exists()
    assert f"environment variable {CSV_PROCESS_ENV}={text!r}" in capsys.readouterr().err


@pytest.mark.parametrize(("text", "expected"), [("", True), (" 1 ", True), ("0", False)])
def test_an_on_off_switch_reads_0_and_1(monkeypatch, text, expected):
    monkeypatch.setenv(CSV_PROCESS_ENV, text)
    assert env_switch(CSV_PROCESS_ENV, True) is expected
