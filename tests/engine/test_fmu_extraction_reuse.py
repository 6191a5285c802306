"""FMUs extracted once per machine and reused by the runs of a study's workers (orchestration/master/fmu_loading.py,
orchestration/batch/child.py), with every run's instances fresh: a run in a worker that ran another run before
gives the same numbers as the run alone in a fresh process."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from orchestration.master import fmu_loading

from ..conftest import PROJECT

SCENARIO = PROJECT / "scenarios" / "elcentro.yaml"


def _run_in_child(payload: dict) -> dict:
    """A run as a study's child runs it: its timeseries.csv and the shared extraction folders of its FMUs."""
    from orchestration.batch.child import extraction_root
    from orchestration.engine_hooks import plan_scenario
    from orchestration.master.session import run_plan

    plan = plan_scenario(SCENARIO, tuple(payload["overrides"]))
    with tempfile.TemporaryDirectory() as tmp:
        run_plan(plan, Path(tmp) / "run", plots=False, progress=False)
        text = (Path(tmp) / "run" / "timeseries.csv").read_text()
    folders = {}
    for unit, path in plan.fmu_paths.items():
        st = os.stat(path)
        folder = extraction_root() / fmu_loading._archive_sha256(str(Path(path).resolve()), st.st_size,
                                                                 st.st_mtime_ns)
        folders[unit] = os.stat(folder).st_ino  # FileNotFoundError if the run did not use a shared extraction
    return {"timeseries": text, "folders": folders, "pid": os.getpid()}


@pytest.mark.slow
def test_two_runs_in_one_worker_equal_runs_in_fresh_processes(tmp_path, monkeypatch):
    from orchestration.batch.child import extraction_root
    from orchestration.batch.runner import Job, run_jobs

    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the workers' (and this process's) file cache and extractions
    monkeypatch.setattr(tempfile, "tempdir", None)
    overrides = {"passive": ["simulation.stop_time=1", "controller.mode=passive", "controller.i_passive=3"],
                 "sosm": ["simulation.stop_time=1", "ground.scale=0.7"]}
    jobs = [Job(name, _run_in_child, {"overrides": o}) for name, o in overrides.items()]
    results = run_jobs(jobs, workers=1)  # one after the other, on one worker
    assert all(r.ok for r in results.values()), {k: r.error for k, r in results.items()}
    a, b = results["passive"].value, results["sosm"].value
    assert a["pid"] != b["pid"]  # each run in a child of its own
    assert a["folders"] == b["folders"]  # the same extractions, not made again
    assert len(list(extraction_root().iterdir())) == len(set(a["folders"].values()))
    assert a["timeseries"] != b["timeseries"]
    for name, value in results.items():
        out = tmp_path / f"fresh-{name}"
        cmd = [sys.executable, str(PROJECT / "orchestration" / "run.py"), str(SCENARIO), "--out", str(out),
               "--no-plots", "--quiet"]
        for o in overrides[name]:
            cmd += ["--set", o]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        assert value.value["timeseries"] == (out / "timeseries.csv").read_text(), name


