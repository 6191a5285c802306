"""Configuration of an identification run (scenarios/identification.yaml) and its validation.

Every key is checked against :data:`SCHEMA`; unknown keys, wrong types and bad values
are reported together, each with its key path (e.g. ``ffoa.n_pop``).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from components.identification.identifiers import IDENTIFIERS
from components.identification.paper_tables import TEST_MATRIX


class ConfigError(ValueError):
    """The configuration is invalid; the message lists every problem with its key path."""


_NUM = (int, float)
# key -> (type(s), default); a nested dict is a sub-schema.
SCHEMA: dict[str, Any] = {
    "data": {
        "source": (str, "synthetic"),
        "folder": ((str, type(None)), None),
        "synthetic": {
            "seed": (int, 20240501),
            "model": (str, "hyperbolic"),
            "repeats": (int, 5),
            "cycles": (int, 10),
            "sampling_hz": (_NUM, 256.0),
            "F0_n": (_NUM, 0.0),
            "include_velocity": (bool, False),
            "write_csv": (bool, False),
            "noise": {
                "force_rel": (_NUM, 0.02),
                "force_abs_n": (_NUM, 0.0),
                "displacement_mm": (_NUM, 0.0),
            },
        },
        "conditions": ((str, list), "all"),
    },
    "fit": {"first_cycle": (int, 1), "cycles": (int, 1)},
    "identifiers": (list, list(IDENTIFIERS)),
    "ffoa": {"n_pop": (int, 50), "n_iter": (int, 300), "step": (_NUM, 0.1), "seed": (int, 1)},
    "structured": {"beta_min": (_NUM, 1e-3), "beta_max": (_NUM, 5.0), "n_grid": (int, 48)},
    "bouc_wen_joint": {"enabled": (bool, True), "max_nfev": (int, 40)},
    "model_selection": {"enabled": (bool, True), "max_nfev": (int, 100)},
    "plant_uncertainty": {"enabled": (bool, True), "samples": (int, 64), "seed": (int, 1)},
    "acceptance": {"window": (int, 50), "rel_tol": (_NUM, 1e-3), "max_nrmse": (_NUM, 0.3)},
    "figures": (bool, True),
    "output": (str, "results/identification"),
}


def _check(node: Any, schema: dict[str, Any], path: str, problems: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if node is None:
        node = {}
    if not isinstance(node, dict):
        problems.append(f"{path or '<top>'}: must be a mapping, got {type(node).__name__}")
        node = {}
    for key in node:
        if key not in schema:
            problems.append(f"{path + '.' if path else ''}{key}: unknown key (known: {', '.join(schema)})")
    for key, spec in schema.items():
        where = f"{path + '.' if path else ''}{key}"
        if isinstance(spec, dict):
            out[key] = _check(node.get(key), spec, where, problems)
            continue
        types, default = spec
        value = node.get(key, copy.deepcopy(default))
        types = types if isinstance(types, tuple) else (types,)
        if isinstance(value, bool) and bool not in types:
            problems.append(f"{where}: must be {' or '.join(t.__name__ for t in types)}, got a boolean")
        elif not isinstance(value, types):
            problems.append(
                f"{where}: must be {' or '.join(t.__name__ for t in types)}, "
                f"got {type(value).__name__} {value!r}"
            )
        out[key] = float(value) if types == _NUM and isinstance(value, _NUM) else value
    return out


@dataclass(frozen=True)
class IdentificationConfig:
    """Validated configuration (plain nested dicts, defaults filled in) and its file."""

    raw: dict[str, Any]
    path: Path | None

    def __getitem__(self, key: str) -> Any:
        return self.raw[key]

    @property
    def conditions(self) -> tuple[tuple[float, float, float], ...] | None:
        """Conditions to identify (None = all present in the data)."""
        c = self.raw["data"]["conditions"]
        return None if c == "all" else tuple(tuple(float(v) for v in item) for item in c)


def validate(doc: Any, path: Path | None = None) -> IdentificationConfig:
    """Check a parsed YAML document against the schema; raises ConfigError listing all problems."""
    problems: list[str] = []
    cfg = _check(doc, SCHEMA, "", problems)
    if not problems:
        _check_data(cfg["data"], problems)
        _check_methods(cfg, problems)
    if problems:
        where = f"{path}: " if path else ""
        raise ConfigError(where + "invalid configuration:\n" + "\n".join(f"  - {p}" for p in problems))
    return IdentificationConfig(cfg, path)


def _check_data(d: dict[str, Any], problems: list[str]) -> None:
    """The ``data`` section (its types already checked): source, synthetic data, conditions."""
    if d["source"] not in ("synthetic", "folder"):
        problems.append(f"data.source: must be 'synthetic' or 'folder', got {d['source']!r}")
    if d["source"] == "folder" and not d["folder"]:
        problems.append("data.folder: required when data.source is 'folder'")
    s = d["synthetic"]
    if s["model"] not in ("hyperbolic", "bouc_wen"):
        problems.append(f"data.synthetic.model: must be 'hyperbolic' or 'bouc_wen', got {s['model']!r}")
    for key, low in (("repeats", 1), ("cycles", 2)):
        if s[key] < low:
            problems.append(f"data.synthetic.{key}: must be >= {low}")
    if s["sampling_hz"] <= 0:
        problems.append("data.synthetic.sampling_hz: must be > 0")
    for key, value in s["noise"].items():
        if value < 0:
            problems.append(f"data.synthetic.noise.{key}: must be >= 0")
    conds = d["conditions"]
    if isinstance(conds, str) and conds != "all":
        problems.append(
            "data.conditions: must be 'all' or a list of [frequency_hz, amplitude_mm, current_a]"
        )
    elif isinstance(conds, list):
        _check_conditions(conds, d["source"] == "synthetic", problems)


def _check_conditions(conds: list[Any], synthetic: bool, problems: list[str]) -> None:
    """Each listed condition a [frequency_hz, amplitude_mm, current_a]; for synthetic data one of the paper's."""
    for k, item in enumerate(conds):
        ok = (
            isinstance(item, list)
            and len(item) == 3
            and all(isinstance(v, _NUM) and not isinstance(v, bool) for v in item)
        )
        if not ok:
            problems.append(f"data.conditions[{k}]: must be [frequency_hz, amplitude_mm, current_a]")
        elif synthetic and tuple(float(v) for v in item) not in TEST_MATRIX:
            problems.append(f"data.conditions[{k}]: {item} is not in the paper's test matrix")


