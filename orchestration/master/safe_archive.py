"""Zip archives (FMUs, SSP packages) opened and extracted within limits.

:func:`check_archive` refuses an archive with more than :data:`MAX_ENTRIES` entries or more
than :func:`unpacked_limit` uncompressed, or with an entry that is a link or would land
outside the extraction folder; :func:`safe_extract` extracts under the same limits and never
writes more than the sizes declared.
"""

from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path

from mre_common.env_settings import EnvSettingError, env_megabytes

MAX_ENTRIES = 10_000
"""Most entries an FMU or SSP archive may have."""
UNPACKED_ENV = "MRE_COSIM_MAX_UNPACKED_MB"
"""Environment variable: the most an FMU or SSP archive may unpack to [MiB] (default 256)."""


DEFAULT_UNPACKED_MB = 256

MAX_UNPACKED_BYTES: int | None = None
"""Most bytes an FMU or SSP archive may unpack to; None: :func:`unpacked_limit` (read when an archive is checked)."""


def unpacked_limit() -> int:
    """Most bytes an archive may unpack to: ``MRE_COSIM_MAX_UNPACKED_MB`` (default 256 MiB), read now.

    EnvSettingError (naming the variable) when it is not a finite number of MiB above 0.
    """
    if MAX_UNPACKED_BYTES is not None:
        return MAX_UNPACKED_BYTES
    limit = env_megabytes(UNPACKED_ENV, DEFAULT_UNPACKED_MB)
    assert limit is not None
    return limit


class ArchiveError(ValueError):
    """A zip archive (FMU or SSP package) that is refused: too large, too many entries, or escaping paths."""


def _unsafe_name(name: str) -> str | None:
    """Why an archive entry name may not be extracted, or None."""
    if "\\" in name or "\x00" in name:
        return "a backslash or NUL in the name"
    if name.startswith("/") or (len(name) > 1 and name[1] == ":"):
        return "an absolute path"
    if ".." in name.split("/"):
        return "'..' in the path"
    return None


def check_archive(z: zipfile.ZipFile, path: Path | str, max_bytes: int | None = None,
                  max_entries: int | None = None) -> int:
    """ArchiveError unless every entry may be extracted within the limits (default: the module's); returns the
    unpacked size."""
    if max_bytes is None:
        try:
            max_bytes = unpacked_limit()
        except EnvSettingError as exc:
            raise ArchiveError(f"{path}: not opened: {exc}") from None
    max_entries = MAX_ENTRIES if max_entries is None else max_entries
    infos = z.infolist()
    if len(infos) > max_entries:
        raise ArchiveError(f"{path}: {len(infos):,} entries, more than the {max_entries:,} allowed")
    total = 0
    for info in infos:
        why = _unsafe_name(info.filename)
        if why is None and stat.S_ISLNK(info.external_attr >> 16):
            why = "a symbolic link"
        if why is not None:
            raise ArchiveError(f"{path}: entry {info.filename!r} is refused ({why})")
        total += info.file_size
    if total > max_bytes:
        raise ArchiveError(f"{path}: unpacks to {total:,} bytes, more than the {max_bytes:,} allowed "
                           f"({UNPACKED_ENV} sets the limit in MiB)")
    return total


def safe_extract(z: zipfile.ZipFile, target: Path | str, path: Path | str, max_bytes: int | None = None,
                 max_entries: int | None = None) -> None:
    """Extract every entry into ``target`` after :func:`check_archive`; never writes more than the sizes declared."""
    check_archive(z, path, max_bytes, max_entries)
    root = Path(target).resolve()
    for info in z.infolist():
        dest = root.joinpath(*[p for p in info.filename.split("/") if p])
        if dest != root and root not in dest.parents:
            raise ArchiveError(f"{path}: entry {info.filename!r} would land outside the extraction folder")
        if info.is_dir():
            dest.mkdir(parents=True, exist_ok=True)
            continue
        dest.parent.mkdir(parents=True, exist_ok=True)
        left = info.file_size
        with z.open(info) as src, open(dest, "wb") as out:
            while left > 0:
                chunk = src.read(min(1 << 20, left))
                if not chunk:
                    break
                out.write(chunk)
                left -= len(chunk)
        mode = (info.external_attr >> 16) & 0o777
        if mode:
            os.chmod(dest, mode | 0o600)
