"""Run a case study: ``python orchestration/study.py scenarios/case_study.yaml``.

Records x strategies, each a co-simulation through the master; see
:mod:`orchestration.studies.case_study` for the study folder it writes. Exit codes: 0
every job succeeded; 1 some jobs failed or the study was interrupted (the report lists
them); 2 configuration error (nothing written).
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from orchestration.studies.case_study import main

if __name__ == "__main__":
    raise SystemExit(main())
