"""Build the plain-C MRE isolator FMU (``MreIsolatorC.fmu``): the same unit as ``MreIsolator``
made without pythonfmu, from ``components/c_isolator/mre_isolator.c``.

The C source is compiled with the system C compiler (``$CC``, default ``cc``) against the
FMI 2.0 headers fmpy ships (``fmpy/c-code``). The defaults of the parameters come from
:mod:`components.physics.mre_isolator_core` (Table 2): they are defined as macros at the top of
the compiled (and shipped, ``sources/``) C file and written to the modelDescription
from the same Python floats, so both implementations start from
the same doubles. The modelDescription is completed (units, output dependencies) by
:func:`components.build.model_description.complete_model_description`, like the pythonfmu units.

``-ffp-contract=off`` keeps the compiler from fusing multiply-adds, so the force is
computed with the same roundings as the Python core (and the same libm ``sinh``).

Usage: ``python -m components.build.c_isolator [--dest FOLDER] [--force]`` (default folder: the
project's FMU folder, :func:`mre_common.project_paths.fmu_dir`).
"""

from __future__ import annotations

import argparse
import hashlib
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO
from xml.etree import ElementTree as ET

from components.build.model_description import DEFAULT_FMU_DIR, BuildError, complete_model_description
from components.physics.mre_isolator_core import (
    BEYOND_RANGE,
    COEFFICIENT_DOCS,
    CURRENT_MAX_A,
    DEVICE_LIMIT_M,
    IDENTIFIED_RANGE_M,
    STOP_DAMPING,
    STOP_STIFFNESS,
    TABLE2,
)
from mre_common.atomic_files import atomic_write
from mre_common.c_compile import CompileFailed, CompilerMissing, compile_c

COMPONENTS_DIR = Path(__file__).resolve().parents[1]
C_SOURCE = COMPONENTS_DIR / "c_isolator" / "mre_isolator.c"
MODEL_IDENTIFIER = "MreIsolatorC"
C_FMU_NAME = f"{MODEL_IDENTIFIER}.fmu"
CFLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off", "-fvisibility=hidden", "-std=c99", "-Wall", "-Wextra")
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # fixed timestamps: the same sources give the same archive


@dataclass(frozen=True)
class CVariable:
    """One variable of the C unit (value references as in the pythonfmu unit)."""

    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: str | None
    start: float | int | str | None
    description: str
    macro: str | None = None  # C default macro fed from the Python value


_COEFF_TEXT = COEFFICIENT_DOCS


def variables() -> list[CVariable]:
    """The unit's variables in value-reference order (the order of the C enum)."""
    inp = {"type": "Real", "causality": "input", "variability": "continuous", "start": 0.0}
    par = {"causality": "parameter", "variability": "fixed"}
    out = [
        CVariable("x", 0, unit="m", description="isolator displacement", **inp),
        CVariable("v", 1, unit="m/s", description="isolator velocity", **inp),
        CVariable("i", 2, unit="A", description="commanded current", **inp),
    ]
    coeffs = TABLE2.as_dict()
    for k, (name, (unit, text)) in enumerate(_COEFF_TEXT.items(), start=3):
        out.append(CVariable(name, k, "Real", unit=unit, start=coeffs[name], description=text,
                             macro=f"DEFAULT_{name.upper()}", **par))
    out += [
        CVariable("F0", 11, "Real", unit="N", start=0.0, description="force offset per device", **par),
        CVariable("n_isolators", 12, "Integer", unit=None, start=2,
                  description="number of identical devices in parallel", macro="DEFAULT_N_ISOLATORS", **par),
        CVariable("i_max", 13, "Real", unit="A", start=CURRENT_MAX_A, description="largest admissible current",
                  macro="DEFAULT_I_MAX", **par),
        CVariable("x_identified", 14, "Real", unit="m", start=IDENTIFIED_RANGE_M,
                  description="displacement range the model was identified on", macro="DEFAULT_X_IDENTIFIED",
                  **par),
        CVariable("x_limit", 15, "Real", unit="m", start=DEVICE_LIMIT_M, description="device displacement limit",
                  macro="DEFAULT_X_LIMIT", **par),
        CVariable("F", 16, "Real", "output", "continuous", "N", None,
                  "total isolator restoring force (acts on the base against x)"),
        # added after F, as in the Python unit (its descriptions: the master reads the String's choices from them)
        CVariable("beyond_range", 17, "String", unit=None, start=BEYOND_RANGE[0],
                  description=f"{' or '.join(repr(b) for b in BEYOND_RANGE)}: the law beyond x_identified", **par),
        CVariable("k_stop", 18, "Real", unit="N/m", start=STOP_STIFFNESS,
                  description="stiffness of the stop at x_limit ('stop')", macro="DEFAULT_K_STOP", **par),
        CVariable("c_stop", 19, "Real", unit="N.s/m", start=STOP_DAMPING,
                  description="damping of the stop at x_limit ('stop')", macro="DEFAULT_C_STOP", **par),
        CVariable("F_off", 20, "Real", "local", "continuous", "N", None,
                  "the same force at 0 A (F - F_off: the controllable force)"),
    ]
    return out


def headers_dir() -> Path:
    """The FMI 2.0 headers shipped with fmpy."""
    import fmpy

    path = Path(fmpy.__file__).resolve().parent / "c-code"
    if not (path / "fmi2Functions.h").is_file():
        raise BuildError(f"fmpy ships no FMI 2.0 headers at {path}")
    return path


def sources() -> list[Path]:
    """Files whose change makes the C FMU stale."""
    return [C_SOURCE, Path(__file__).resolve(), COMPONENTS_DIR / "physics" / "mre_isolator_core.py",
            Path(__file__).resolve().parent / "model_description.py"]


