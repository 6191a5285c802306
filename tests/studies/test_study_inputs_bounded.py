"""Hostile input to the study tools (study.py, ida.py, tune.py): bounded waits, defensive stores, numbers in
their domain, names in bytes, ``extends`` across folders (reliability corpus classes 1, 4, 5, 6, 7)."""

from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from mre_common.fs_limits import encoded_length, name_max, name_problem, path_problem
from orchestration.batch.pool import BatchPool, BatchUnavailable, probe_scheduler, scheduler_endpoint
from orchestration.batch.store import RESUME_MARKER, ResultStore, StoreError, folder_problems, open_for_resume
from orchestration.case_study.case_config import MAX_SWEEP_POINTS, load_study
from orchestration.ida_study.ida_config import load_ida
from orchestration.master.errors import ScenarioError

from ..conftest import PROJECT

STUDY = PROJECT / "scenarios" / "case_study.yaml"
IDA = PROJECT / "scenarios" / "ida.yaml"


# -- class 1: every wait on the network is bounded ------------------------------------------------------------
class Listener:
    """A loopback TCP listener for one test: accepts, then stays silent or says ``greeting``; stops by itself."""

    def __init__(self, greeting: bytes = b"", lifetime_s: float = 30.0) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.greeting, self.end = greeting, time.monotonic() + lifetime_s
        self.stop = threading.Event()
        self.conns: list[socket.socket] = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set() and time.monotonic() < self.end:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            if self.greeting:
                conn.sendall(self.greeting)
            self.conns.append(conn)
        for c in self.conns:
            c.close()
        self.sock.close()

    def __enter__(self) -> Listener:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(5)


@pytest.mark.parametrize("greeting", [b"", b"HTTP/1.1 400 Bad Request\r\n\r\n", b"SSH-2.0-OpenSSH_9.6\r\n"])
def test_a_listener_that_is_not_a_dask_scheduler_is_refused_within_the_connect_timeout(greeting):
    with Listener(greeting) as listener:
        start = time.monotonic()
        with pytest.raises(BatchUnavailable, match=r"not a Dask scheduler|not as a Dask scheduler"):
            probe_scheduler(f"tcp://127.0.0.1:{listener.port}", 1.0)
        assert time.monotonic() - start < 3.0


def test_the_pool_refuses_a_silent_listener_within_its_connect_timeout():
    with Listener() as listener:
        start = time.monotonic()
        pool = BatchPool(f"127.0.0.1:{listener.port}", connect_timeout_s=1.0)
        with pytest.raises(BatchUnavailable, match="sent nothing within 1 s"):
            pool.start()
        assert time.monotonic() - start < 5.0


@pytest.mark.parametrize("address", ["http://127.0.0.1:8787", "tls://127.0.0.1:8786", "tcp://127.0.0.1",
                                     "tcp://127.0.0.1:0", "tcp://127.0.0.1:99999", "tcp://:8786",
                                     "tcp://127.0.0.1:87a6", "tcp://127.0.0.1:8786/x", "localhost"])
def test_malformed_or_foreign_addresses_are_refused_before_any_wait(address):
    start = time.monotonic()
    with pytest.raises(BatchUnavailable, match="tcp://HOST:PORT"):
        scheduler_endpoint(address)
    assert time.monotonic() - start < 0.1


def test_a_well_formed_address_parses_to_host_and_port():
    assert scheduler_endpoint("tcp://127.0.0.1:8786") == ("127.0.0.1", 8786)
    assert scheduler_endpoint("example.org:1") == ("example.org", 1)
    assert scheduler_endpoint("tcp://[::1]:8786") == ("::1", 8786)


def test_a_closed_port_is_refused_at_once():
    with socket.socket() as s:  # a port that was free a moment ago: nothing listens on it
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(BatchUnavailable, match="cannot reach"):
        probe_scheduler(f"tcp://127.0.0.1:{port}", 1.0)


