"""The project's source files a job's numbers depend on, found from what its module imports.

:func:`import_closure` follows every ``import`` statement of a module (at the top and inside
functions, since jobs import lazily), and of each project module reached, to the project's
files: no hand-written list to forget a module in (an edited in-process executor changes the
key of every job that imports it). Only modules inside the project folder count; installed
packages are named by their versions elsewhere (:func:`orchestration.batch.portable.code_version`).
The graph is read from the source text (:mod:`ast`), so nothing is imported to find it.
"""

from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

from mre_common.project_paths import PROJECT_DIR

MODULE_PREFIX = "module:"
"""A code source given as ``module:<dotted name>`` stands for that module's import closure."""


def module_file(name: str, root: Path = PROJECT_DIR) -> Path | None:
    """The project file of a dotted module name (``pkg/mod.py`` or ``pkg/mod/__init__.py``), or None."""
    base = root.joinpath(*name.split("."))
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _package(name: str, path: Path) -> str:
    """The package a module's relative imports are relative to."""
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _imported(name: str, path: Path) -> set[str]:
    """Every dotted name a module's import statements may load (``from a import b``: ``a`` and ``a.b``)."""
    try:
        tree = ast.parse(path.read_bytes(), filename=str(path))
    except (SyntaxError, ValueError):
        return set()
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = _package(name, path).split(".")
                parts = parts[: len(parts) - (node.level - 1)] if node.level > 1 else parts
                base = ".".join([*parts, *([node.module] if node.module else [])])
            else:
                base = node.module or ""
            out.add(base)
            out.update(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
    return {n for n in out if n}


@lru_cache(maxsize=64)
def import_closure(module: str, root: Path = PROJECT_DIR) -> tuple[str, ...]:
    """The project files (relative to ``root``, sorted) of ``module`` and of every project module it imports,
    directly or through others, with the packages' ``__init__.py`` on the way."""
    seen: dict[str, Path] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        path = module_file(name, root)
        if path is None:
            continue
        seen[name] = path
        parts = name.split(".")
        todo += [".".join(parts[:k]) for k in range(1, len(parts))]  # its packages run first
        todo += sorted(_imported(name, path) - set(seen))
    return tuple(sorted({p.relative_to(root).as_posix() for p in seen.values()}))


def expand(sources: tuple[str, ...], root: Path = PROJECT_DIR) -> tuple[str, ...]:
    """``sources`` with each ``module:<name>`` replaced by that module's :func:`import_closure`."""
    out: list[str] = []
    for entry in sources:
        if entry.startswith(MODULE_PREFIX):
            out += import_closure(entry.removeprefix(MODULE_PREFIX), root)
        else:
            out.append(entry)
    return tuple(dict.fromkeys(out))
