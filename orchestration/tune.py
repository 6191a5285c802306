"""Tune the SOSM gains of a study: ``python orchestration/tune.py scenarios/case_study.yaml --force``.

Writes the study's gains file (``scenarios/sosm_gains.yaml``); see
:mod:`orchestration.studies.tuning`. Exit codes: 0 written; 2 configuration error or the
gains file exists without ``--force`` (nothing written).
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from orchestration.studies.tuning import main

if __name__ == "__main__":
    raise SystemExit(main())
