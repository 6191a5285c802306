"""mre_common: atomic writes, the C compile cache, folder claims (fast, standard library only)."""

from __future__ import annotations

import os
import shutil
import stat
import threading
from pathlib import Path

import pytest

from mre_common import c_compile
from mre_common.atomic_files import atomic_write, atomic_write_bytes, atomic_write_text, current_umask
from mre_common.folder_claim import claim_folder, read_claim


def test_atomic_write_replaces_the_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")
    atomic_write_text(target, "new\r\nline")
    assert target.read_bytes() == b"new\r\nline"  # no newline translation
    atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.bin"]
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~current_umask()
    atomic_write_bytes(target, b"x", mode=0o640)
    assert stat.S_IMODE(target.stat().st_mode) == 0o640


@pytest.mark.parametrize("error", [ValueError, KeyboardInterrupt])
def test_atomic_write_keeps_the_old_file_on_an_error(tmp_path, error):
    target = tmp_path / "a.json"
    target.write_text("old")

    def half(f):
        f.write("half of the new")
        raise error("disk on fire")

    with pytest.raises(error):
        atomic_write(target, half)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_current_umask_matches_the_os(tmp_path):
    old = os.umask(0o027)
    try:
        assert current_umask() == 0o027
    finally:
        os.umask(old)


needs_cc = pytest.mark.skipif(shutil.which(os.environ.get("CC", "cc")) is None, reason="no C compiler")


@needs_cc
def test_compile_cached_compiles_once_per_content_and_rebuilds_on_a_change(tmp_path, monkeypatch):
    source = tmp_path / "k.c"
    source.write_text("int answer(void) { return 41; }\n")
    calls = []
    real = c_compile.compile_c
    monkeypatch.setattr(c_compile, "compile_c", lambda *a, **k: calls.append(a) or real(*a, **k))
    flags = ("-shared", "-fPIC", "-O2")
    first = c_compile.compile_cached(source, flags, name="k", folder=tmp_path / "cache")
    again = c_compile.compile_cached(source, flags, name="k", folder=tmp_path / "cache")
    assert first == again and len(calls) == 1
    import ctypes

    assert ctypes.CDLL(str(first)).answer() == 41
    source.write_text("int answer(void) { return 42; }\n")
    changed = c_compile.compile_cached(source, flags, name="k", folder=tmp_path / "cache")
    assert changed != first and len(calls) == 2
    assert ctypes.CDLL(str(changed)).answer() == 42
    other_flags = c_compile.compile_cached(source, (*flags, "-DX=1"), name="k", folder=tmp_path / "cache")
    assert other_flags != changed and len(calls) == 3
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == sorted(
        p.name for p in (first, changed, other_flags))  # no temporary file left


@needs_cc
def test_compile_errors_name_the_cause_and_leave_nothing(tmp_path, monkeypatch):
    source = tmp_path / "bad.c"
    source.write_text("this is not C\n")
    with pytest.raises(c_compile.CompileFailed) as info:
        c_compile.compile_cached(source, ("-shared", "-fPIC"), folder=tmp_path / "cache")
    assert str(info.value).startswith("compiling bad.c with ") and info.value.stderr
    assert list((tmp_path / "cache").iterdir()) == []
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    with pytest.raises(c_compile.CompilerMissing, match=r"no C compiler .*no-such-compiler.* \(set CC\)"):
        c_compile.compile_cached(source, ("-shared",), folder=tmp_path / "cache")


def test_claim_refuses_a_second_claimant(tmp_path):
    claim_folder(tmp_path, ".marker", {"tool": "first", "pid": 1})
    with pytest.raises(FileExistsError):
        claim_folder(tmp_path, ".marker", {"tool": "second"})
    assert read_claim(tmp_path, ".marker") == {"tool": "first", "pid": 1}


def test_of_many_racing_claimants_exactly_one_wins(tmp_path):
    won, lost = [], []

    def claim(k: int) -> None:
        try:
            claim_folder(tmp_path, ".marker", {"k": k})
            won.append(k)
        except FileExistsError:
            lost.append(k)

    threads = [threading.Thread(target=claim, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(won) == 1 and len(lost) == 7
    assert read_claim(tmp_path, ".marker") == {"k": won[0]}


def test_a_claim_that_cannot_be_written_leaves_no_marker(tmp_path):
    class Unserialisable:
        pass

    with pytest.raises(TypeError):
        claim_folder(tmp_path, ".marker", {"x": Unserialisable()})
    assert not (tmp_path / ".marker").exists()
    with pytest.raises(OSError):
        claim_folder(Path(tmp_path) / "missing", ".marker", {})


@pytest.mark.parametrize("text", ["abc", "nan", "inf", "-1", "0", "1e300"])
def test_a_megabyte_variable_that_means_nothing_is_refused_by_name(monkeypatch, text):
    from mre_common.env_settings import EnvSettingError, env_megabytes

    monkeypatch.setenv("MRE_COSIM_TEST_MB", text)
    with pytest.raises(EnvSettingError, match="MRE_COSIM_TEST_MB"):
        env_megabytes("MRE_COSIM_TEST_MB", 256)


def test_a_megabyte_variable_in_its_domain_gives_bytes(monkeypatch):
    from mre_common.env_settings import env_megabytes

    monkeypatch.delenv("MRE_COSIM_TEST_MB", raising=False)
    assert env_megabytes("MRE_COSIM_TEST_MB", 256) == 256 * 2**20
    assert env_megabytes("MRE_COSIM_TEST_MB", None) is None
    monkeypatch.setenv("MRE_COSIM_TEST_MB", " 1.5 ")
    assert env_megabytes("MRE_COSIM_TEST_MB", 256) == 3 * 2**19
    monkeypatch.setenv("MRE_COSIM_TEST_MB", "0")
    assert env_megabytes("MRE_COSIM_TEST_MB", 256, zero_ok=True) == 0
