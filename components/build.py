"""Build the project's FMUs with pythonfmu and complete their modelDescription.

Every ``components/*_fmu.py`` holds one ``Fmi2Slave`` shell; its FMU is named after the
class (the model identifier). The shell lists the physics modules it imports in
``FMU_CORE_MODULES``; they travel in the FMU's resources under their own (unique)
module names.

pythonfmu 0.7 writes no units and no output dependencies, so the build rewrites the
modelDescription: ``UnitDefinitions`` for every unit the shell declares in
``fmi_units``, the ``unit`` attribute on each Real, and ``ModelStructure`` with
``Outputs`` and ``InitialUnknowns`` whose dependencies come from ``fmi_dependencies``
(output name -> input names; outputs not listed depend on no input).

The Linux binary pythonfmu 0.7 ships has an exit hook that uses freed memory; the build
removes it (see ``pythonfmu_exit_fix``).

Usage: ``python -m components.build [--dest fmus] [--force] [--storeys N ...]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import os
import re
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

from components.pythonfmu_exit_fix import ExitHookError, remove_exit_hook

COMPONENTS_DIR = Path(__file__).resolve().parent
PROJECT_DIR = COMPONENTS_DIR.parent
DEFAULT_FMU_DIR = PROJECT_DIR / "fmus"

# SI units used at the FMU boundaries: name -> exponents of the SI base units.
# A unit with no base-unit expression (fractional powers) is declared by name only.
SI_UNITS: dict[str, dict[str, int] | None] = {
    "1": {},
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "N/A": {"kg": 1, "m": 1, "s": -2, "A": -1},
    "N/(m.A)": {"kg": 1, "s": -2, "A": -1},
    "N.s/(m.A)": {"kg": 1, "s": -1, "A": -1},
    "1/m": {"m": -1},
    "1/(m.A)": {"m": -1, "A": -1},
    "1/s": {"s": -1},
    "A": {"A": 1},
    "A/s": {"A": 1, "s": -1},
    "m.s-1.5": None,  # sqrt(m)/s^1.5: SOSM gain theta
    "A.s0.5/m0.5": None,  # SOSM gain zeta
}

_ELEMENT_ORDER = (
    "ModelExchange",
    "CoSimulation",
    "UnitDefinitions",
    "TypeDefinitions",
    "LogCategories",
    "DefaultExperiment",
    "VendorAnnotations",
    "ModelVariables",
    "ModelStructure",
)


@dataclass(frozen=True)
class FmuSource:
    """One buildable FMU: the shell script and the class it holds."""

    script: Path
    class_name: str
    core_modules: tuple[str, ...]
    storeys: int | None = None  # only for shells that take N_STOREYS at build time
    requirements: tuple[str, ...] = ()  # Python packages the unit imports on the host
    handles_state: bool = False  # the shell implements fmi2GetFMUstate/fmi2SetFMUstate

    @property
    def fmu_name(self) -> str:
        if self.storeys is None or self.storeys == 3:
            return f"{self.class_name}.fmu"
        return f"{self.class_name}{self.storeys}.fmu"

    @property
    def sources(self) -> list[Path]:
        """Files whose change makes the FMU stale."""
        cores = [COMPONENTS_DIR / f"{m}.py" for m in self.core_modules]
        return [self.script, *cores, Path(__file__).resolve(), COMPONENTS_DIR / "pythonfmu_exit_fix.py"]


class BuildError(RuntimeError):
    """An FMU could not be built."""


def _load_module(script: Path, module_name: str):
    sys.path.insert(0, str(COMPONENTS_DIR))
    try:
        spec = importlib.util.spec_from_file_location(module_name, script)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(COMPONENTS_DIR))
    return module


def _shell_class(module):
    from pythonfmu import Fmi2Slave

    classes = [
        obj
        for _, obj in inspect.getmembers(module, inspect.isclass)
        if issubclass(obj, Fmi2Slave) and obj is not Fmi2Slave and obj.__module__ == module.__name__
    ]
    if len(classes) != 1:
        raise BuildError(f"{module.__file__}: expected one Fmi2Slave class, found {len(classes)}")
    return classes[0]


def discover(storeys: tuple[int, ...] = ()) -> list[FmuSource]:
    """All FMU shells in components/, plus building variants for the given storey counts."""
    found = []
    for script in sorted(COMPONENTS_DIR.glob("*_fmu.py")):
        module = _load_module(script, f"_discover_{script.stem}")
        cls = _shell_class(module)
        cores = tuple(getattr(module, "FMU_CORE_MODULES", ()))
        extra = {
            "requirements": tuple(getattr(module, "FMU_REQUIREMENTS", ())),
            "handles_state": "_get_fmu_state" in vars(cls) and "_set_fmu_state" in vars(cls),
        }
        if hasattr(module, "N_STOREYS"):
            for n in sorted({module.N_STOREYS, *storeys}):
                found.append(FmuSource(script, cls.__name__, cores, storeys=n, **extra))
        else:
            found.append(FmuSource(script, cls.__name__, cores, **extra))
    return found


def is_stale(source: FmuSource, fmu: Path) -> bool:
    """True if the FMU is missing or older than any of its sources."""
    if not fmu.exists():
        return True
    built = fmu.stat().st_mtime
    return any(p.stat().st_mtime > built for p in source.sources)


def _render_script(source: FmuSource, workdir: Path) -> Path:
    """The shell as it goes into the FMU: a storey variant gets its own module name."""
    if source.storeys is None:
        return source.script
    stem = f"{source.script.stem.removesuffix('_fmu')}_n{source.storeys}_fmu"
    text = source.script.read_text()
    text, count = re.subn(r"^N_STOREYS = \d+$", f"N_STOREYS = {source.storeys}", text, flags=re.M)
    if count != 1:
        raise BuildError(f"{source.script}: needs exactly one line 'N_STOREYS = <int>'")
    target = workdir / f"{stem}.py"
    target.write_text(text)
    return target


def _declared_metadata(script: Path) -> tuple[dict[str, str], dict[str, tuple[str, ...]], dict[str, float]]:
    from pythonfmu import Real
    from pythonfmu.variables import ScalarVariable

    module = _load_module(script, f"_meta_{script.stem}")
    instance = _shell_class(module)(instance_name="build", resources=str(script.parent))
    starts = {v.name: float(v.getter()) for v in instance.vars.values()
              if isinstance(v, Real) and ScalarVariable.requires_start(v)}
    return dict(instance.fmi_units), dict(instance.fmi_dependencies), starts


def complete_model_description(
    xml: bytes,
    units: dict[str, str],
    deps: dict[str, tuple[str, ...]],
    starts: dict[str, float] | None = None,
) -> bytes:
    """Add unit definitions, Real units and the model structure to a pythonfmu modelDescription.

    ``starts`` rewrites Real start values with full precision (pythonfmu writes 16
    significant digits, which can be one ulp off the unit's own default).
    """
    root = ET.fromstring(xml)
    variables = root.find("ModelVariables")
    index = {}
    for k, sv in enumerate(variables.findall("ScalarVariable"), start=1):
        index[sv.get("name")] = (k, sv)
    unknown = set(units) - set(index)
    if unknown:
        raise BuildError(f"fmi_units names unknown variables: {sorted(unknown)}")
    used = set()
    for name, (_, sv) in index.items():
        real = sv.find("Real")
        if real is not None and starts and name in starts and real.get("start") is not None:
            real.set("start", repr(starts[name]))
        if real is None or name not in units:
            continue
        unit = units[name]
        if unit not in SI_UNITS:
            raise BuildError(f"variable {name}: unit {unit!r} is not in components.build.SI_UNITS")
        real.set("unit", unit)
        used.add(unit)

    unit_defs = ET.Element("UnitDefinitions")
    for unit in sorted(used):
        node = ET.SubElement(unit_defs, "Unit", name=unit)
        exponents = SI_UNITS[unit]
        if exponents is not None:
            ET.SubElement(node, "BaseUnit", {k: str(v) for k, v in exponents.items()})
    if used:
        root.append(unit_defs)

    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    structure = ET.SubElement(root, "ModelStructure")
    outputs = [(k, name) for name, (k, sv) in index.items() if sv.get("causality") == "output"]
    inputs = {name for name, (_, sv) in index.items() if sv.get("causality") == "input"}
    bad = {o: d for o, d in deps.items() if o not in dict((n, k) for k, n in outputs) or set(d) - inputs}
    if bad:
        raise BuildError(f"fmi_dependencies must map outputs to inputs: {bad}")
    if outputs:
        out_node = ET.SubElement(structure, "Outputs")
        for k, name in outputs:
            refs = " ".join(str(index[d][0]) for d in deps.get(name, ()))
            kinds = " ".join("dependent" for _ in deps.get(name, ()))
            attrib = {"index": str(k), "dependencies": refs}
            if kinds:
                attrib["dependenciesKind"] = kinds
            ET.SubElement(out_node, "Unknown", attrib)
    # Initial unknowns: outputs and calculated parameters. Their dependencies are left
    # undeclared, which FMI 2.0 reads as "may depend on every known" (parameters too).
    initial = [k for name, (k, sv) in index.items() if sv.get("causality") in ("output", "calculatedParameter")]
    if initial:
        init_node = ET.SubElement(structure, "InitialUnknowns")
        for k in sorted(initial):
            ET.SubElement(init_node, "Unknown", {"index": str(k)})
    root[:] = sorted(root, key=lambda e: _ELEMENT_ORDER.index(e.tag))
    for element in root.iter():
        element.tail = None
        if element.text is not None and not element.text.strip():
            element.text = None
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


PYTHON_REQUIREMENT = "Python >= 3.11 (CPython, the interpreter of the host process)"


def _requirements_text(source: FmuSource) -> str:
    lines = [
        f"# {source.fmu_name} runs Python code through pythonfmu: the host process must provide",
        f"# {PYTHON_REQUIREMENT} with these packages installed:",
        *source.requirements,
    ]
    return "\n".join(lines) + "\n"


def _documentation(source: FmuSource) -> str:
    packages = ", ".join(source.requirements) or "none besides the standard library"
    return (
        f"<html><head><title>{source.class_name}</title></head><body>"
        f"<h1>{source.class_name}</h1>"
        f"<p>An FMI 2.0 co-simulation unit of the mre-cosim toolkit, built with pythonfmu. It executes "
        f"Python: the importing tool must run it in a process with {PYTHON_REQUIREMENT}; packages: "
        f"{packages} (also listed in resources/requirements.txt).</p>"
        f"<p>Variables, units and their meaning: see modelDescription.xml and the project README.</p>"
        f"</body></html>\n"
    )


def build(source: FmuSource, dest: Path) -> Path:
    """Build one FMU into ``dest`` and complete its modelDescription; returns its path."""
    from pythonfmu import FmuBuilder

    dest.mkdir(parents=True, exist_ok=True)
    target = dest / source.fmu_name
    with tempfile.TemporaryDirectory(prefix="mre_build_") as tmp:
        tmp = Path(tmp)
        script = _render_script(source, tmp)
        cores = [COMPONENTS_DIR / f"{m}.py" for m in source.core_modules]
        requirements = tmp / "requirements.txt"
        requirements.write_text(_requirements_text(source))
        docs = tmp / "documentation"
        docs.mkdir()
        (docs / "index.html").write_text(_documentation(source))
        options = {"canGetAndSetFMUstate": True} if source.handles_state else {}
        sys.path.insert(0, str(COMPONENTS_DIR))
        try:
            raw = FmuBuilder.build_FMU(script, dest=tmp / "raw.fmu", project_files=[*cores, requirements],
                                       documentation_folder=docs, **options)
            units, deps, starts = _declared_metadata(script)
        except Exception as exc:  # pythonfmu raises plain exceptions
            raise BuildError(f"building {source.fmu_name} from {source.script.name}: {exc}") from exc
        finally:
            sys.path.remove(str(COMPONENTS_DIR))
            sys.modules.pop(script.stem, None)
        # Written next to the target and renamed: a concurrent reader never sees half an FMU.
        fd, partial = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=dest)
        os.close(fd)
        try:
            with zipfile.ZipFile(raw) as zin, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zout:
                for item in zin.infolist():
                    data = zin.read(item.filename)
                    if item.filename == "modelDescription.xml":
                        data = complete_model_description(data, units, deps, starts)
                    elif item.filename.startswith("binaries/linux64/"):
                        data = remove_exit_hook(data, f"{source.fmu_name}:{item.filename}")
                    zout.writestr(item, data)
            os.chmod(partial, 0o644)
            os.replace(partial, target)
        except ExitHookError as exc:
            Path(partial).unlink(missing_ok=True)
            raise BuildError(str(exc)) from None
        except BaseException:
            Path(partial).unlink(missing_ok=True)
            raise
    return target


def ensure_built(dest: Path = DEFAULT_FMU_DIR, force: bool = False, storeys: tuple[int, ...] = ()) -> list[Path]:
    """Build every FMU that is missing or older than its sources; returns all FMU paths."""
    paths = []
    for source in discover(storeys):
        fmu = dest / source.fmu_name
        if force or is_stale(source, fmu):
            build(source, dest)
        paths.append(fmu)
    from components.c_isolator_build import ensure_c_isolator  # the plain-C isolator, not pythonfmu

    paths.append(ensure_c_isolator(dest, force))
    return paths


def known_fmu(path: Path) -> FmuSource | None:
    """The source of an FMU path in the project's fmus/ folder, if the project builds it."""
    path = Path(path).resolve()
    if path.parent != DEFAULT_FMU_DIR.resolve():
        return None
    m = re.fullmatch(r"([A-Za-z]+?)(\d+)?\.fmu", path.name)
    storeys = (int(m.group(2)),) if m and m.group(2) else ()
    for source in discover(storeys):
        if source.fmu_name == path.name:
            return source
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Build the project's FMUs into fmus/.")
    parser.add_argument("--dest", type=Path, default=DEFAULT_FMU_DIR, help="output folder (default fmus/)")
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    parser.add_argument(
        "--storeys", type=int, nargs="*", default=[], help="also build shear-building variants with N storeys"
    )
    args = parser.parse_args(argv)
    for path in ensure_built(args.dest, args.force, tuple(args.storeys)):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
