"""Nothing escapes its folder, nothing untrusted runs: names, caches, scripts, the CSV process, units, JSON.

Each test builds the hostile input itself and checks the outcome against what the docs promise
(docs/reliability.md): refused before anything is written and naming the key, a cache entry not
what it should be made again with a note naming the cache, a script that ends or moves the
process refused by a check in a child process, a stuck CSV process a bounded error.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parents[2]
SCENARIOS = PROJECT / "scenarios"


# -- names that become paths ---------------------------------------------------------------------------------------

def test_an_out_or_a_name_beyond_the_file_systems_limits_is_refused_before_anything_is_written(tmp_path):
    from orchestration.master.runfolder import RunFolderUnusable, new_run_folder

    with pytest.raises(RunFolderUnusable, match=r"--out .*300 bytes.*255 bytes per name"):
        new_run_folder(tmp_path, "x", tmp_path / ("a" * 300) / "run")
    deep = tmp_path.joinpath(*["b" * 200] * 25)
    with pytest.raises(RunFolderUnusable, match="bytes per path"):
        new_run_folder(tmp_path, "x", deep)
    with pytest.raises(RunFolderUnusable, match="run folder name"):
        new_run_folder(tmp_path / "runs", "é" * 120)  # 240 bytes + the time stamp
    assert sorted(tmp_path.iterdir()) == []


def test_a_run_folder_is_resolved_when_it_is_made_so_a_later_chdir_cannot_move_it(tmp_path, monkeypatch):
    from orchestration.master.runfolder import new_run_folder

    monkeypatch.chdir(tmp_path)
    folder = new_run_folder(Path("runs"), "x", Path("out"))
    assert folder.is_absolute() and folder == tmp_path / "out"
    assert new_run_folder(Path("runs"), "x").is_absolute()


@pytest.mark.parametrize(("sets", "key", "text"), [
    (('strategy_definitions={"../x": {parameters: {mode: passive, i_passive: 1.0}}}',
      'strategies=[passive-off, "../x"]'), "strategies.1", "must be a plain name"),
    (('records={"../up": elcentro.yaml}',), "records.../up", "must be a plain name"),
    (("strategy_definitions={" + "s" * 250 + ": {parameters: {mode: passive, i_passive: 1.0}}}",
      "strategies=[passive-off, " + "s" * 250 + "]"), "strategies.1", "bytes per name"),
])
def test_a_study_name_that_would_leave_its_folder_or_cannot_be_filled_is_refused_at_load(tmp_path, sets, key, text):
    """Strategy, record and variant ids name run folders (runs/<record>-<strategy>--<variant>): checked when the
    study is read, as ${best_current} without the sweep that fills it, before any pool or folder."""
    from orchestration.case_study.case_config import load_study
    from orchestration.master.errors import ScenarioError

    base = ("records={elcentro: elcentro.yaml}", "overrides=[simulation.stop_time=0.05]")
    with pytest.raises(ScenarioError) as info:
        load_study(SCENARIOS / "case_study.yaml", (*base, *sets) if not sets[0].startswith("records") else
                   (*sets, base[1]))
    (problem,) = info.value.problems
    assert problem.key == key and text in problem.message, problem


def test_a_suite_pattern_beyond_the_name_limit_or_leaving_the_folder_is_a_problem_not_a_crash(tmp_path):
    from orchestration.ida_study.suites import folder_suite

    for pattern, text in (("a" * 300 + ".AT2", "bytes per name"), ("../*.AT2", "inside the folder")):
        records, problems = folder_suite(tmp_path, (pattern,))
        assert records == [] and problems[0].key == "suite.patterns.0" and text in problems[0].message
    records, problems = folder_suite(tmp_path / ("d" * 300), ("*.AT2",))
    assert problems[0].key == "suite.folder" and "bytes per name" in problems[0].message


# -- strict JSON ---------------------------------------------------------------------------------------------------

def test_json_files_are_strict_a_non_finite_number_is_null_with_its_reason(tmp_path):
    import numpy as np

    from orchestration.master.runfolder import write_json

    write_json(tmp_path / "s.json", {"peak": math.nan, "rows": [1.0, -math.inf], "n": np.float64("inf"), "ok": 1})
    text = (tmp_path / "s.json").read_text()
    data = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))
    assert data["peak"] is None and data["rows"] == [1.0, None] and data["n"] is None and data["ok"] == 1
    assert data["non_finite"] == {"peak": "not a number (nan)", "rows[1]": "infinite (-inf)", "n": "infinite (inf)"}


def test_a_stored_result_with_a_non_finite_value_reads_back_with_a_valid_checksum(tmp_path):
    from orchestration.batch.store import ResultStore

    store = ResultStore(tmp_path)
    store.put("k" * 32, {"status": "ok", "ok": True, "value": {"x": math.nan}})
    assert store.get("k" * 32)["value"] == {"x": None}


# -- caches --------------------------------------------------------------------------------------------------------

def test_the_shared_results_store_recomputes_damaged_or_linked_entries_and_names_the_cache(tmp_path, capsys):
    """The Radau references kept across studies: an entry is used only if it is what the store wrote for its key
    (content key and checksum); a truncated, edited or linked one is removed and computed again, noted; a
    read-only cache is a note, not an error."""
    from orchestration.batch.store import SharedResultStore, open_shared_store

    cache = tmp_path / "results"
    store = SharedResultStore(cache)
    assert (cache.stat().st_mode & 0o777) == 0o700
    key = "a" * 32
    store.put(key, {"status": "ok", "ok": True, "value": {"x_base_mm": 1.5}})
    assert store.get(key)["value"] == {"x_base_mm": 1.5}
    path = store.folder / f"{key}.json"
    for damage in ("truncate", "forge", "link"):
        if damage == "truncate":
            path.write_text(path.read_text()[:20])
        elif damage == "forge":
            data = json.loads(path.read_text())
            data["value"]["x_base_mm"] = 0.1  # a better-looking number, checksum left as it was
            path.write_text(json.dumps(data))
        else:
            target = tmp_path / "planted.json"
            target.write_text(json.dumps({"status": "ok", "ok": True, "key": key, "value": {}}))
            path.unlink()
            path.symlink_to(target)
        assert store.get(key) is None, damage
        assert not os.path.lexists(path), damage
        assert f"note: cache {store.folder}: {key}.json" in capsys.readouterr().err  # names the cache and entry
        store.put(key, {"status": "ok", "ok": True, "value": {"x_base_mm": 1.5}})
    (tmp_path / "file").write_text("x")
    assert open_shared_store(tmp_path / "file") is None
    assert f"note: cache {tmp_path / 'file'}" in capsys.readouterr().err


def test_a_planted_worker_file_copy_is_replaced_by_the_bytes_of_its_sha256(tmp_path, monkeypatch, capsys):
    import hashlib
    import tempfile

    from orchestration.batch import portable

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(portable, "_CACHE_ROOT", None)
    data = b"time_s,accel_g\n0,0\n"
    ref = portable.FileRef(hashlib.sha256(data).hexdigest(), "r.csv")
    first = portable.local_copy(ref, data)
    assert first.read_bytes() == data and (first.parent.parent.stat().st_mode & 0o777) == 0o700
    first.write_bytes(b"planted")
    os.utime(first, ns=(1, 1))  # another size and time: the SHA-256 is computed again
    again = portable.local_copy(ref, data)
    assert again == first and again.read_bytes() == data
    assert "is not the file of that SHA-256" in capsys.readouterr().err


def test_cache_keys_follow_what_the_job_imports_not_a_list(tmp_path):
    """The case study's jobs import the in-process executor (through the tuning module): it is in their key's code;
    a module added to the import graph changes the key, one outside it does not."""
    from orchestration.batch.code_sources import import_closure

    closure = import_closure("orchestration.case_study.case_jobs")
    assert "orchestration/inprocess/scalar_executor.py" in closure
    assert "components/physics/monolithic.py" in closure  # imported inside reference_job only
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "job.py").write_text("def job():\n    from pkg import helper\n    return helper.f()\n")
    (pkg / "helper.py").write_text("from .deep import g\ndef f():\n    return g()\n")
    (pkg / "deep.py").write_text("def g():\n    return 1\n")
    (pkg / "unused.py").write_text("")
    assert import_closure("pkg.job", tmp_path) == ("pkg/__init__.py", "pkg/deep.py", "pkg/helper.py", "pkg/job.py")


# -- user scripts --------------------------------------------------------------------------------------------------

SCRIPTS = {
    "os_exit": "import os\nos._exit(0)\n",
    "sys_exit": "import sys\nsys.exit(0)\n",
    "chdir": "import os\nos.chdir('/')\n",
    "forever": "while True:\n    pass\n",
}


@pytest.mark.parametrize("kind", sorted(SCRIPTS))
def test_a_model_script_that_ends_moves_or_never_ends_is_refused_by_a_bounded_check_in_a_child(tmp_path, kind):
    pytest.importorskip("openseespy")
    from components.physics import opensees_building_core as core

    script = tmp_path / f"{kind}.py"
    model = (SCENARIOS / "structures" / "dyke_linear.py").read_text()
    script.write_text(SCRIPTS[kind] + model)
    cwd = os.getcwd()
    text = core.check_script(script, timeout_s=3.0)
    assert os.getcwd() == cwd
    expected = {"os_exit": "ended the process", "sys_exit": "SystemExit", "chdir": "must not call os.chdir",
                "forever": "did not finish building its model within 3 s"}[kind]
    assert text is not None and expected in text and str(script) in text
    assert core.check_script(SCENARIOS / "structures" / "dyke_linear.py") is None


def test_a_script_given_as_a_plain_path_is_a_hashed_data_file_of_the_plan(tmp_path, monkeypatch):
    """Its SHA-256 goes into manifest.json (data_files), its path is absolute (a later chdir cannot move it)."""
    pytest.importorskip("openseespy")
    import hashlib

    from orchestration.engine_hooks import plan_scenario

    monkeypatch.chdir(PROJECT)
    plan = plan_scenario(SCENARIOS / "elcentro_opensees.yaml",
                         ("simulation.stop_time=0.05", "building.script=scenarios/structures/dyke_linear.py"))
    path = PROJECT / "scenarios" / "structures" / "dyke_linear.py"
    assert plan.data_files["building.script"] == path and plan.parameters["building"]["script"] == str(path)
    assert plan.input_hashes[str(path)] == hashlib.sha256(path.read_bytes()).hexdigest()


def test_a_package_carrying_a_script_is_named_when_it_is_read():
    from orchestration.interop.ssp_package import carried_scripts
    from orchestration.master.yaml_source import DataFile

    data = {"units": {"building": {"parameters": {"script": DataFile("/x/resources/model.py"), "m_0": 1.0}},
                      "ground": {"parameters": {"record": DataFile("/x/resources/kobe.csv", "record")}}}}
    assert carried_scripts(data) == ["units.building.parameters.script = resources/model.py"]


# -- the CSV process -----------------------------------------------------------------------------------------------

_CSV_CASE = textwrap.dedent("""
    import os, signal, sys, time
    from pathlib import Path
    import numpy as np
    from orchestration.master.recorder import CsvProcess, RowStorage
    mode, folder = sys.argv[1], Path(sys.argv[2])
    n = 50_000
    st = RowStorage(n, 2, shared=True)
    st.time[:] = np.arange(n) * 1e-3
    st.data[:] = 1.0
    CsvProcess.STALL_S = 3.0
    p = CsvProcess.start(folder / "timeseries.csv", ["a", "b"], st)
    p.rows(n // 2)
    for _ in range(200):  # until the child has written the announced rows
        tmp = list(folder.glob(".timeseries.csv.*.tmp"))
        if tmp and tmp[0].stat().st_size > 10 * (n // 2):
            break
        time.sleep(0.05)
    os.kill(p._pid, signal.SIGSTOP if mode == "stop" else signal.SIGKILL)
    started = time.monotonic()
    p.finish(n)
    try:
        p.wait()
        print("no error")
    except OSError as exc:
        print(f"{time.monotonic() - started:.1f} {exc}")
""")


@pytest.mark.parametrize("mode", ["stop", "kill"])
def test_a_stopped_or_killed_csv_process_is_a_bounded_error_and_its_rows_are_kept_as_incomplete(tmp_path, mode):
    """In a fresh interpreter (the CSV process is forked). SIGSTOP: the parent does not wait forever; SIGKILL: no
    hidden .tmp is left; either way the rows written are in timeseries.csv.incomplete and the error says so."""
    from orchestration.master.recorder import CsvProcess

    if not sys.platform.startswith("linux"):
        pytest.skip("the CSV process is Linux only")
    done = subprocess.run([sys.executable, "-c", _CSV_CASE, mode, str(tmp_path)], capture_output=True, text=True,
                          timeout=60, cwd=PROJECT)
    seconds, _, message = done.stdout.strip().partition(" ")
    assert float(seconds) < 10, done.stdout + done.stderr
    assert ("was stopped" if mode == "stop" else "killed by signal 9") in message
    kept = tmp_path / f"timeseries.csv{CsvProcess.INCOMPLETE_SUFFIX}"
    assert f"kept in {kept.name}" in message and sorted(p.name for p in tmp_path.iterdir()) == [kept.name]
    lines = kept.read_text().splitlines()
    assert lines[0] == "time,a,b" and len(lines) - 1 >= 25_000 and all(line.count(",") == 2 for line in lines)


# -- units of a connection -----------------------------------------------------------------------------------------

def test_units_of_a_connection_refused_if_different_warned_if_the_output_has_none(capsys):
    from orchestration.master.unit_check import connection_units, warn_once

    assert connection_units("a.x", "b.x", "m", "mm")[0] == "unit mismatch: a.x is in m, b.x in mm"
    problem, warning = connection_units("a.y", "b.x", "", "A")
    assert problem is None and "a.y declares no unit" in warning and "b.x in A" in warning
    assert connection_units("a.x", "b.x", "m", "") == (None, None)
    assert connection_units("a.x", "b.x", "m", "m") == (None, None)
    warn_once(warning)
    warn_once(warning)
    assert capsys.readouterr().err.count("warning: a.y declares no unit") == 1
