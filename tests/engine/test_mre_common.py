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
    assert sorted(p.name for p in (tmp_path / "cache").iterdir() if not p.name.endswith(".sha256")) == sorted(
        p.name for p in (first, changed, other_flags))  # no temporary file left
    assert sorted(p.name for p in (tmp_path / "cache").iterdir() if p.name.endswith(".sha256")) == sorted(
        f".{p.name}.sha256" for p in (first, changed, other_flags))  # each library's digest beside it


@needs_cc
def test_compile_cached_rebuilds_a_damaged_or_replaced_library_and_names_the_cache(tmp_path, capsys):
    source = tmp_path / "k.c"
    source.write_text("int answer(void) { return 41; }\n")
    flags = ("-shared", "-fPIC", "-O2")
    cache = tmp_path / "cache"
    first = c_compile.compile_cached(source, flags, name="k", folder=cache)
    assert (cache.stat().st_mode & 0o777) == 0o700
    good = first.read_bytes()
    first.write_bytes(good[: len(good) // 2])  # truncated
    again = c_compile.compile_cached(source, flags, name="k", folder=cache)
    assert again == first and again.read_bytes() == good
    assert f"note: cache {cache}" in capsys.readouterr().err
    first.unlink()
    first.symlink_to(tmp_path / "elsewhere.so")  # planted link: never followed, compiled again
    (tmp_path / "elsewhere.so").write_bytes(b"not a library")
    again = c_compile.compile_cached(source, flags, name="k", folder=cache)
    assert not again.is_symlink() and again.read_bytes() == good
    assert (tmp_path / "elsewhere.so").read_bytes() == b"not a library"


def test_a_cache_folder_open_to_others_is_closed_a_link_or_a_file_is_not_used(tmp_path, capsys):
    from mre_common.private_cache import CacheUnusable, private_folder, trusted_folder

    assert (private_folder(tmp_path / "c").stat().st_mode & 0o777) == 0o700
    (tmp_path / "open").mkdir()
    (tmp_path / "open").chmod(0o777)
    (tmp_path / "open" / "planted.so").write_bytes(b"x")
    assert private_folder(tmp_path / "open") == tmp_path / "open"  # others could write into it: emptied, closed
    assert list((tmp_path / "open").iterdir()) == [] and ((tmp_path / "open").stat().st_mode & 0o777) == 0o700
    assert "others could write into it): emptied and made private" in capsys.readouterr().err
    (tmp_path / "readable").mkdir(mode=0o755)
    (tmp_path / "readable").chmod(0o755)
    (tmp_path / "readable" / "kept.so").write_bytes(b"x")
    private_folder(tmp_path / "readable")  # only readable by others (an older version's mode): closed, kept
    assert [p.name for p in (tmp_path / "readable").iterdir()] == ["kept.so"]
    (tmp_path / "link").symlink_to(tmp_path / "c")
    (tmp_path / "file").write_text("x")
    for name in ("link", "file"):
        with pytest.raises(CacheUnusable, match=f"cache {tmp_path / name}"):
            private_folder(tmp_path / name)
        used = trusted_folder(tmp_path / name)
        assert used != tmp_path / name and (used.stat().st_mode & 0o777) == 0o700
        assert f"note: cache {tmp_path / name}" in capsys.readouterr().err
        used.rmdir()


def test_a_manifest_catches_a_changed_missing_extra_or_linked_file(tmp_path):
    from mre_common.private_cache import manifest_problem, write_manifest

    entry = tmp_path / "e"
    (entry / "sub").mkdir(parents=True)
    (entry / "a.so").write_bytes(b"library")
    (entry / "sub" / "b.py").write_text("print(1)")
    write_manifest(entry, "abc")
    assert manifest_problem(entry, "abc") is None
    assert "not from" in manifest_problem(entry, "other")
    (entry / "a.so").write_bytes(b"librarX")
    assert "a.so" in manifest_problem(entry, "abc")
    (entry / "a.so").write_bytes(b"library")
    (entry / "sub" / "c.py").write_text("import os")
    assert "sub/c.py" in manifest_problem(entry, "abc")
    (entry / "sub" / "c.py").unlink()
    (entry / "sub" / "b.py").unlink()
    (entry / "sub" / "b.py").symlink_to(tmp_path / "elsewhere.py")
    assert "not a regular file" in manifest_problem(entry, "abc")


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


def test_an_own_file_or_link_at_a_cache_name_in_the_temporary_folder_is_replaced_not_followed(tmp_path, monkeypatch,
                                                                                            capsys):
    import tempfile

    from mre_common.private_cache import private_folder

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    (tmp_path / "target").mkdir()
    (tmp_path / "mre-cosim-files-x").symlink_to(tmp_path / "target")
    (tmp_path / "mre-cosim-files-y").write_text("x")
    for name in ("mre-cosim-files-x", "mre-cosim-files-y"):
        folder = private_folder(tmp_path / name)
        assert folder.is_dir() and not folder.is_symlink() and (folder.stat().st_mode & 0o777) == 0o700
        assert f"note: cache {tmp_path / name}: was a" in capsys.readouterr().err
    assert list((tmp_path / "target").iterdir()) == []


def test_the_file_hasher_is_sha256_in_chunks_and_its_cache_follows_a_rewrite(tmp_path):
    import hashlib

    from mre_common import hashing

    path = tmp_path / "big.bin"
    data = os.urandom(hashing.CHUNK * 2 + 17)  # more than one chunk, not a whole number of them
    path.write_bytes(data)
    assert hashing.file_sha256(path) == hashing.file_sha256(str(path)) == hashlib.sha256(data).hexdigest()
    assert hashing.cached_file_sha256(path) == hashlib.sha256(data).hexdigest()
    path.write_bytes(b"other")  # another size: hashed again, not served from the cache
    assert hashing.cached_file_sha256(path) == hashlib.sha256(b"other").hexdigest()
    (tmp_path / "empty").write_bytes(b"")
    assert hashing.file_sha256(tmp_path / "empty") == hashlib.sha256(b"").hexdigest()


def test_the_engine_and_the_batch_layer_use_the_one_hasher():
    from mre_common import hashing, private_cache
    from orchestration.batch import portable
    from orchestration.master import fmu_loading, runfolder

    assert runfolder.sha256 is hashing.file_sha256
    assert private_cache.file_sha256 is hashing.file_sha256
    assert fmu_loading._archive_sha256 is hashing.versioned_sha256
    assert portable.file_sha256 is hashing.cached_file_sha256


def test_the_console_and_the_guard_share_one_exit_code_table():
    from mre_common import guard
    from orchestration import console

    assert console.EXIT_USAGE is guard.EXIT_USAGE == 2
    assert (guard.EXIT_OK, guard.EXIT_FAILED, guard.EXIT_BUG, guard.EXIT_INTERRUPTED) == (0, 1, 3, 130)
    assert console.main(["no-such-tool"]) == guard.EXIT_USAGE
