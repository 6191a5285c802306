"""YAML documents with the file and line of every key, ``extends`` and ``--set`` overrides.

``load_tree(path)`` returns plain Python data plus a map from key path (a tuple) to
(file, line), so that every later problem can point at the line a user wrote. A scalar
tagged ``!data`` or ``!record`` becomes a :class:`DataFile` of that kind, found later
through the data path; the application may check a kind before any unit is loaded (the
project reads every ``!record`` as a ground-motion record).
Duplicate keys are errors (plain PyYAML silently keeps the last one).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from orchestration.master.errors import Problem, ScenarioError

KeyPath = tuple[Any, ...]
Lines = dict[KeyPath, tuple[str, int | None]]


@dataclass(frozen=True)
class DataFile:
    """A data file named in a scenario, resolved through the data-directory search path."""

    name: str
    kind: str = "data"  # the tag without "!": "data" (any file) or "record" (checked by the application)

    def __str__(self) -> str:
        return f"!{self.kind} {self.name}"


def _construct(node: yaml.Node, path: KeyPath, lines: Lines, file: str, problems: list[Problem]) -> Any:
    lines.setdefault(path, (file, node.start_mark.line + 1))
    if isinstance(node, yaml.MappingNode):
        out: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                problems.append(Problem("keys must be plain names", _dotted(path), file, key_node.start_mark.line + 1))
                continue
            key = key_node.value
            if key in out:
                problems.append(
                    Problem("duplicate key", _dotted((*path, key)), file, key_node.start_mark.line + 1)
                )
                continue
            lines[(*path, key)] = (file, key_node.start_mark.line + 1)
            out[key] = _construct(value_node, (*path, key), lines, file, problems)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_construct(item, (*path, k), lines, file, problems) for k, item in enumerate(node.value)]
    if node.tag in ("!data", "!record") and isinstance(node, yaml.ScalarNode):
        return DataFile(str(node.value), node.tag[1:])
    if node.tag.startswith("!"):
        problems.append(Problem(f"unknown tag {node.tag} (known: !data, !record)", _dotted(path), file,
                                node.start_mark.line + 1))
        return None
    loader = yaml.SafeLoader("")
    try:
        return loader.construct_object(node)
    except yaml.YAMLError as exc:
        problems.append(Problem(f"cannot read value: {exc}", _dotted(path), file, node.start_mark.line + 1))
        return None


def _dotted(path: KeyPath) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def dotted(path: KeyPath) -> str:
    """Key path as users write it: ``units.ground.parameters.scale``, ``connections[2]``."""
    return _dotted(path)


def parse_text(text: str, file: str, path: KeyPath = ()) -> tuple[Any, Lines]:
    """Parse one YAML document; raises ScenarioError with every problem found."""
    problems: list[Problem] = []
    lines: Lines = {}
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        reason = getattr(exc, "problem", None) or str(exc)
        raise ScenarioError(Problem(f"not valid YAML: {reason}", "", file, line)) from None
    if node is None:
        return None, lines
    data = _construct(node, path, lines, file, problems)
    if problems:
        raise ScenarioError(problems)
    return data, lines


def merge(base: Any, override: Any) -> Any:
    """Deep merge: mappings merge key by key, anything else (lists too) is replaced."""
    if isinstance(base, dict) and isinstance(override, dict):
        out = dict(base)
        for key, value in override.items():
            out[key] = merge(base[key], value) if key in base else value
        return out
    return override


def load_tree(path: Path, _seen: tuple[Path, ...] = ()) -> tuple[dict[str, Any], Lines]:
    """Read a scenario file and the chain of files it ``extends``, merged; with key lines."""
    path = Path(path).resolve()
    if path in _seen:
        chain = " -> ".join(str(p) for p in (*_seen, path))
        raise ScenarioError(Problem(f"'extends' loops: {chain}", "extends", str(path)))
    try:
        text = path.read_text()
    except OSError as exc:
        where = str(_seen[-1]) if _seen else ""
        raise ScenarioError(Problem(f"cannot read scenario file {path}: {exc.strerror}", "extends" if _seen else "",
                                    where)) from None
    data, lines = parse_text(text, str(path))
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ScenarioError(Problem("a scenario must be a mapping of keys", "", str(path), 1))
    parent = data.pop("extends", None)
    if parent is None:
        return data, lines
    if not isinstance(parent, str):
        file, line = lines[("extends",)]
        raise ScenarioError(Problem("must be the path of another scenario file", "extends", file, line))
    base, base_lines = load_tree(path.parent / parent, (*_seen, path))
    return merge(base, data), {**base_lines, **lines}


def apply_override(data: dict[str, Any], lines: Lines, assignment: str, unit_names: set[str]) -> None:
    """Apply ``KEY=VALUE`` (VALUE read as YAML). ``UNIT.PARAM=V`` sets a unit parameter."""
    source = f"--set {assignment}"
    if "=" not in assignment:
        raise ScenarioError(Problem("expected KEY=VALUE", "", source))
    key, _, text = assignment.partition("=")
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise ScenarioError(Problem("empty key", "", source))
    if parts[0] in unit_names and parts[0] not in data and len(parts) == 2:
        parts = ["units", parts[0], "parameters", parts[1]]
    value, _ = parse_text(text, source, tuple(parts))
    node = data
    for part in parts[:-1]:
        child = node.get(part) if isinstance(node, dict) else None
        if child is None:
            child = node[part] = {}
        if not isinstance(child, dict):
            raise ScenarioError(Problem(f"'{part}' is not a mapping", ".".join(parts), source))
        node = child
    node[parts[-1]] = value
    for k in range(1, len(parts) + 1):
        prefix = tuple(parts[:k])
        if k == len(parts) or prefix not in lines:
            lines[prefix] = (source, None)


def locate(lines: Lines, path: KeyPath) -> tuple[str, int | None]:
    """File and line of the longest known prefix of a key path."""
    for k in range(len(path), -1, -1):
        hit = lines.get(tuple(path[:k]))
        if hit is not None:
            return hit
    return "", None
