"""The plumbing of a job that runs a plan on a Dask worker (:mod:`orchestration.batch.pool`).

Every payload carries a :class:`~orchestration.batch.portable.PortablePlan` and the bytes of
the files it names (``"files"``: SHA-256 -> bytes, shared handles resolved by Dask), so no
job reads the client's file system: :func:`job_plan` puts the files into the worker's cache
and returns the plan with its paths there. :func:`run_folder` runs a plan into a temporary
run folder and returns it whole; :func:`write_run_files` writes such a folder on the client.
The jobs themselves live with their studies (``case_study.case_jobs``, ``ida_study.ida_jobs``).
"""

from __future__ import annotations

import os
import tempfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mre_common.atomic_files import atomic_write_bytes


def job_plan(payload: dict[str, Any], parameters: dict[str, dict[str, Any]] | None = None
             ) -> tuple[Any, dict[str, str]]:
    """The payload's plan with its files in this machine's cache (``parameters`` set on top); also
    {local path: client path}."""
    from orchestration.batch.portable import relocate

    return relocate(payload["plan"], payload["files"], parameters)


def _localize(text: str, paths: dict[str, str]) -> str:
    for local, client in paths.items():
        text = text.replace(local, client)
    return text


def run_folder_prefix(pid: int) -> str:
    """Prefix of the temporary run folder of the process ``pid``: a killed job's folder is found and removed
    by its parent (:func:`orchestration.batch.child.call_in_child`)."""
    return f"mre-cosim-run-{pid}-"


def run_folder(payload: dict[str, Any], results_file: bool = True,
               add_files: Callable[[Any, Any, Path], None] | None = None) -> tuple[Any, dict[str, bytes]]:
    """Run the payload's plan; its outcome and its run folder's files (zlib-compressed), by name.

    The run folder is written in a temporary folder of the worker; the paths of the worker's
    file cache in its JSON files (``manifest.json``, ``summary.json``) are replaced by the
    client's paths (the SHA-256 in the manifest names the same bytes). ``results_file=False``: the run writes no
    time series (:func:`~orchestration.master.session.run_plan`). ``add_files(plan, outcome, folder)`` may write
    more files into the folder before it is sent (a study's numbers, computed from the recorder's every step).
    """
    from orchestration.master.session import run_plan

    plan, paths = job_plan(payload)
    with tempfile.TemporaryDirectory(prefix=run_folder_prefix(os.getpid())) as tmp:
        folder = Path(tmp) / "run"
        outcome = run_plan(plan, folder, plots=False, progress=False, results_file=results_file)
        if add_files is not None:
            add_files(plan, outcome, folder)
        files = {}
        for f in sorted(folder.iterdir()):
            if f.is_file():
                data = f.read_bytes()
                if f.suffix == ".json":
                    data = _localize(data.decode(), paths).encode()
                files[f.name] = zlib.compress(data, 1)
    return outcome, files


def write_run_files(folder: Path, files: dict[str, bytes]) -> None:
    """Write a run folder sent back by :func:`run_folder` (each file to a temporary name, then renamed).

    ``summary.json`` is written last, after ``manifest.json``, as :func:`~orchestration.master.session.run_plan`
    does: if a write fails (a full disk), the OSError propagates and the folder holds no summary that says
    complete (one left from before is removed), so it never looks complete without being so.
    """
    folder.mkdir(parents=True, exist_ok=True)
    last = ("manifest.json", "summary.json")
    order = [n for n in files if n not in last] + [n for n in last if n in files]
    try:
        for name in order:
            atomic_write_bytes(folder / name, zlib.decompress(files[name]), mode=0o644)
    except OSError:
        (folder / "summary.json").unlink(missing_ok=True)
        raise
