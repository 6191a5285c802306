"""Build the tests' typed units from C: ``Typed2.fmu`` (FMI 2.0: Real, Integer, Boolean, String,
Enumeration) and ``Typed3.fmu`` (FMI 3.0: Float64 ... UInt64, Boolean, String, Enumeration).

The sources are ``tests/support/typed/typed2.c`` and ``tests/support/typed/typed3.c``, compiled with the system C
compiler (``$CC``, default ``cc``) against the FMI headers fmpy ships (``fmpy/c-code``), as
tests/support/fmi3_build.py does; the modelDescription.xml is written here with the value references of
the C enums. Each unit has, per type, an input ``u_<Type>`` and an output ``y_<Type>``.
"""

from __future__ import annotations

from pathlib import Path

import fmpy

from .fmi3_build import REFUSED, compile_fmu

HERE = Path(__file__).resolve().parent / "typed"
HEADERS = Path(fmpy.__file__).resolve().parent / "c-code"
CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=default", "-Wall", "-Wextra", "-Werror")

ITEMS = (("low", 1), ("mid", 2), ("high", 5), ("neg", -3))
"""The enumeration type ``Level`` of both units (name, value)."""

TYPES2 = ("Real", "Integer", "Boolean", "String", "Enumeration")
PARAMETERS2 = {"echo": ("Boolean", "false"), "label": ("String", "typed"), "start": ("Real", "0"),
               "k": ("Integer", "0"), "first": ("Enumeration", "1")}
TYPES3 = ("Float64", "Float32", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
          "Boolean", "String", "Enumeration")
PARAMETERS3 = {"echo": ("Boolean", "false"), "big": ("Boolean", "false"), "label": ("String", "typed"),
               "start": ("Float64", "0"), "k8": ("Int8", "0"), "first": ("Enumeration", "1")}
_INPUT_START = {"Boolean": "false", "String": "", "Enumeration": "1"}


def _variability(fmi_type: str, causality: str) -> str:
    if causality == "parameter":
        return "fixed"
    continuous = fmi_type in ("Real", "Float64", "Float32") and causality == "input"
    return "continuous" if continuous else "discrete"


def description2(guid: str) -> str:
    """Typed2's modelDescription.xml (parameters vr 0-4, inputs 10 + j, outputs 20 + j)."""
    rows: list[tuple[str, int, str, str, str | None]] = [
        (name, vr, t, "parameter", start) for vr, (name, (t, start)) in enumerate(PARAMETERS2.items())]
    rows += [(f"u_{t}", 10 + j, t, "input", _INPUT_START.get(t, "0")) for j, t in enumerate(TYPES2)]
    rows += [(f"y_{t}", 20 + j, t, "output", None) for j, t in enumerate(TYPES2)]
    xml = []
    for name, vr, t, causality, start in rows:
        attrs = ' declaredType="Level"' if t == "Enumeration" else ""
        attrs += f' start="{start}"' if start is not None else ""
        initial = ' initial="calculated"' if causality == "output" else ""
        xml.append(f'    <ScalarVariable name="{name}" valueReference="{vr}" causality="{causality}" '
                   f'variability="{_variability(t, causality)}"{initial}><{t}{attrs}/></ScalarVariable>')
    first_output = len(rows) - len(TYPES2) + 1  # 1-based index
    outputs = "\n".join(f'      <Unknown index="{first_output + j}" dependencies=""/>' for j in range(len(TYPES2)))
    initial = "\n".join(f'      <Unknown index="{first_output + j}"/>' for j in range(len(TYPES2)))
    items = "".join(f'<Item name="{n}" value="{v}"/>' for n, v in ITEMS)
    variables = "\n".join(xml)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Typed2" guid="{guid}" generationTool="tests/support/typed_build.py"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Typed2" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions>
    <SimpleType name="Level"><Enumeration>{items}</Enumeration></SimpleType>
  </TypeDefinitions>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/>
  <ModelVariables>
{variables}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}
    </Outputs>
    <InitialUnknowns>
{initial}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def description3(token: str) -> str:
    """Typed3's modelDescription.xml (time vr 0, parameters 1-6, inputs 10 + j, outputs 30 + j)."""
    rows: list[tuple[str, int, str, str, str | None]] = [
        (name, vr, t, "parameter", start) for vr, (name, (t, start)) in enumerate(PARAMETERS3.items(), start=1)]
    rows += [(f"u_{t}", 10 + j, t, "input", _INPUT_START.get(t, "0")) for j, t in enumerate(TYPES3)]
    rows += [(f"y_{t}", 30 + j, t, "output", None) for j, t in enumerate(TYPES3)]
    xml = ['    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>']
    for name, vr, t, causality, start in rows:
        head = (f'name="{name}" valueReference="{vr}" causality="{causality}" '
                f'variability="{_variability(t, causality)}"')
        head += ' declaredType="Level"' if t == "Enumeration" else ""
        if t == "String":
            body = f'<Start value="{start}"/>' if start is not None else ""
            xml.append(f"    <String {head}>{body}</String>")
        else:
            xml.append(f'    <{t} {head}' + (f' start="{start}"' if start is not None else "") + "/>")
    outputs = "\n".join(f'    <Output valueReference="{30 + j}" dependencies=""/>' for j in range(len(TYPES3)))
    initial = "\n".join(f'    <InitialUnknown valueReference="{30 + j}"/>' for j in range(len(TYPES3)))
    items = "".join(f'<Item name="{n}" value="{v}"/>' for n, v in ITEMS)
    variables = "\n".join(xml)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Typed3" instantiationToken="{token}"
  generationTool="tests/support/typed_build.py" variableNamingConvention="flat">
  <CoSimulation modelIdentifier="Typed3" canHandleVariableCommunicationStepSize="true" hasEventMode="false"/>
  <TypeDefinitions>
    <EnumerationType name="Level">{items}</EnumerationType>
  </TypeDefinitions>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/>
  <ModelVariables>
{variables}
  </ModelVariables>
  <ModelStructure>
{outputs}
{initial}
  </ModelStructure>
</fmiModelDescription>
"""


def _build(dest: Path, source: Path, identifier: str, define: str, description, platform: str) -> Path:
    headers = [h for h in (REFUSED,) if f'#include "{h.name}"'.encode() in source.read_bytes()]
    return compile_fmu(dest, identifier, source, description, token_define=define, platform=platform,
                       headers=headers, cflags=CFLAGS)


def build_typed2(dest: Path) -> Path:
    """Compile and package ``dest/Typed2.fmu`` (FMI 2.0); raises CalledProcessError on a C error."""
    return _build(dest, HERE / "typed2.c", "Typed2", "MODEL_GUID", description2, fmpy.platform)


def build_typed3(dest: Path) -> Path:
    """Compile and package ``dest/Typed3.fmu`` (FMI 3.0); raises CalledProcessError on a C error."""
    return _build(dest, HERE / "typed3.c", "Typed3", "INSTANTIATION_TOKEN", description3, fmpy.platform_tuple)
