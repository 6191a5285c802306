"""A study file as the study tools read it: ``--set KEY=VALUE`` overrides into its data, and which file of an
``extends`` chain wrote each key (relative paths are relative to that file)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.yaml_source import YAML_BOOLEANS, load_tree

REPLACED_KEYS = frozenset({"records"})  # a study that extends another and names records runs those only


def declares_section(argv: list[str], key: str) -> bool:
    """Whether the study a command line names (its first positional argument) has a top-level ``key`` section,
    or the line sets one with ``--set key...``; False if the file cannot be read (the tool it goes to says why)."""
    import argparse

    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("study", nargs="?")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    known, _ = parser.parse_known_args(argv)
    if any(o.split("=", 1)[0].strip().split(".")[0] == key for o in known.overrides):
        return True
    if known.study is None:
        return False
    try:
        data, _ = load_tree(Path(known.study), replace=REPLACED_KEYS)
    except Exception:
        return False
    return isinstance(data, dict) and key in data


def key_files(study_file: Path) -> dict:
    """Which file of an ``extends`` chain wrote each key of a study file (relative paths are relative to it), as
    it reads now; empty if it cannot be read (the paths are then relative to the study file). For ``--resume``."""
    try:
        return load_tree(study_file, replace=REPLACED_KEYS)[1]
    except (ScenarioError, OSError, ValueError):
        return {}


def apply_overrides(data: dict[str, Any], lines: dict, overrides: tuple[str, ...]) -> None:
    """``KEY=VALUE`` (VALUE as YAML) into the study's data; ScenarioError for a malformed one."""
    for assignment in overrides:
        key, sep, text = assignment.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(Problem("expected KEY=VALUE", "", f"--set {assignment}"))
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise ScenarioError(Problem(f"value is not YAML: {exc}", key, f"--set {assignment}")) from None
        if isinstance(value, bool) and text.strip() not in YAML_BOOLEANS:
            raise ScenarioError(Problem(f"{text.strip()!r} is a YAML 1.1 boolean: write true or false", key,
                                        f"--set {assignment}"))
        node = data
        parts = key.strip().split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ScenarioError(Problem(f"'{part}' is not a mapping", key, f"--set {assignment}"))
        node[parts[-1]] = value
        lines[tuple(parts)] = (f"--set {assignment}", None)