@pytest.mark.slow
def test_study_py_at_a_silent_listener_is_exit_2_within_the_bound(tmp_path):
    with Listener(lifetime_s=60) as listener:
        start = time.monotonic()
        proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "study.py"), str(STUDY),
                               "--scheduler", f"tcp://127.0.0.1:{listener.port}", "--out", str(tmp_path / "s")],
                              capture_output=True, text=True, timeout=120, cwd=tmp_path)
        elapsed = time.monotonic() - start
    assert proc.returncode == 2, proc.stderr
    assert "sent nothing within 10 s" in proc.stderr and "Traceback" not in proc.stderr
    assert elapsed < 60
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("override", ["sweep.step=1e-10", "sweep.stop=1e300", "i_max=1e300", "sweep.step=5e-324"])
def test_a_sweep_has_a_bounded_size(override):
    with pytest.raises(ScenarioError, match=f"more than {MAX_SWEEP_POINTS:,} currents"):
        load_study(STUDY, (override,))


def test_the_shipped_sweep_is_within_the_bound():
    spec = load_study(STUDY).spec
    assert len(spec.sweep.currents(spec.i_max)) <= MAX_SWEEP_POINTS


# -- class 5: numbers finite and in their domain, booleans true/false -------------------------------------------
@pytest.mark.parametrize("override, message", [
    ("timeout_s=.nan", "finite"), ("timeout_s=.inf", "finite"), ("timeout_s=0", "greater than 0"),
    ("timeout_s=-5", "greater than 0"), ("timeout_s=1e12", "less than or equal"),
    ("objective.w_acc=.nan", "finite"), ("objective.penalty=-.inf", "finite"), ("objective.x_limit=.nan", "finite"),
    ("tuning.bounds.lam=[.nan, 2]", "finite"), ("tuning.bounds.rho=[1, .inf]", "finite"),
    ("tuning.seed=-1", "greater than or equal to 0"), ("tuning.stop_time=-1", "must be positive"),
    ("tuning.stop_time=.nan", "finite"), ("tuning.n_samples=0", "greater than or equal to 1"),
    ("tuning.max_evals=1e12", "integer|less than"), ("x_limit=.nan", "finite"), ("x_identified=0", "greater than 0"),
    ("reference.rtol=.nan", "finite"), ("paper_current_range=[2, 1]", "low <= high"),
    ("reference.enabled=yes", "YAML 1.1 boolean"), ("reference.enabled=off", "YAML 1.1 boolean"),
    ("reference.enabled='yes'", "valid boolean"), ("reference.enabled=1", "valid boolean"),
])
def test_a_study_number_or_boolean_out_of_its_domain_is_refused_with_its_key(override, message):
    key = override.split("=")[0]
    with pytest.raises(ScenarioError) as info:
        load_study(STUDY, (override,))
    text = info.value.report()
    assert re_search(message, text) and key.split(".")[-1] in text, text


def re_search(pattern: str, text: str) -> bool:
    import re

    return re.search(pattern, text) is not None


