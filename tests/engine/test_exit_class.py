"""Exit classes: a problem known before the first step is exit 2 with nothing written (the native executor on a
system it cannot run, a value outside a variable's declared min/max, a !data record that cannot be read); an
incomplete folder is said to be marked only when it is; Ctrl-C handling is installed before any other import."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import zipfile

import pytest

from orchestration import run as run_tool
from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import ScenarioError
from orchestration.master.resolve import resolve
from orchestration.master.scenario import load_scenario

from ..conftest import PROJECT
from ..support.typed_build import build_typed2

ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"
SHORT = "simulation.stop_time=0.05"


def _run(tmp_path, *sets: str) -> tuple[int, str]:
    argv = [str(ELCENTRO), "--set", SHORT, *[a for s in sets for a in ("--set", s)], "--out", str(tmp_path / "out"),
            "--quiet", "--no-plots"]
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), *argv], capture_output=True,
                          text=True, cwd=tmp_path, timeout=300)
    return proc.returncode, proc.stderr


def _bounded_isolator(tmp_path):
    """The isolator with declared bounds: n_isolators in [1, 8], i_max in [0, 5] A."""
    src, dest = PROJECT / "fmus" / "MreIsolator.fmu", tmp_path / "bounded.fmu"

    def edit(text: str) -> str:
        text = re.sub(r'(name="n_isolators"[^>]*>\s*<Integer) ', r'\1 min="1" max="8" ', text, count=1)
        return re.sub(r'(name="i_max"[^>]*>\s*<Real) ', r'\1 min="0" max="5" ', text, count=1)

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = zin.read(info)
            zout.writestr(info, edit(data.decode()).encode() if info.filename == "modelDescription.xml" else data)
    return dest


@pytest.mark.parametrize(("setting", "message"), [
    ("isolator.n_isolators=9", "n_isolators = 9 is outside its declared range [1, 8]"),
    ("isolator.n_isolators=0", "n_isolators = 0 is outside its declared range [1, 8]"),
    ("isolator.i_max=5.5", "i_max = 5.5 is outside its declared range [0, 5] A"),
    ("isolator.i_max=-0.1", "i_max = -0.1 is outside its declared range [0, 5] A"),
])
def test_a_value_outside_a_declared_range_is_a_scenario_error(tmp_path, setting, message):
    fmu = _bounded_isolator(tmp_path)
    with pytest.raises(ScenarioError, match=re.escape(message)):
        plan_scenario(ELCENTRO, (SHORT, f"units.isolator.fmu={fmu}", setting))
    plan = plan_scenario(ELCENTRO, (SHORT, f"units.isolator.fmu={fmu}", "isolator.n_isolators=8", "isolator.i_max=5"))
    assert plan.descriptions["isolator"].variables["i_max"].max_value == 5.0
    assert plan.parameters["isolator"]["n_isolators"] == 8


def test_the_native_executor_on_a_system_it_cannot_run_is_refused_before_the_run(tmp_path):
    fmu = build_typed2(tmp_path)
    path = tmp_path / "typed.yaml"
    path.write_text(f"name: typed\nunits:\n  a:\n    fmu: {fmu}\nconnections: []\noutputs: all\n"
                    f"simulation: {{step: 0.1, stop_time: 0.5, executor: native}}\nresults: {{dir: {tmp_path}/r}}\n")
    with pytest.raises(ScenarioError) as err:
        resolve(load_scenario(path))
    assert "simulation.executor" in str(err.value) and "not Real" in str(err.value)
    assert not (tmp_path / "r").exists()
    path.write_text(path.read_text().replace("executor: native", "executor: auto"))
    assert resolve(load_scenario(path)).loaded.scenario.simulation.executor == "auto"  # auto falls back instead


def test_a_data_file_given_as_the_record_is_checked_as_a_record(tmp_path):
    bad = tmp_path / "g.csv"
    bad.write_text("garbage\n")
    code, err = _run(tmp_path, f"ground.record=!data {bad}")
    assert code == 2 and "unreadable record" in err and str(bad) in err
    assert not (tmp_path / "out").exists()


def test_an_unmarked_folder_is_not_called_marked(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps({"complete": False}))
    assert run_tool.results_note(tmp_path) == "partial results (marked incomplete)"
    (tmp_path / "summary.json").unlink()
    assert "NOT marked incomplete" in run_tool.results_note(tmp_path)
    (tmp_path / "manifest.json").write_text(json.dumps({"complete": False}))
    assert run_tool.results_note(tmp_path) == "partial results (marked incomplete)"


@pytest.mark.parametrize("tool", ["run.py", "ssp.py", "study.py", "ida.py", "tune.py", "identify.py"])
def test_ctrl_c_handling_is_installed_before_any_other_import(tool):
    """The guard is imported first (standard library only), before argparse and the project's modules."""
    proc = subprocess.run([sys.executable, "-X", "importtime", str(PROJECT / "orchestration" / tool), "--help"],
                          capture_output=True, text=True, timeout=120)
    names = [line.rsplit("|", 1)[-1].strip() for line in proc.stderr.splitlines() if line.startswith("import time:")]
    guard = names.index("mre_common.guard")
    late = [n for n in names[guard + 1:] if n in ("argparse", "orchestration.cli", "logging", "numpy")]
    assert late, names[guard:]
    assert not [n for n in names[:guard] if n in ("argparse", "orchestration.cli", "logging", "numpy", "yaml")]


def test_a_plain_string_record_path_is_checked_where_the_unit_will_open_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "garbage.csv").write_text("no numbers here\n")
    (tmp_path / "folder.csv").mkdir()
    for value, message in (("nowhere.csv", f"no {tmp_path / 'nowhere.csv'}"),
                           ("garbage.csv", "unreadable record"), ("folder.csv", "is a folder, not a regular file")):
        with pytest.raises(ScenarioError, match=re.escape(message)):
            plan_scenario(ELCENTRO, (SHORT, f"ground.record={value}"))
    from ..conftest import shipped_record

    (tmp_path / "ok.csv").write_bytes(shipped_record("elcentro_1940_ns.csv").read_bytes())
    assert plan_scenario(ELCENTRO, (SHORT, "ground.record=ok.csv")).parameters["ground"]["record"] == "ok.csv"
