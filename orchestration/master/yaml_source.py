"""YAML documents with the file and line of every key, ``extends`` and ``--set`` overrides.

``load_tree(path)`` returns plain Python data plus a map from key path (a tuple) to
(file, line), so that every later problem can point at the line a user wrote. A scalar
tagged ``!data`` or ``!record`` becomes a :class:`DataFile` of that kind, found later
through the data path; the application may check a kind before any unit is loaded (the
project reads every ``!record`` as a ground-motion record).
Duplicate keys are errors (plain PyYAML silently keeps the last one).

Hostile input is bounded: only regular files of at most :data:`MAX_FILE_BYTES` are read
(a FIFO or a device would block or never end), the text must be UTF-8, nesting is at
most :data:`MAX_DEPTH` levels, aliases may expand to at most :data:`MAX_NODES` values (a
few hundred bytes of anchors can otherwise expand to billions) and may not refer to
themselves, and an ``extends`` chain is at most :data:`MAX_EXTENDS` files long. Each is a
ScenarioError naming the file.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from orchestration.master.errors import Problem, ScenarioError

KeyPath = tuple[Any, ...]
Lines = dict[KeyPath, tuple[str, int | None]]

MAX_FILE_BYTES = 4 * 1024 * 1024
"""Largest scenario (or study) file read; the project's are a few kB."""
MAX_DEPTH = 64
"""Deepest nesting of mappings and lists (after alias expansion)."""
MAX_NODES = 20_000
"""Most values a document may expand to (aliases included)."""
MAX_EXTENDS = 32
"""Longest ``extends`` chain."""


@dataclass(frozen=True)
class DataFile:
    """A data file named in a scenario, resolved through the data-directory search path."""

    name: str
    kind: str = "data"  # the tag without "!": "data" (any file) or "record" (checked by the application)

    def __str__(self) -> str:
        return f"!{self.kind} {self.name}"


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 numbers: ``1e-3`` is a number (YAML 1.1 wants ``1.0e-3``), while
    ``1_0``, ``017``, ``0x1F`` and ``1:30`` are text, not 10, 15, 31 and 90 (a typo is reported, not
    reinterpreted)."""


_Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in ("tag:yaml.org,2002:int",
                                                                      "tag:yaml.org,2002:float")]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_Loader.add_implicit_resolver("tag:yaml.org,2002:int", re.compile(r"^[-+]?(?:0|[1-9][0-9]*)$"),
                              list("-+0123456789"))
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+0123456789."))


class _Budget:
    """Values constructed so far and the nodes being constructed (to find aliases that contain themselves)."""

    def __init__(self) -> None:
        self.nodes = 0
        self.open: set[int] = set()


YAML_BOOLEANS = ("true", "false", "True", "False", "TRUE", "FALSE")
"""The booleans of YAML 1.2; PyYAML's 1.1 resolver also reads yes/no/on/off/y/n as booleans, which are refused."""


