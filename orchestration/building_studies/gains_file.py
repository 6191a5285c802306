"""A SOSM gains file (``scenarios/sosm_gains.yaml``, written by ``orchestration/tune.py``), read back."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from components.physics.sosm_controller_core import SosmGains
from orchestration.master.errors import ScenarioError


def read_gains(path: Path) -> tuple[SosmGains, dict[str, Any]]:
    """Gains and the whole document from a gains file; raises ScenarioError if missing or invalid."""
    if not path.is_file():
        raise ScenarioError(f"SOSM gains file {path} does not exist: run "
                            f"'python orchestration/tune.py <study.yaml>' first (see docs/case_study.md)")
    try:
        doc = yaml.safe_load(path.read_text())
        g = doc["gains"]
        gains = SosmGains(lam=float(g["lambda"]), rho=float(g["rho"]), zeta=float(g["zeta"]),
                          theta=float(g["theta"]), i_max=float(g["i_max"]), s_release=float(g.get("s_release", 0.0)))
    except (yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{path}: not a valid SOSM gains file ({exc})") from None
    return gains, doc
