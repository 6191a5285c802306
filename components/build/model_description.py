"""Completing a modelDescription: SI units, full-precision starts and the model structure.

pythonfmu 0.7 writes no units and no output dependencies; :func:`complete_model_description`
adds ``UnitDefinitions`` for every unit a shell declares in ``fmi_units``, the ``unit``
attribute on each Real, and ``ModelStructure`` with ``Outputs`` and ``InitialUnknowns``
whose dependencies come from ``fmi_dependencies``. The plain-C isolator's build uses it too.
"""

from __future__ import annotations

from xml.etree import ElementTree as ET

from mre_common.project_paths import PROJECT_DIR as PROJECT_DIR  # re-exported: the checkout or site-packages
from mre_common.project_paths import fmu_dir

DEFAULT_FMU_DIR = fmu_dir()  # the checkout's fmus/ when writable, else the per-user cache (mre_common.project_paths)


class BuildError(RuntimeError):
    """An FMU could not be built."""


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
    "J": {"kg": 1, "m": 2, "s": -2},  # energy (the building's energy integrals)
    "N/A": {"kg": 1, "m": 1, "s": -2, "A": -1},
    "N/(m.A)": {"kg": 1, "s": -2, "A": -1},
    "N.s/(m.A)": {"kg": 1, "s": -1, "A": -1},
    "1/m": {"m": -1},
    "1/(m.A)": {"m": -1, "A": -1},
    "1/s": {"s": -1},
    "A": {"A": 1},
    "A/s": {"A": 1, "s": -1},
    "m0.5/s1.5": None,  # m^0.5 s^-1.5: SOSM gain theta
    "A.s0.5/m0.5": None,  # A s^0.5 m^-0.5: SOSM gain zeta
    # model-based controllers: frequencies, H2 weights and white-noise intensities
    "Hz": {"s": -1},
    "1/m2": {"m": -2},
    "s2/m2": {"m": -2, "s": 2},
    "s4/m2": {"m": -2, "s": 4},
    "1/N2": {"kg": -2, "m": -2, "s": 4},
    "m2/s3": {"m": 2, "s": -3},
    "m2.s": {"m": 2, "s": 1},
    "N2.s": {"kg": 2, "m": 2, "s": -3},
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
    used = _set_reals(index, units, starts or {})
    if used:
        root.append(_unit_definitions(used))
    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    root.append(_model_structure(index, deps))
    root[:] = sorted(root, key=lambda e: _ELEMENT_ORDER.index(e.tag))
    for element in root.iter():
        element.tail = None
        if element.text is not None and not element.text.strip():
            element.text = None
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _set_reals(index: dict[str, tuple[int, ET.Element]], units: dict[str, str], starts: dict[str, float]) -> set[str]:
    """Full-precision start values and the units of the Real variables; the units used."""
    used = set()
    for name, (_, sv) in index.items():
        real = sv.find("Real")
        if real is not None and name in starts and real.get("start") is not None:
            real.set("start", repr(starts[name]))
        if real is None or name not in units:
            continue
        unit = units[name]
        if unit not in SI_UNITS:
            raise BuildError(f"variable {name}: unit {unit!r} is not in components.build.model_description.SI_UNITS")
        real.set("unit", unit)
        used.add(unit)
    return used


def _unit_definitions(used: set[str]) -> ET.Element:
    unit_defs = ET.Element("UnitDefinitions")
    for unit in sorted(used):
        node = ET.SubElement(unit_defs, "Unit", name=unit)
        exponents = SI_UNITS[unit]
        if exponents is not None:
            ET.SubElement(node, "BaseUnit", {k: str(v) for k, v in exponents.items()})
    return unit_defs


def _model_structure(index: dict[str, tuple[int, ET.Element]], deps: dict[str, tuple[str, ...]]) -> ET.Element:
    """The outputs with their declared dependencies on inputs, and the initial unknowns."""
    structure = ET.Element("ModelStructure")
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
    return structure
