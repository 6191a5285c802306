"""Finished jobs of a study, one JSON file each under ``<study>/jobs/<key>.json``: what ``--resume`` reads.

A job's key is made from its content (:func:`orchestration.batch.portable.job_key`), so a
resumed study reuses exactly the results whose inputs and code are unchanged. Results of
jobs that ran and failed by themselves are kept (they would fail again); jobs lost with
their workers or cancelled are not, so a resume runs them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from orchestration.master.runfolder import write_json

KEPT_STATUSES = ("ok", "failed")


class ResultStore:
    """The ``jobs/`` folder of a study."""

    def __init__(self, study_folder: Path) -> None:
        self.folder = Path(study_folder) / "jobs"
        self.folder.mkdir(parents=True, exist_ok=True)

    def _path(self, key: str) -> Path:
        return self.folder / f"{key}.json"

    def get(self, key: str) -> dict[str, Any] | None:
        """The stored result of a job, or None (absent or unreadable)."""
        try:
            return json.loads(self._path(key).read_text())
        except (OSError, ValueError):
            return None

    def put(self, key: str, record: dict[str, Any]) -> bool:
        """Store a result (atomically) if its status is worth keeping; True if stored."""
        if record.get("status") not in KEPT_STATUSES:
            return False
        write_json(self._path(key), {**record, "key": key})
        return True

    def keys(self) -> set[str]:
        return {p.stem for p in self.folder.glob("*.json")}