def test_a_yaml_1_1_boolean_in_a_study_file_is_refused_with_its_line(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text(f"extends: {STUDY}\nreference:\n  enabled: yes\n")
    with pytest.raises(ScenarioError) as info:
        load_study(f)
    assert f"{f}:3" in info.value.report() and "'yes' is a YAML 1.1 boolean" in info.value.report()


@pytest.mark.parametrize("override, message", [
    ("timeout_s=.nan", "finite"), ("timeout_s=0", "greater than 0"), ("window.tail_s=.inf", "finite"),
    ("window.strong_motion=yes", "YAML 1.1 boolean"), ("window.strong_motion='no'", "valid boolean"),
    ("confidence=.nan", "finite"), ("intensity.damping=.nan", "finite"), ("time_scale=.inf", "finite"),
    ("limit_states.slight.threshold=.nan", "finite|slight"),
])
def test_an_ida_number_or_boolean_out_of_its_domain_is_refused(override, message):
    try:
        loaded, problems, _ = load_ida(IDA, (override,))
        text = "\n".join(str(p) for p in problems)
    except ScenarioError as exc:  # a malformed --set is refused while it is applied
        loaded, text = None, exc.report()
    assert loaded is None and re_search(message, text), text


def test_tune_writes_no_gains_file_from_a_non_finite_objective(tmp_path, monkeypatch, capsys):
    """A tuning whose best J is NaN (every simulation without finite peaks) is exit 1 and writes nothing."""
    import orchestration.batch.pool as pool_module
    from orchestration.case_study import tuning

    class NoPool:
        def __init__(self, *a, **k) -> None: ...
        def start(self) -> None: ...
        def describe(self) -> str: return "no pool"
        def __enter__(self): return self
        def __exit__(self, *exc): ...

    gains = tuning.DEFAULT_GAINS
    monkeypatch.setattr(pool_module, "BatchPool", NoPool)
    monkeypatch.setattr(tuning, "tune_and_check", lambda *a, **k: ({"gains": gains, "objective": math.nan}, {}, ""))
    out = tmp_path / "gains.yaml"
    assert tuning.main([str(STUDY), "--out", str(out), "--quiet"]) == 1
    assert not out.exists()
    assert "not finite" in capsys.readouterr().err


def test_tune_refuses_a_gains_file_it_could_not_write_before_any_work(tmp_path, monkeypatch, capsys):
    """--out below a file is exit 2 naming it, before the pool starts or any simulation runs."""
    from orchestration.case_study import tuning

    def never(*a, **k):
        raise AssertionError("the tuning started")

    monkeypatch.setattr(tuning, "tune_and_check", never)
    (tmp_path / "precious.txt").write_text("keep")
    assert tuning.main([str(STUDY), "--out", str(tmp_path / "precious.txt" / "g.yaml"), "--force", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "precious.txt" in err and "not a folder" in err, err
    assert (tmp_path / "precious.txt").read_text() == "keep"


# -- class 4: stores and folders read defensively --------------------------------------------------------------
def result(peak: float = 0.0123) -> dict:
    return {"label": "elcentro/sosm", "ok": True, "status": "ok", "value": {"peak_base_displacement_m": peak},
            "error": None, "wall_time_s": 1.5, "worker": None}


def test_a_stored_result_round_trips_with_its_key_and_checksum(tmp_path):
    store = ResultStore(tmp_path)
    assert store.put("k1", result())
    got = store.get("k1")
    assert got["value"] == result()["value"] and got["key"] == "k1" and len(got["checksum"]) == 64
    assert store.problems() == []


@pytest.mark.parametrize("damage, message", [
    (lambda d: {**d, "value": {"peak_base_displacement_m": 0.001}}, "checksum does not match"),
    (lambda d: {**d, "key": "k2"}, "holds the result of key 'k2'"),
    (lambda d: [d], "JSON list"),
    (lambda d: {k: v for k, v in d.items() if k != "checksum"}, "checksum does not match"),
    (lambda d: {**d, "status": "lost"}, "no valid status"),
    (lambda d: {k: v for k, v in d.items() if k != "ok"}, "no valid status"),
])
def test_a_stored_result_edited_by_hand_is_refused_with_the_file_named(tmp_path, damage, message):
    store = ResultStore(tmp_path)
    store.put("k1", result())
    path = tmp_path / "jobs" / "k1.json"
    path.write_text(json.dumps(damage(json.loads(path.read_text()))))
    with pytest.raises(StoreError, match=message) as info:
        store.get("k1")
    assert str(path) in str(info.value)
    assert store.get("k1", strict=False) is None
    assert len(store.problems()) == 1 and str(path) in store.problems()[0]


@pytest.mark.parametrize("make, message", [
    (lambda p: p.write_bytes(b"\xff\xfe{"), "cannot be read|not JSON"),
    (lambda p: p.write_text('{"key": "k1"'), "not JSON"),
    (lambda p: p.mkdir(), "a folder"),
])
def test_a_damaged_store_entry_is_refused(tmp_path, make, message):
    store = ResultStore(tmp_path)
    make(tmp_path / "jobs" / "k1.json")
    with pytest.raises(StoreError, match=message):
        store.get("k1")


def study_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "study.json").write_text("{}")
    ResultStore(folder).put("k1", result())
    return folder


def test_a_resume_claims_its_folder_and_a_second_one_is_refused(tmp_path):
    folder = study_folder(tmp_path)
    _, marker = open_for_resume(folder, "study.json", "study.py")
    with pytest.raises(StoreError, match="another --resume"):
        open_for_resume(folder, "study.json", "study.py")
    marker.unlink()
    _, marker = open_for_resume(folder, "study.json", "study.py")  # free again
    marker.unlink()


def test_a_claim_left_by_an_ended_process_is_taken_over(tmp_path):
    folder = study_folder(tmp_path)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (folder / RESUME_MARKER).write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname()}))
    _, marker = open_for_resume(folder, "study.json", "study.py")
    assert json.loads(marker.read_text())["pid"] == os.getpid()


