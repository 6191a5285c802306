"""The layout's import rules, read from the source (every import statement, also inside functions).

* ``mre_common`` (atomic writes, C compile-and-cache, folder claims, the CLI guard) imports nothing of ours.
* ``orchestration.master`` (the engine) imports only itself and ``mre_common``: no ``components``, no application.
* ``orchestration.interop`` imports the engine and itself; ``orchestration.batch`` (the Dask layer) the engine
  and itself, no study; ``orchestration.inprocess`` the engine and the physics cores.
* ``components`` never imports ``orchestration``; ``components.physics`` imports only itself.
* A pythonfmu shell imports, by bare name, only physics cores that travel in its FMU.
* No import cycle anywhere; no engine module mentions the building; no two modules share a file name.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

from .conftest import PROJECT

PACKAGES = ("orchestration", "components", "mre_common")
COMMON = "mre_common"
ENGINE = "orchestration.master"
# module prefix -> prefixes of project modules it may import (the most specific prefix applies)
RULES = {
    COMMON: (COMMON,),
    ENGINE: (ENGINE, COMMON),
    "orchestration.interop": (ENGINE, "orchestration.interop", COMMON),
    "orchestration.batch": (ENGINE, "orchestration.batch", COMMON),
    "orchestration.inprocess": (ENGINE, "orchestration.inprocess", "components.physics", COMMON),
    "orchestration.identification": ("orchestration.identification", "orchestration.batch", ENGINE,
                                     "components.identification", "components.physics", COMMON),
    "components.physics": ("components.physics",),
    "components": ("components", COMMON),
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PROJECT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def project_sources() -> dict[str, str]:
    """Module name -> source of every Python module of the two packages."""
    return {module_name(p): p.read_text() for pkg in PACKAGES for p in sorted((PROJECT / pkg).rglob("*.py"))}


def imports_of(name: str, source: str) -> set[str]:
    """Project modules a module imports (absolute and relative imports; ``from pkg import mod`` as ``pkg.mod``)."""
    found: set[str] = set()
    package = name if name.endswith("__init__") else name.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names)
    return {m for m in found if m.split(".")[0] in PACKAGES}


def graph(sources: dict[str, str]) -> dict[str, set[str]]:
    """Module -> the project modules it imports (names that are not modules are dropped)."""
    return {n: {m for m in imports_of(n, s) if m in sources and m != n} for n, s in sources.items()}


FORBIDDEN = {"orchestration.case_study": ("orchestration.ida_study",)}
"""Applications that may import much, but not this: IDA builds on the case study, never the reverse."""


def violations(sources: dict[str, str]) -> list[str]:
    """Every import that breaks RULES or FORBIDDEN."""
    out = []
    for name, targets in sorted(graph(sources).items()):
        for prefix, banned in FORBIDDEN.items():
            if name == prefix or name.startswith(prefix + "."):
                out += [f"{name} imports {t}" for t in sorted(targets)
                        if any(t == b or t.startswith(b + ".") for b in banned)]
    for name, targets in sorted(graph(sources).items()):
        rule = max((p for p in RULES if name == p or name.startswith(p + ".")), key=len, default=None)
        if rule is None:
            continue
        allowed = RULES[rule]
        out += [f"{name} imports {t}" for t in sorted(targets)
                if not any(t == a or t.startswith(a + ".") for a in allowed) and not rule.startswith(t)]
    return out


def cycles(sources: dict[str, str]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    g = graph(sources)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(g)))

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on.discard(w)
                scc.append(w)
                if w == v:
                    break
            if len(scc) > 1:
                found.append(sorted(scc))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return found


def test_engine_and_physics_keep_their_import_rules():
    assert violations(project_sources()) == []


def test_no_import_cycles():
    assert cycles(project_sources()) == []


def test_the_rules_catch_an_engine_module_that_imports_components():
    sources = project_sources()
    sources["orchestration.master.execution"] += "\nfrom components.physics.mre_isolator_core import IsolatorLaw\n"
    sources["orchestration.master.recorder"] += "\ndef f():\n    from orchestration.case_study.case_metrics import x\n"
    sources["orchestration.batch.pool"] += "\nimport orchestration.ida_study.fragility\n"
    sources["orchestration.case_study.claims"] += "\nimport orchestration.ida_study.fragility\n"
    assert sorted(violations(sources)) == [
        "orchestration.batch.pool imports orchestration.ida_study.fragility",
        "orchestration.case_study.claims imports orchestration.ida_study.fragility",
        "orchestration.master.execution imports components.physics.mre_isolator_core",
        "orchestration.master.recorder imports orchestration.case_study.case_metrics",
    ]


def test_the_cycle_check_catches_a_cycle():
    sources = project_sources()
    sources["orchestration.master.unit"] += "\nfrom orchestration.master import algorithm\n"
    assert any({"orchestration.master.algorithm", "orchestration.master.unit"} <= set(c) for c in cycles(sources))


@pytest.mark.parametrize("shell", sorted(p.name for p in (PROJECT / "components" / "shells").glob("*_fmu.py")))
def test_shells_import_only_their_own_physics_cores(shell):
    tree = ast.parse((PROJECT / "components" / "shells" / shell).read_text())
    cores = {p.stem for p in (PROJECT / "components" / "physics").glob("*.py")}
    cores |= {p.stem for p in (PROJECT / "components" / "shells").glob("*.py") if not p.stem.endswith("_fmu")}
    declared: set[str] = set()
    bare: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "FMU_CORE_MODULES" for t in node.targets):
            declared = set(ast.literal_eval(node.value))
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in cores:
            bare.add(node.module)
        if isinstance(node, ast.Import | ast.ImportFrom):
            mod = node.module if isinstance(node, ast.ImportFrom) else node.names[0].name
            assert (mod or "").split(".")[0] not in PACKAGES, f"{shell} imports {mod}: shells travel without packages"
    assert bare <= declared, f"{shell} imports {bare - declared} without listing it in FMU_CORE_MODULES"


BUILDING_WORDS = re.compile(r"isolat|drift|storey|\bfloors?\b(?!\s*\()|hysteres|sosm|earthquake", re.IGNORECASE)
"""Words of our application (C's floor() is arithmetic, not a floor of a building)."""


def test_the_engine_knows_no_building():
    """The engine knows FMUs and variables: its code and comments name no part of our application."""
    found = [f"{p.relative_to(PROJECT)}:{i}: {line.strip()}"
             for p in sorted((PROJECT / "orchestration" / "master").rglob("*.[pc]*")) if p.suffix in (".py", ".c")
             for i, line in enumerate(p.read_text().splitlines(), 1)
             if BUILDING_WORDS.search(line)]
    assert found == []


def test_no_two_modules_share_a_file_name():
    """A name says what a file holds: ``report.py`` in three packages says nothing."""
    generic = {"__init__.py", "__main__.py", "conftest.py"}
    seen: dict[str, list[str]] = {}
    for pkg in PACKAGES:
        for p in (PROJECT / pkg).rglob("*.py"):
            if p.name not in generic:
                seen.setdefault(p.name, []).append(str(p.relative_to(PROJECT)))
    assert {n: ps for n, ps in seen.items() if len(ps) > 1} == {}
