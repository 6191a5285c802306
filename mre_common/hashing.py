"""SHA-256 of a file: the one hasher of the project (run manifests, input checks, caches, batch transfers)."""

from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from pathlib import Path

CHUNK = 1 << 20
"""Bytes read at a time: a file is never held in memory whole."""


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of a file's bytes, read in chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()


@lru_cache(maxsize=4096)
def versioned_sha256(path: str, size: int, mtime_ns: int) -> str:
    """:func:`file_sha256` of ``path``, computed once per (path, size, modification time): the caller's
    ``os.stat`` is the key, so a file rewritten in place is hashed again."""
    return file_sha256(path)


def cached_file_sha256(path: str | os.PathLike[str]) -> str:
    """:func:`file_sha256`, computed once per (resolved path, size, modification time) in this process."""
    st = os.stat(path)
    return versioned_sha256(str(Path(path).resolve()), st.st_size, st.st_mtime_ns)