@pytest.mark.parametrize("damage, message", [
    (lambda f: (f / "study.json").unlink(), "missing or not a file"),
    (lambda f: ((f / "jobs" / "k1.json").unlink(), (f / "jobs").rmdir(), (f / "jobs").write_text("")), "not a folder"),
    (lambda f: (f / "jobs" / "notes.txt").write_text("mine"), "unexpected file"),
    (lambda f: (f / "jobs" / "k9.json").write_text("[]"), "JSON list"),
])
def test_a_resume_of_a_folder_the_tool_did_not_write_is_refused(tmp_path, damage, message):
    folder = study_folder(tmp_path)
    damage(folder)
    with pytest.raises(StoreError, match=message):
        open_for_resume(folder, "study.json", "study.py")
    assert not (folder / RESUME_MARKER).exists()


def test_a_resume_of_a_file_or_a_read_only_folder_is_refused(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(StoreError, match="not a folder"):
        open_for_resume(f, "study.json", "study.py")
    with pytest.raises(StoreError, match="does not exist"):
        open_for_resume(tmp_path / "nowhere", "study.json", "study.py")
    folder = study_folder(tmp_path)
    folder.chmod(0o555)
    try:
        if os.access(folder, os.W_OK):
            pytest.skip("running as root: a read-only folder is writable")
        with pytest.raises(StoreError, match="read-only"):
            open_for_resume(folder, "study.json", "study.py")
    finally:
        folder.chmod(0o755)


@pytest.mark.slow
@pytest.mark.parametrize("tool, record", [("study.py", "study.json"), ("ida.py", "ida.json")])
@pytest.mark.parametrize("flag", ["--resume", "--report"])
def test_the_tools_refuse_a_folder_they_did_not_write_with_exit_2(tmp_path, tool, record, flag):
    folder = tmp_path / "f"
    folder.mkdir()
    (folder / record).write_text("[1, 2]")  # JSON, but not the tool's record
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / tool), flag, str(folder), "--quiet"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and (record in proc.stderr or str(folder) in proc.stderr)


# -- class 6: names and paths in bytes, against the file system's limits ------------------------------------------
def test_names_are_measured_in_bytes():
    emoji = "\N{GRINNING FACE}" * 100
    assert len(emoji) == 100 and encoded_length(emoji) == 400
    assert name_max("/tmp") == os.pathconf("/tmp", "PC_NAME_MAX")
    assert "400 bytes" in name_problem(emoji, "/tmp")
    assert name_problem("a" * name_max("/tmp"), "/tmp") is None
    assert name_problem("a" * name_max("/tmp"), "/tmp", reserve=1) is not None
    assert name_problem("\N{GRINNING FACE}" * 60, "/tmp") is None  # 240 bytes


def test_a_path_beyond_the_limits_is_named():
    assert path_problem("/tmp/" + "\N{GRINNING FACE}" * 70) is not None  # one 280-byte component
    deep = "/tmp/" + "/".join(["d" * 200] * 25)  # 5,000 bytes
    assert "bytes per path" in path_problem(deep)
    assert path_problem("/tmp/ok/study") is None


def test_a_study_name_or_out_the_file_system_cannot_hold_is_refused_before_any_work(tmp_path):
    emoji = "\N{GRINNING FACE}" * 100
    assert [k for k, _ in folder_problems(emoji, tmp_path, None)] == ["name"]
    assert [k for k, _ in folder_problems("ok", tmp_path, tmp_path / emoji)] == ["--out"]
    assert folder_problems("\N{GRINNING FACE}" * 50, tmp_path, None) == []


@pytest.mark.slow
def test_study_py_refuses_a_study_name_of_100_emoji_with_exit_2(tmp_path):
    emoji = "\N{GRINNING FACE}" * 100
    proc = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "study.py"), str(STUDY),
                           "--set", f"name={emoji}", "--quiet"], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    assert proc.returncode == 2 and "400 bytes" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert not (tmp_path / "studies").exists()