def test_a_second_unit_of_one_fmu_gets_its_own_folder(tmp_path, monkeypatch):
    """Two loads of one archive in one process: the shared extraction, then a private one (no shared library state);
    released: the shared folder stays for later runs, the private one is removed."""
    import fmpy
    import fmpy.fmi2

    path = PROJECT / "fmus" / "SosmCurrentController.fmu"
    if not path.is_file():
        pytest.skip("FMUs not built (python -m components.build)")
    md = fmpy.read_model_description(str(path))
    monkeypatch.setattr(fmu_loading, "_SHARED_ROOT", None)
    monkeypatch.setattr(fmu_loading, "_IN_USE", set())
    fmu_loading.share_extractions(tmp_path / "x")
    d1, s1 = fmu_loading.load_slave(fmpy.fmi2.FMU2Slave, path, md, "a", 0.0)
    d2, s2 = fmu_loading.load_slave(fmpy.fmi2.FMU2Slave, path, md, "b", 0.0)
    assert Path(d1).parent == tmp_path / "x" and Path(d2).parent != tmp_path / "x"
    for d, s in ((d1, s1), (d2, s2)):
        s.freeLibrary()
        fmu_loading.release(d)
    assert Path(d1).is_dir() and not Path(d2).exists()
    d3, s3 = fmu_loading.load_slave(fmpy.fmi2.FMU2Slave, path, md, "c", 0.0)
    assert d3 == d1  # reused, not extracted again
    fmu_loading.release(d3, abandoned=True)  # after a Fatal status its library stays loaded with its instance
    d5, s5 = fmu_loading.load_slave(fmpy.fmi2.FMU2Slave, path, md, "e", 0.0)
    assert d5 != d1  # so the shared folder is not lent again in this process
    s5.freeLibrary()
    fmu_loading.release(d5)
    s3.freeLibrary()
    fmu_loading.share_extractions(None)
    d4, s4 = fmu_loading.load_slave(fmpy.fmi2.FMU2Slave, path, md, "d", 0.0)
    assert Path(d4).parent != tmp_path / "x"
    s4.freeLibrary()
    fmu_loading.release(d4)
    assert not Path(d4).exists()


def _shared(tmp_path, monkeypatch, root: Path) -> tuple[Path, str]:
    path = PROJECT / "fmus" / "SosmCurrentController.fmu"
    if not path.is_file():
        pytest.skip("FMUs not built (python -m components.build)")
    monkeypatch.setattr(fmu_loading, "_SHARED_ROOT", None)
    fmu_loading.share_extractions(root)
    st = os.stat(path)
    return path, fmu_loading._archive_sha256(str(path.resolve()), st.st_size, st.st_mtime_ns)


def test_a_planted_or_damaged_extraction_is_never_used_and_made_again_with_a_note(tmp_path, monkeypatch, capsys):
    """An extraction is used only if its files match the manifest written when it was extracted: a folder planted
    under the archive's SHA-256 (no manifest), one with a changed or an extra file, is extracted again, noted."""
    root = tmp_path / "x"
    path, sha = _shared(tmp_path, monkeypatch, root)
    first = Path(fmu_loading._shared_folder(path))
    assert first == root / sha and (root.stat().st_mode & 0o777) == 0o700
    library = next(first.rglob("*.so"))
    good = library.read_bytes()
    for damage in ("truncate", "extra", "planted"):
        if damage == "truncate":
            library.write_bytes(good[:100])
        elif damage == "extra":
            (first / "sitecustomize.py").write_text("import os; os.system('touch /tmp/pwned')")
        else:
            import shutil

            shutil.rmtree(first)
            (first / "binaries").mkdir(parents=True)
            (first / "binaries" / "evil.so").write_bytes(b"\x7fELF planted")
        again = Path(fmu_loading._shared_folder(path))
        assert again == first and library.read_bytes() == good, damage
        assert not (first / "sitecustomize.py").exists() and not (first / "binaries" / "evil.so").exists()
        err = capsys.readouterr().err
        assert f"note: cache {root}: extraction {sha[:16]}" in err and "extracting it again" in err, damage
    fmu_loading.share_extractions(None)


def test_an_extraction_root_that_is_a_symlink_or_open_to_others_is_not_used(tmp_path, monkeypatch, capsys):
    """A pre-created symlink at the cache's place is not followed (the files land in a private folder of the
    process's own), and the note names the cache."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    root = tmp_path / "x"
    root.symlink_to(elsewhere)
    path, _sha = _shared(tmp_path, monkeypatch, root)
    used = Path(fmu_loading._shared_folder(path))
    assert used.parent != root and not any(elsewhere.iterdir())
    assert f"note: cache {root}: is a symbolic link (never followed)" in capsys.readouterr().err
    fmu_loading.share_extractions(None)