def _construct(node: yaml.Node, path: KeyPath, lines: Lines, file: str, problems: list[Problem],
               budget: _Budget | None = None) -> Any:
    budget = budget if budget is not None else _Budget()
    budget.nodes += 1
    line = node.start_mark.line + 1
    if budget.nodes > MAX_NODES:
        raise ScenarioError(Problem(f"the document expands to more than {MAX_NODES:,} values (aliases "
                                    "repeating anchors?); refusing to read it", _short(path), file, line))
    if len(path) > MAX_DEPTH:
        raise ScenarioError(Problem(f"nested more than {MAX_DEPTH} levels deep", _short(path), file, line))
    if id(node) in budget.open:
        raise ScenarioError(Problem("an alias refers to the anchor that contains it (a recursive structure)",
                                    _short(path), file, line))
    lines.setdefault(path, (file, line))
    if isinstance(node, yaml.MappingNode | yaml.SequenceNode):
        budget.open.add(id(node))
        try:
            return _collection(node, path, lines, file, problems, budget)
        finally:
            budget.open.discard(id(node))
    if node.tag in ("!data", "!record") and isinstance(node, yaml.ScalarNode):
        return DataFile(str(node.value), node.tag[1:])
    if node.tag.startswith("!"):
        problems.append(Problem(f"unknown tag {node.tag} (known: !data, !record)", _dotted(path), file, line))
        return None
    if node.tag == "tag:yaml.org,2002:bool" and node.value not in YAML_BOOLEANS:
        problems.append(Problem(f"{node.value!r} is a YAML 1.1 boolean: write true or false (or quote it for "
                                "text)", _dotted(path), file, line))
        return None
    loader = yaml.SafeLoader("")
    try:
        return loader.construct_object(node)
    except (yaml.YAMLError, ValueError, TypeError, OverflowError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if "Exceeds the limit" in reason:  # int(): more than sys.get_int_max_str_digits() digits
            reason = "an integer with too many digits"
        problems.append(Problem(f"cannot read value: {reason}", _dotted(path), file, line))
        return None


def _collection(node: yaml.MappingNode | yaml.SequenceNode, path: KeyPath, lines: Lines, file: str,
                problems: list[Problem], budget: _Budget) -> Any:
    if isinstance(node, yaml.SequenceNode):
        return [_construct(item, (*path, k), lines, file, problems, budget) for k, item in enumerate(node.value)]
    out: dict[Any, Any] = {}
    for key_node, value_node in node.value:
        if not isinstance(key_node, yaml.ScalarNode):
            problems.append(Problem("keys must be plain names", _dotted(path), file, key_node.start_mark.line + 1))
            continue
        key = key_node.value
        if key in out:
            problems.append(Problem("duplicate key", _dotted((*path, key)), file, key_node.start_mark.line + 1))
            continue
        lines[(*path, key)] = (file, key_node.start_mark.line + 1)
        out[key] = _construct(value_node, (*path, key), lines, file, problems, budget)
    return out


def _short(path: KeyPath, keep: int = 6) -> str:
    """A key path for a message, its middle elided when deep."""
    return _dotted(path) if len(path) <= keep else f"{_dotted(path[:3])}...{_dotted(path[-2:])}"


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
        _check_depth(text, file)  # before composing: PyYAML's composer recurses once per level
        node = yaml.compose(text, Loader=_Loader)
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


def _check_depth(text: str, file: str) -> None:
    """ScenarioError if the document nests deeper than MAX_DEPTH (read as events: no recursion)."""
    depth = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > MAX_DEPTH:
                line = event.start_mark.line + 1 if event.start_mark is not None else None
                raise ScenarioError(Problem(f"nested more than {MAX_DEPTH} levels deep", "", file, line))
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1


def read_text_file(path: Path, what: str = "scenario file", limit: int = MAX_FILE_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes; ScenarioError naming the file otherwise.

    A FIFO, a device (``/dev/zero``) or a folder is refused before it is opened for
    reading, so nothing blocks or reads without end.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ScenarioError(Problem(f"cannot read {what} {path}: {exc.strerror or exc}", "")) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a FIFO" if stat.S_ISFIFO(info.st_mode) else \
                "a device or special file"
            raise ScenarioError(Problem(f"cannot read {what} {path}: {kind}, not a regular file", ""))
        if info.st_size > limit:
            raise ScenarioError(Problem(f"{what} {path} is {info.st_size:,} bytes, more than the {limit:,} "
                                        "allowed", ""))
        chunks = []
        size = 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise ScenarioError(Problem(f"cannot read {what} {path}: {exc.strerror or exc}", "")) from None
    finally:
        os.close(fd)
    data = b"".join(chunks)
    if len(data) > limit:
        raise ScenarioError(Problem(f"{what} {path} is more than {limit:,} bytes", ""))
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ScenarioError(Problem(f"not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                                    "save the file as UTF-8", "", str(path), line)) from None


def resolved(path: Path | str) -> Path:
    """The absolute path with symbolic links resolved; a symlink loop is left as it is (reading it fails clearly)."""
    try:
        return Path(path).resolve()
    except (RuntimeError, OSError):  # "Symlink loop" (RuntimeError before Python 3.13)
        return Path(os.path.abspath(path))


def merge(base: Any, override: Any) -> Any:
    """Deep merge: mappings merge key by key, anything else (lists too) is replaced."""
    if isinstance(base, dict) and isinstance(override, dict):
        out = dict(base)
        for key, value in override.items():
            out[key] = merge(base[key], value) if key in base else value
        return out
    return override


def load_tree(path: Path, _seen: tuple[Path, ...] = (), replace: frozenset[str] = frozenset()
              ) -> tuple[dict[str, Any], Lines]:
    """Read a scenario file and the chain of files it ``extends``, merged; with key lines.

    A top-level key in ``replace`` that a file sets replaces what the files it extends set, whole, instead of
    merging with it (a study's ``records``: the records a study names are its records)."""
    path = resolved(path)
    if path in _seen:
        chain = " -> ".join(str(p) for p in (*_seen, path))
        raise ScenarioError(Problem(f"'extends' loops: {chain}", "extends", str(path)))
    if len(_seen) >= MAX_EXTENDS:
        raise ScenarioError(Problem(f"'extends' chain longer than {MAX_EXTENDS} files", "extends", str(_seen[-1])))
    try:
        text = read_text_file(path)
    except ScenarioError as exc:
        if not _seen:
            raise
        message = exc.problems[0].message
        if str(path) not in message:
            message = f"{path}: {message}"
        raise ScenarioError(Problem(message, "extends", str(_seen[-1]))) from None
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
    base, base_lines = load_tree(path.parent / parent, (*_seen, path), replace)
    replaced = {key for key in replace if key in data}
    if replaced:
        base = {k: v for k, v in base.items() if k not in replaced}
        base_lines = {k: v for k, v in base_lines.items() if not (k and k[0] in replaced)}
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