# -- class 7: extends across folders ----------------------------------------------------------------------------
def test_a_study_extending_a_shipped_one_resolves_inherited_paths_against_the_shipped_folder(tmp_path):
    own = tmp_path / "mine"
    own.mkdir()
    (own / "extra.yaml").write_text("stop_time: 1.0\n")
    f = own / "study.yaml"
    shipped = STUDY.parent
    f.write_text(f"extends: {STUDY}\nname: mine\n")  # the shipped records, found in the shipped folder
    study = load_study(f)
    assert list(study.spec.records) == ["elcentro", "hachinohe", "northridge", "kobe"]
    assert study.scenario_path("elcentro") == (shipped / "elcentro.yaml").resolve()
    f.write_text(f"extends: {STUDY}\nname: mine\nrecords:\n  extra: extra.yaml\n")
    study = load_study(f)
    assert list(study.spec.records) == ["extra"]  # records replace the parent's: the study runs these only
    assert study.scenario_path("extra") == (own / "extra.yaml").resolve()
    assert study.lines[("records", "extra")][0] == str(f)
    assert ("records", "elcentro") not in study.lines  # nor its line
    assert study.gains_path == (shipped / "sosm_gains.yaml").resolve()
    f.write_text(f"extends: {STUDY}\ngains: my_gains.yaml\n")
    assert load_study(f).gains_path == (own / "my_gains.yaml").resolve()


def test_an_ida_study_extending_a_shipped_one_resolves_inherited_paths_against_the_shipped_folder(tmp_path):
    f = tmp_path / "ida.yaml"
    f.write_text(f"extends: {IDA}\nname: mine\n")
    loaded, problems, _ = load_ida(f)
    assert problems == [], problems
    assert loaded.resolve(loaded.spec.scenario, "scenario") == (IDA.parent / loaded.spec.scenario).resolve()
    assert loaded.resolve(loaded.spec.gains, "gains") == (IDA.parent / loaded.spec.gains).resolve()


# -- a timed-out job leaves no temporary folder -----------------------------------------------------------------
def _stuck_job(note: str) -> None:
    """Makes a temporary run folder as jobs.run_folder does, writes its path to ``note``, then hangs."""
    import tempfile

    from orchestration.batch.jobs import run_folder_prefix

    folder = tempfile.mkdtemp(prefix=run_folder_prefix(os.getpid()))
    Path(note).write_text(folder)
    time.sleep(60)


def test_a_killed_job_leaves_no_temporary_run_folder(tmp_path):
    """Killed as soon as its run folder exists (the path a timeout takes too): the folder is removed."""
    from orchestration.batch.child import call_in_child

    note = tmp_path / "where"
    out = call_in_child(_stuck_job, str(note), timeout_s=120.0, cancelled=lambda: note.exists() and note.stat().st_size)
    assert not out["ok"] and "process killed" in out["error"]
    assert not Path(note.read_text()).exists()


def test_an_ida_ladder_has_a_bounded_size():
    from orchestration.ida_study.ida_config import MAX_LEVELS

    levels = ", ".join(f"{0.001 * (k + 1):g}" for k in range(MAX_LEVELS + 1))
    _, problems, _ = load_ida(IDA, (f"intensity.levels=[{levels}]",))
    assert any(f"at most {MAX_LEVELS:,}" in p.message and p.key == "intensity.levels" for p in problems), problems


def test_a_resumed_study_extending_a_shipped_one_still_finds_the_shipped_files(tmp_path):
    """--resume rebuilds the study from study.json's config: key_files says again which file wrote each path."""
    from orchestration.building_studies.study_file import key_files
    from orchestration.case_study.case_config import LoadedStudy, StudySpec

    f = tmp_path / "study.yaml"
    f.write_text(f"extends: {STUDY}\nname: mine\n")
    config = load_study(f).spec.model_dump()
    resumed = LoadedStudy(StudySpec.model_validate(config), f, config, key_files(f))
    assert resumed.scenario_path("elcentro") == (STUDY.parent / "elcentro.yaml").resolve()
    assert key_files(tmp_path / "gone.yaml") == {}