def _check_methods(cfg: dict[str, Any], problems: list[str]) -> None:
    """The sections after ``data`` (their types already checked): fit, identifiers and their settings."""
    if cfg["fit"]["first_cycle"] < 0 or cfg["fit"]["cycles"] < 1:
        problems.append("fit: first_cycle must be >= 0 and cycles >= 1")
    for k, name in enumerate(cfg["identifiers"]):
        if name not in IDENTIFIERS:
            problems.append(
                f"identifiers[{k}]: unknown identifier {name!r} (known: {', '.join(IDENTIFIERS)})"
            )
    if not cfg["identifiers"]:
        problems.append("identifiers: list at least one identifier")
    f = cfg["ffoa"]
    if f["n_pop"] < 2 or f["n_iter"] < 1 or f["step"] <= 0:
        problems.append("ffoa: n_pop must be >= 2, n_iter >= 1, step > 0")
    st = cfg["structured"]
    if not 0 < st["beta_min"] < st["beta_max"] or st["n_grid"] < 3:
        problems.append("structured: need 0 < beta_min < beta_max and n_grid >= 3")
    if cfg["model_selection"]["max_nfev"] < 1:
        problems.append("model_selection.max_nfev: must be >= 1")
    if cfg["plant_uncertainty"]["samples"] < 2:
        problems.append("plant_uncertainty.samples: must be >= 2 (a covariance needs two samples)")
    a = cfg["acceptance"]
    if a["window"] < 1 or a["rel_tol"] < 0 or a["max_nrmse"] <= 0:
        problems.append("acceptance: window must be >= 1, rel_tol >= 0, max_nrmse > 0")


def load_config(path: str | Path) -> IdentificationConfig:
    """Read and validate a YAML configuration file."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from None
    return validate(doc, path)
