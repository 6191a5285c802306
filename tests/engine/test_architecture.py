"""The layout's import rules, read from the source (every import statement, also inside functions).

* ``mre_common`` (atomic writes, C compile-and-cache, folder claims, the CLI guard) imports nothing of ours.
* ``orchestration.master`` (the engine) imports only itself and ``mre_common``: no ``components``, no application.
* ``orchestration.interop`` imports the engine and itself; ``orchestration.batch`` (the Dask layer) the engine
  and itself, no study; ``orchestration.inprocess`` the engine and the physics cores.
* ``orchestration.building_studies`` (what the building studies share) imports the engine, the application's hooks
  (``engine_hooks``, ``building_report``, ``roles``) and the physics cores: no study.
* ``orchestration.case_study`` and ``orchestration.ida_study`` build on ``building_studies``, never on each other;
  ``orchestration.suite_benchmark`` builds on both, and neither imports it.
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

from ..conftest import PROJECT

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
    "orchestration.building_studies": ("orchestration.building_studies", ENGINE, "orchestration.engine_hooks",
                                       "orchestration.building_report", "orchestration.roles", "components.physics",
                                       COMMON),
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


FORBIDDEN = {"orchestration.case_study": ("orchestration.ida_study", "orchestration.suite_benchmark"),
             "orchestration.ida_study": ("orchestration.case_study", "orchestration.suite_benchmark")}
"""Applications that may import much, but not this: the two studies share orchestration.building_studies and
never import each other."""


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
    sources["orchestration.ida_study.ida_plan"] += "\nfrom orchestration.case_study.case_plan import prepare\n"
    sources["orchestration.building_studies.strategies"] += "\nfrom orchestration.case_study import case_config\n"
    assert sorted(violations(sources)) == [
        "orchestration.batch.pool imports orchestration.ida_study.fragility",
        "orchestration.building_studies.strategies imports orchestration.case_study",
        "orchestration.building_studies.strategies imports orchestration.case_study.case_config",
        "orchestration.case_study.claims imports orchestration.ida_study.fragility",
        "orchestration.ida_study.ida_plan imports orchestration.case_study.case_plan",
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


BUILDING_WORDS = re.compile(r"isolat|drift|storey|\bfloors?\b(?!\s*\()|hysteres|sosm|earthquake"
                            r"|kobe|el[\s_-]?centro|hachinohe|northridge", re.IGNORECASE)
"""Words of our application, the earthquake records' names among them (C's floor() is arithmetic, not a floor of a
building)."""


def building_lines(files: dict[str, str]) -> list[str]:
    """``path:line: text`` of every line that names a part of our application."""
    return [f"{path}:{i}: {line.strip()}" for path, text in sorted(files.items())
            for i, line in enumerate(text.splitlines(), 1) if BUILDING_WORDS.search(line)]


def test_the_engine_knows_no_building():
    """The engine knows FMUs and variables: its code and comments name no part of our application."""
    files = {str(p.relative_to(PROJECT)): p.read_text()
             for p in sorted((PROJECT / "orchestration" / "master").rglob("*.[pc]*")) if p.suffix in (".py", ".c")}
    assert building_lines(files) == []


def test_the_building_word_scan_finds_record_names():
    files = {"m.py": "x = 1\n# as on the KOBE record\nrecord = 'elcentro'\n# El Centro, El_Centro, Hachinohe\n"
                     "# northridge\nfloor(x)\n"}
    assert [line.split(":")[1] for line in building_lines(files)] == ["2", "3", "4", "5"]


def test_no_two_modules_share_a_file_name():
    """A name says what a file holds: ``report.py`` in three packages says nothing."""
    generic = {"__init__.py", "__main__.py", "conftest.py"}
    seen: dict[str, list[str]] = {}
    for pkg in PACKAGES:
        for p in (PROJECT / pkg).rglob("*.py"):
            if p.name not in generic:
                seen.setdefault(p.name, []).append(str(p.relative_to(PROJECT)))
    assert {n: ps for n, ps in seen.items() if len(ps) > 1} == {}


# -- one source for each fact ------------------------------------------------------------------------------------

TABLE2_VALUES = (5.8161, 3.3431, 0.5767, 0.3396, 4.9810, 8.1100, 0.1322, 0.3463)
"""Table 2 of the paper in its units (this test's own copy: the oracle); their SI forms are x1000 (not alpha)."""
DYKE_VALUES = (98.3, 516e3, 684e3, 4 * 98.3)
"""The Dyke building's masses and storey stiffnesses (Table 3), and its total mass (the isolator stop's)."""
FACT_HOMES = {
    "Table 2": ("components/physics/mre_isolator_core.py",),
    "the Dyke building": ("components/physics/dyke_building.py",),
}
INDEPENDENT_COPIES = (
    "components/identification/testdata.py",  # the synthetic test-data generator: an independent check
    "components/identification/paper_tables.py",  # Table 1 is data (its per-condition fits)
)
"""Files that keep their own numbers on purpose (the tests' oracles and scenarios/structures/*.py are not scanned)."""


def _fact_values() -> dict[str, tuple[float, ...]]:
    si = tuple(v / 1e-3 for v in TABLE2_VALUES[:4] + TABLE2_VALUES[6:])
    return {"Table 2": TABLE2_VALUES + si, "the Dyke building": DYKE_VALUES}


def numeric_literals(source: str) -> list[tuple[int, float]]:
    """(line, value) of every number written in a module's code (not in its strings or comments)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            out.append((node.lineno, float(node.value)))
    return out


def fact_copies(files: dict[str, str]) -> list[str]:
    """``path:line: value (fact)`` for every literal of Table 2 or the Dyke table outside the fact's home."""
    found = []
    for path, source in sorted(files.items()):
        if path in INDEPENDENT_COPIES:
            continue
        for fact, values in _fact_values().items():
            if path in FACT_HOMES[fact]:
                continue
            found += [(path, line, f"{path}:{line}: {value!r} ({fact})") for line, value in numeric_literals(source)
                      if any(abs(value - v) <= 1e-12 * abs(v) for v in values)]
    return [text for *_, text in sorted(found)]


def _product_files() -> dict[str, str]:
    return {str(p.relative_to(PROJECT)): p.read_text() for pkg in ("components", "orchestration")
            for p in sorted((PROJECT / pkg).rglob("*.py"))}


def test_table2_and_the_dyke_table_have_one_source_in_the_product():
    """Table 2's coefficients live in mre_isolator_core, the Dyke building's table in dyke_building: every other
    module of components/ and orchestration/ imports them (the C unit is held to the module by test_c_isolator)."""
    assert fact_copies(_product_files()) == []


def test_the_fact_scan_finds_a_copy():
    files = _product_files()
    files["components/physics/sosm_controller_core.py"] += "\nK0_0 = 5816.1  # N/(m A)\n"
    last = files["components/physics/sosm_controller_core.py"].count("\n")
    files["orchestration/tuning_copy.py"] = "SLOPE = 0.1322 / 1e-3\nMASSES = [98.3] * 4\nTOTAL = 393.2\n"
    files["components/physics/lqg_plant_core.py"] += "\nNOTE = 'k0_0 = 5.8161 N/mm'  # 516e3 in a comment\n"
    assert fact_copies(files) == [
        f"components/physics/sosm_controller_core.py:{last}: 5816.1 (Table 2)",
        "orchestration/tuning_copy.py:1: 0.1322 (Table 2)",
        "orchestration/tuning_copy.py:2: 98.3 (the Dyke building)",
        "orchestration/tuning_copy.py:3: 393.2 (the Dyke building)",
    ]


LAW_HOME = "components/physics/mre_isolator_core.py"
LAW_FUNCTIONS = {"sinh", "cosh"}
"""A call of sinh or cosh is how Eq. 17 (or its derivatives) gets written: only the law's module calls them."""
LAW_CALLS_ALLOWED = {  # path: (calls allowed, why)
    "components/physics/lqg_plant_core.py": (1, "numpy's sinh with its argument clipped, handed to the law"),
}
FITTING_LIBRARY = "components/identification/"
"""The identification library fits the law's forms to the tests (regressors, batched predictions over parameter
sets, the synthetic test-data generator): it writes the forms it fits; what it finds goes to parameter files."""


def law_calls(files: dict[str, str]) -> list[str]:
    """``path:line`` of every call of sinh/cosh (math., np., bare) outside the law's module and the allowed ones."""
    found = []
    for path, source in sorted(files.items()):
        if path == LAW_HOME or path.startswith(FITTING_LIBRARY):
            continue
        lines = sorted(node.lineno for node in ast.walk(ast.parse(source)) if isinstance(node, ast.Call)
                       and (getattr(node.func, "attr", None) or getattr(node.func, "id", None)) in LAW_FUNCTIONS)
        if len(lines) > LAW_CALLS_ALLOWED.get(path, (0, ""))[0]:
            found += [f"{path}:{line}" for line in lines]
    return found


def test_the_isolator_law_is_written_in_one_module():
    """Eq. 17, its dF/dx and dF/di are written in mre_isolator_core only: the controllers' models, the SOSM law
    and its conditions, the monolithic reference and the figures call its functions."""
    assert law_calls(_product_files()) == []


def test_the_law_scan_finds_a_copy():
    files = {"components/physics/x_core.py": "import math\nimport numpy as np\n\ndef f(a, b, x):\n"
                                             "    return a * math.sinh(b * x) + np.cosh(x)\n"}
    files["components/physics/lqg_plant_core.py"] = "def f(x):\n    return np.sinh(x)\n"  # its one allowed call
    assert law_calls(files) == ["components/physics/x_core.py:5", "components/physics/x_core.py:5"]
    files["components/physics/lqg_plant_core.py"] += "def g(x):\n    return math.cosh(x)\n"
    assert law_calls(files)[:2] == ["components/physics/lqg_plant_core.py:2", "components/physics/lqg_plant_core.py:4"]


def _bare_imports(source: str, cores: set[str]) -> set[str]:
    """The physics cores and shell helpers a module imports by bare name (``import m``, ``from m import``)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name in cores}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module in cores:
            found.add(node.module)
    return found


@pytest.mark.parametrize("shell", sorted(p.name for p in (PROJECT / "components" / "shells").glob("*_fmu.py")))
def test_each_fmu_carries_every_module_its_cores_import(shell):
    """FMU_CORE_MODULES is closed under the bare imports of the modules it lists: a core that imports another
    (lqg_plant_core imports mre_isolator_core and dyke_building) makes every FMU that carries it carry that one."""
    physics, shells = PROJECT / "components" / "physics", PROJECT / "components" / "shells"
    files = {p.stem: p for p in physics.glob("*.py")} | {p.stem: p for p in shells.glob("*.py")
                                                         if not p.stem.endswith("_fmu")}
    tree = ast.parse((shells / shell).read_text())
    declared = next((set(ast.literal_eval(n.value)) for n in tree.body if isinstance(n, ast.Assign | ast.AnnAssign)
                     and getattr(n.targets[0] if isinstance(n, ast.Assign) else n.target, "id", "")
                     == "FMU_CORE_MODULES"), set())
    needed: set[str] = set()
    todo = sorted(declared)
    while todo:
        name = todo.pop()
        for other in _bare_imports(files[name].read_text(), set(files)) - needed:
            needed.add(other)
            todo.append(other)
    assert needed <= declared, f"{shell} carries {sorted(declared)} but they import {sorted(needed - declared)}"


def _carried() -> dict[str, set[str]]:
    """Shell file -> the modules its FMU carries (FMU_CORE_MODULES)."""
    out = {}
    for p in sorted((PROJECT / "components" / "shells").glob("*_fmu.py")):
        tree = ast.parse(p.read_text())
        out[p.name] = next((set(ast.literal_eval(n.value)) for n in tree.body
                            if isinstance(n, ast.Assign | ast.AnnAssign)
                            and getattr(n.targets[0] if isinstance(n, ast.Assign) else n.target, "id", "")
                            == "FMU_CORE_MODULES"), set())
    return out


UNCHECKED_SHARING: dict[str, set[str]] = {}
"""Shells whose FMU carries a module another kind of FMU carries too, without refusing a foreign copy of it."""


def test_every_fmu_that_shares_a_module_refuses_another_fmu_s_copy():
    """pythonfmu FMUs share one interpreter: a module carried by the FMUs of two shells is served to both by the
    copy loaded first, so each shell checks it (shared_copies.copy_problem, or model_based_shell.copy_problems
    for the model-based controllers) before it runs."""
    carried = _carried()
    missing = {}
    for shell, modules in carried.items():
        shared = {m for m in modules for other, theirs in carried.items() if other != shell and m in theirs}
        shared -= {"model_based_shell", "shared_copies"}
        text = (PROJECT / "components" / "shells" / shell).read_text()
        checks = "shared_copies.copy_problem(" in text or "shared.start_controller(" in text
        unchecked = set() if checks else shared
        if unchecked != UNCHECKED_SHARING.get(shell, set()):
            missing[shell] = sorted(unchecked)
    assert missing == {}


def test_a_shared_module_loaded_from_another_fmu_with_other_code_is_refused(tmp_path):
    import components.physics.dyke_building as dyke
    import components.physics.mre_isolator_core as law
    import components.shells.shared_copies as copies

    same, other, none = tmp_path / "same", tmp_path / "other", tmp_path / "none"
    for folder in (same, other, none):
        folder.mkdir()
    for module in (law, dyke, copies):
        here = Path(module.__file__)
        (same / here.name).write_bytes(here.read_bytes())
        (other / here.name).write_bytes(here.read_bytes())
    (other / "dyke_building.py").write_text(Path(dyke.__file__).read_text().replace("98.3", "99.0", 1))
    assert copies.copy_problem((law, dyke), str(same)) == ""
    assert copies.copy_problem((law, dyke), str(none)) == ""  # an FMU without these modules
    assert copies.copy_problem((law, dyke), None) == ""
    assert "different version of the module dyke_building" in copies.copy_problem((law, dyke), str(other))
    (other / "dyke_building.py").write_bytes(Path(dyke.__file__).read_bytes())
    (other / "shared_copies.py").write_text(Path(copies.__file__).read_text() + "\n# another version\n")
    assert "different version of the module shared_copies" in copies.copy_problem((law, dyke), str(other))
