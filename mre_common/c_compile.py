"""Compile a C file with the system compiler, once per content (source, compiler and flags).

:func:`compile_c` runs the compiler (``$CC``, default ``cc``) and turns its two ways of
failing into :class:`CompilerMissing` and :class:`CompileFailed`. :func:`compile_cached`
keeps the resulting shared library in a cache folder (``$MRE_COSIM_CACHE``, default
``~/.cache/mre-cosim``) under a name holding a hash of the source, the compiler's name and
every flag, so it is compiled once and rebuilt when any of them changes; the library is
compiled under a temporary name and renamed, so a concurrent process sees it whole or not at all.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

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
    target = Path(folder) if folder is not None else cache_dir()
    target = target / f"{stem}-{cache_key(source, flags, libs, compiler)}.so"
    if target.exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, partial = tempfile.mkstemp(prefix=f".{stem}.", suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        compile_c(source, partial, flags, libs, compiler)
        os.replace(partial, target)  # atomic: a concurrent process sees the whole library or none
    finally:
        Path(partial).unlink(missing_ok=True)
    return target
