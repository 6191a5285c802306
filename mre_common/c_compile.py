"""Compile a C file with the system compiler, once per content (source, compiler and flags).

:func:`compile_c` runs the compiler (``$CC``, default ``cc``) and turns its two ways of
failing into :class:`CompilerMissing` and :class:`CompileFailed`. :func:`compile_cached`
keeps the resulting shared library in a cache folder (``$MRE_COSIM_CACHE``, default
``~/.cache/mre-cosim``) under a name holding a hash of the source, the compiler's name and
every flag, so it is compiled once and rebuilt when any of them changes; the library is
compiled under a temporary name and renamed, so a concurrent process sees it whole or not at all.
The folder must be this user's private one (:mod:`mre_common.private_cache`: mode 0700, owned,
not a symlink; else a folder of the process's own is used, with a note), and a library is loaded
only if it has the SHA-256 written beside it when it was compiled (else compiled again, noted).
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from mre_common.atomic_files import atomic_write_text
from mre_common.hashing import file_sha256
from mre_common.private_cache import fallback_folder, note, remove_entry, trusted_folder

CACHE_ENV = "MRE_COSIM_CACHE"
"""Environment variable naming the cache folder of compiled libraries."""


class NoCacheFolder(OSError):
    """No cache folder can be named (no ``$MRE_COSIM_CACHE`` and no home folder)."""


class CompilerMissing(FileNotFoundError):
    """The C compiler cannot be started."""

    def __init__(self, compiler: str) -> None:
        super().__init__(f"no C compiler {compiler!r} (set CC)")
        self.compiler = compiler


class CompileFailed(OSError):
    """The compiler ran and failed; ``command`` and ``stderr`` say how."""

    def __init__(self, source: Path, compiler: str, command: list[str], stderr: str) -> None:
        super().__init__(f"compiling {Path(source).name} with {compiler!r} failed: {stderr.strip()}")
        self.source, self.compiler, self.command, self.stderr = Path(source), compiler, command, stderr


def compiler_name() -> str:
    """The C compiler to use: ``$CC``, default ``cc``."""
    return os.environ.get("CC", "cc")


def cache_dir() -> Path:
    """The cache folder of compiled libraries (:class:`NoCacheFolder` if none can be named)."""
    try:
        return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "mre-cosim")
    except (RuntimeError, KeyError) as exc:  # no home folder to put a cache in
        raise NoCacheFolder(f"no cache folder for the kernel (set {CACHE_ENV}): {exc}") from None


def compile_c(source: str | os.PathLike[str], output: str | os.PathLike[str], flags: Sequence[str],
              libs: Sequence[str] = (), compiler: str | None = None) -> list[str]:
    """Run ``compiler *flags source -o output *libs``; the command run.

    Raises :class:`CompilerMissing` if the compiler cannot be started and
    :class:`CompileFailed` if it exits non-zero.
    """
    compiler = compiler or compiler_name()
    command = [compiler, *flags, str(source), "-o", str(output), *libs]
    try:
        done = subprocess.run(command, capture_output=True, text=True, check=False)
    except FileNotFoundError:
        raise CompilerMissing(compiler) from None
    if done.returncode != 0:
        raise CompileFailed(Path(source), compiler, command, done.stderr)
    return command


def cache_key(source: str | os.PathLike[str], flags: Sequence[str], libs: Sequence[str] = (),
              compiler: str | None = None) -> str:
    """16 hex digits of the SHA-256 of the source's bytes, the compiler's name and every flag."""
    text = " ".join((compiler or compiler_name(), *flags, *libs)).encode()
    return hashlib.sha256(Path(source).read_bytes() + text).hexdigest()[:16]


def compile_cached(source: str | os.PathLike[str], flags: Sequence[str], libs: Sequence[str] = (), *,
                   name: str | None = None, folder: str | os.PathLike[str] | None = None,
                   compiler: str | None = None) -> Path:
    """The shared library ``<folder>/<name>-<key>.so`` built from ``source``, compiled only if absent.

    ``name`` defaults to the source's stem, ``folder`` to :func:`cache_dir`, ``compiler`` to
    :func:`compiler_name`; ``key`` is :func:`cache_key`. Raises :class:`NoCacheFolder`,
    :class:`CompilerMissing`, :class:`CompileFailed`, or another OSError (e.g. an unwritable
    folder); nothing is left behind then.
    """
    source = Path(source)
    compiler = compiler or compiler_name()
    stem = name or source.stem
    root = trusted_folder(Path(folder) if folder is not None else cache_dir())
    target = root / f"{stem}-{cache_key(source, flags, libs, compiler)}.so"
    if os.path.lexists(target):
        problem = _library_problem(target)
        if problem is None:
            return target
        note(root, f"{target.name} {problem}: compiling it again")
        remove_entry(target)
    try:
        fd, partial = tempfile.mkstemp(prefix=f".{stem}.", suffix=".so", dir=root)
    except OSError as exc:  # a read-only or full cache: compiled where this process may (noted)
        root = fallback_folder(root, f"cannot be written ({exc.strerror or exc})")
        target = root / target.name
        if target.exists():
            return target
        fd, partial = tempfile.mkstemp(prefix=f".{stem}.", suffix=".so", dir=root)
    os.close(fd)
    try:
        compile_c(source, partial, flags, libs, compiler)
        digest = file_sha256(partial)
        atomic_write_text(_digest_file(target), digest + "\n", mode=0o600)
        os.replace(partial, target)  # atomic: a concurrent process sees the whole library or none
    finally:
        Path(partial).unlink(missing_ok=True)
    return target


def _digest_file(library: Path) -> Path:
    """The file holding a cached library's SHA-256, written when it was compiled."""
    return library.with_name(f".{library.name}.sha256")


def _library_problem(library: Path) -> str | None:
    """Why a cached library is not the one compiled there (a link, not a file, no or another SHA-256), or None."""
    if library.is_symlink() or not library.is_file():
        return "is not a regular file"
    if not _digest_file(library).is_file():
        return "has no SHA-256 recorded beside it (compiled by an older version?)"
    try:
        wanted = _digest_file(library).read_text(encoding="ascii").strip()
        found = file_sha256(library)
    except (OSError, UnicodeError) as exc:
        return f"cannot be verified ({exc.strerror if isinstance(exc, OSError) and exc.strerror else exc})"
    return None if wanted == found else "does not have the SHA-256 written when it was compiled"