def is_stale(fmu: Path) -> bool:
    """True if the FMU is missing or older than any of its sources."""
    if not fmu.exists():
        return True
    built = fmu.stat().st_mtime
    return any(p.stat().st_mtime > built for p in sources())


def is_c_isolator(path: Path) -> bool:
    """True for the project's own ``MreIsolatorC.fmu`` in the build folder (the one the master may build)."""
    path = Path(path).resolve()
    return path.name == C_FMU_NAME and path.parent == DEFAULT_FMU_DIR.resolve()


def _fmt(value: float | int) -> str:
    return repr(value) if isinstance(value, float) else str(value)


def _guid(defines: list[str]) -> str:
    digest = hashlib.sha256(C_SOURCE.read_bytes())
    for item in (*defines, *CFLAGS, *(repr(v) for v in variables())):
        digest.update(item.encode())
    return "{" + str(uuid.UUID(bytes=digest.digest()[:16], version=5)) + "}"


def model_description(guid: str) -> bytes:
    """The complete modelDescription.xml of the C unit."""
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": MODEL_IDENTIFIER,
        "guid": guid,
        "description": "MRE base isolator (plain C): F = n*(c0(i) v + k0(i) x + alpha(i) sinh(beta(i) x) + F0)",
        "generationTool": "mre-cosim components/build/c_isolator.py",
        "variableNamingConvention": "structured",
    })
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": MODEL_IDENTIFIER,
        "needsExecutionTool": "false",
        "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true",
        "providesDirectionalDerivative": "false",
    })
    files = ET.SubElement(root.find("CoSimulation"), "SourceFiles")
    ET.SubElement(files, "File", name=C_SOURCE.name)
    cats = ET.SubElement(root, "LogCategories")
    for name, text in (("logStatusWarning", "fmi2Warning messages"), ("logStatusDiscard", "fmi2Discard messages"),
                       ("logStatusError", "fmi2Error messages"), ("logStatusFatal", "fmi2Fatal messages"),
                       ("logAll", "all messages")):
        ET.SubElement(cats, "Category", name=name, description=text)
    model_vars = ET.SubElement(root, "ModelVariables")
    for var in variables():
        sv = ET.SubElement(model_vars, "ScalarVariable", {
            "name": var.name, "valueReference": str(var.vr), "description": var.description,
            "causality": var.causality, "variability": var.variability,
        })
        attrib = {} if var.start is None else {"start": _fmt(var.start)}
        ET.SubElement(sv, var.type, attrib)
    units = {v.name: v.unit for v in variables() if v.unit is not None}
    return complete_model_description(ET.tostring(root), units, {"F": ("x", "v", "i")})


def _rendered_source(defines: dict[str, str]) -> str:
    """The C source with the build's macros (GUID, defaults) defined up front: it compiles alone."""
    head = [f"/* Generated by components/build/c_isolator.py from {C_SOURCE.name}. */"]
    head += [f"#define {name} {value}" for name, value in defines.items()]
    return "\n".join(head) + "\n\n" + C_SOURCE.read_text()


def _compile(source: Path) -> Path:
    target = source.with_suffix(".so")
    try:
        compile_c(source, target, (*CFLAGS, f"-I{headers_dir()}"), ("-lm",))
    except CompilerMissing as exc:
        raise BuildError(f"no C compiler {exc.compiler!r} found (set CC)") from None
    except CompileFailed as exc:
        raise BuildError(f"compiling {C_SOURCE.name} failed:\n{' '.join(exc.command)}\n{exc.stderr}") from None
    return target


def _platform() -> tuple[str, str]:
    from fmpy import platform, sharedLibraryExtension

    if platform != "linux64":
        raise BuildError(f"the C isolator build supports linux64 only, this is {platform}")
    return platform, sharedLibraryExtension


def build_c_isolator(dest: Path = DEFAULT_FMU_DIR) -> Path:
    """Compile the C isolator and write ``dest/MreIsolatorC.fmu`` (atomically); returns its path."""
    plat, ext = _platform()
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    defines = {v.macro: _fmt(v.start) for v in variables() if v.macro is not None}
    guid = _guid([f"{k}={v}" for k, v in defines.items()])
    defines["MODEL_GUID"] = f'"{guid}"'
    with tempfile.TemporaryDirectory(prefix="mre_cbuild_") as tmp:
        source = Path(tmp) / C_SOURCE.name
        source.write_text(_rendered_source(defines))
        library = _compile(source)

        def write(f: BinaryIO) -> None:
            with zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as z:
                for name, data in (
                    ("modelDescription.xml", model_description(guid)),
                    (f"binaries/{plat}/{MODEL_IDENTIFIER}{ext}", library.read_bytes()),
                    (f"sources/{C_SOURCE.name}", source.read_bytes()),
                ):
                    z.writestr(zipfile.ZipInfo(name, _ZIP_TIME), data, zipfile.ZIP_DEFLATED)

        atomic_write(dest / C_FMU_NAME, write, binary=True)
    return dest / C_FMU_NAME


def ensure_c_isolator(dest: Path = DEFAULT_FMU_DIR, force: bool = False) -> Path:
    """Build the C isolator FMU into ``dest`` if it is missing or stale; returns its path."""
    fmu = Path(dest) / C_FMU_NAME
    if force or is_stale(fmu):
        build_c_isolator(dest)
    return fmu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Build the plain-C MRE isolator FMU.")
    parser.add_argument("--dest", type=Path, default=DEFAULT_FMU_DIR, help=f"output folder (default {DEFAULT_FMU_DIR})")
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    args = parser.parse_args(argv)
    print(ensure_c_isolator(args.dest, args.force))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
