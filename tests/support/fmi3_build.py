"""Build the tests' FMI 3.0 Co-Simulation unit (``ConstantCurrent3.fmu``) from C, and craft
description-only FMUs (FMI 1.0, model exchange only, ...) for the refusal tests (an FMI 2.0
model-exchange-only FMU is accepted, then refused for its missing library; FMI 2.0 model
exchange FMUs that run are built by tests/support/me_build.py).

The C source ``tests/support/fmi3/constant_current3.c`` is compiled with the system C compiler
(``$CC``, default ``cc``) against the FMI 3.0 headers fmpy ships (``fmpy/c-code``); the
modelDescription.xml is written here, with the value references of the C enum.
:func:`compile_fmu` and :func:`write_fmu` also build the other test C units (tests/support/typed_build.py,
tests/support/me_build.py).
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import tempfile
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

import fmpy

SOURCE = Path(__file__).resolve().parent / "fmi3" / "constant_current3.c"
REFUSED = SOURCE.parent / "fmi3_refused.h"  # the FMI 3.0 functions the tests' C units refuse (included)
MODEL_IDENTIFIER = "ConstantCurrent3"
HEADERS = Path(fmpy.__file__).resolve().parent / "c-code"
CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=hidden", "-Wall", "-Wextra", "-Werror")
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)

# name: (value reference, FMI 3.0 element, attributes) in the order of the C enum
VARIABLES: dict[str, tuple[int, str, str]] = {
    "time": (0, "Float64", 'causality="independent" variability="continuous" unit="s" description="simulation time"'),
    "current": (1, "Float64", 'causality="parameter" variability="fixed" declaredType="Current" start="0" '
                              'description="current to hold"'),
    "i": (2, "Float64", 'causality="output" variability="continuous" declaredType="Current" '
                        'description="command current"'),
    "offset": (3, "Float64", 'causality="input" variability="continuous" declaredType="Current" start="0" '
                             'description="added to the current"'),
    "fail_at": (4, "Float64", 'causality="parameter" variability="fixed" unit="s" start="-1" '
                              'description="fail at the first step past this time (negative: never)"'),
    "fail_mode": (5, "Int32", 'causality="parameter" variability="fixed" start="1" min="0" max="3" '
                              'description="0 none, 1 fmi3Error, 2 terminateSimulation, 3 fmi3Fatal"'),
    "count": (6, "Int64", 'causality="parameter" variability="fixed" start="1" '
                          'description="sources in parallel: i = count * current + offset"'),
    "enabled": (7, "Boolean", 'causality="parameter" variability="fixed" start="true" '
                              'description="false: i = 0"'),
    "tag": (8, "String", 'causality="parameter" variability="fixed" description="logged at initialization"'),
}


def _variables_xml() -> str:
    rows = []
    for name, (vr, element, attributes) in VARIABLES.items():
        if element == "String":
            rows.append(f'    <String name="{name}" valueReference="{vr}" {attributes}><Start value=""/></String>')
        else:
            rows.append(f'    <{element} name="{name}" valueReference="{vr}" {attributes}/>')
    return "\n".join(rows)


def model_description(token: str, output_dependencies: str | None = "3") -> str:
    """The unit's modelDescription.xml; ``output_dependencies=None`` leaves them undeclared."""
    vr_i = VARIABLES["i"][0]
    deps = "" if output_dependencies is None else f' dependencies="{output_dependencies}"'
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{MODEL_IDENTIFIER}" instantiationToken="{token}"
  description="Constant current source (FMI 3.0, plain C)" generationTool="tests/support/fmi3_build.py"
  variableNamingConvention="flat">
  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUState="false" canSerializeFMUState="false" hasEventMode="false"
    providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>
  <UnitDefinitions>
    <Unit name="A"><BaseUnit A="1"/></Unit>
    <Unit name="s"><BaseUnit s="1"/></Unit>
  </UnitDefinitions>
  <TypeDefinitions>
    <Float64Type name="Current" quantity="ElectricCurrent" unit="A"/>
  </TypeDefinitions>
  <LogCategories>
    <Category name="logEvents" description="teardown calls and the tag"/>
    <Category name="logStatusWarning" description="warnings"/>
    <Category name="logStatusError" description="errors"/>
    <Category name="logStatusFatal" description="fatal errors"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.001"/>
  <ModelVariables>
{_variables_xml()}
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="{vr_i}"{deps}/>
    <InitialUnknown valueReference="{vr_i}"/>
  </ModelStructure>
</fmiModelDescription>
"""


def write_fmu(path: Path, files: dict[str, bytes | str]) -> Path:
    """A zip with fixed timestamps holding ``files`` (archive name: content)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, content in files.items():
            info = zipfile.ZipInfo(name, _ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, content.encode("utf-8") if isinstance(content, str) else content)
    return path


def compile_fmu(dest: Path, identifier: str, source: Path, description: Callable[[str], str], *,
                token_define: str, platform: str, headers: Sequence[Path] = (), defines: Sequence[str] = (),
                cflags: Sequence[str] = CFLAGS, libs: Sequence[str] = ()) -> Path:
    """Compile a test unit's C ``source`` (with the local ``headers`` it includes) against fmpy's FMI headers and
    package ``dest/<identifier>.fmu``: the library under ``binaries/<platform>/``, the sources under
    ``sources/``, ``description(token)`` as modelDescription.xml. The GUID / instantiation token (passed to the C
    code as ``token_define``) is a hash of the sources and the identifier. Raises CalledProcessError on a C error.
    """
    code = {p.name: p.read_bytes() for p in (source, *headers)}
    token = "{" + hashlib.sha256(b"".join(code.values()) + identifier.encode()).hexdigest()[:32] + "}"
    binary = f"binaries/{platform}/{identifier}{fmpy.sharedLibraryExtension}"
    with tempfile.TemporaryDirectory() as tmp:
        library = Path(tmp) / f"{identifier}{fmpy.sharedLibraryExtension}"
        includes = [f"-I{folder}" for folder in dict.fromkeys(h.parent for h in headers)]
        cmd = [os.environ.get("CC", "cc"), *cflags, f"-I{HEADERS}", *includes, f'-D{token_define}="{token}"',
               *defines, "-o", str(library), str(source), *libs]
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        files = {"modelDescription.xml": description(token), binary: library.read_bytes(),
                 **{f"sources/{name}": data for name, data in code.items()}}
        return write_fmu(Path(dest) / f"{identifier}.fmu", files)


def build_constant_current3(dest: Path, output_dependencies: str | None = "3") -> Path:
    """Compile the C unit and package ``dest/ConstantCurrent3.fmu``; raises CalledProcessError on a C error."""
    return compile_fmu(dest, MODEL_IDENTIFIER, SOURCE, lambda token: model_description(token, output_dependencies),
                       token_define="INSTANTIATION_TOKEN", platform=fmpy.platform_tuple, headers=(REFUSED,))


FMI1_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="1.0" modelName="Old" modelIdentifier="Old" guid="{old}"
  numberOfContinuousStates="0" numberOfEventIndicators="0">
  <ModelVariables>
    <ScalarVariable name="i" valueReference="0" causality="output"><Real/></ScalarVariable>
  </ModelVariables>
  <Implementation>
    <CoSimulation_StandAlone>
      <Capabilities canHandleVariableCommunicationStepSize="true"/>
    </CoSimulation_StandAlone>
  </Implementation>
</fmiModelDescription>
"""

FMI2_ME_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Me2" guid="{me2}">
  <ModelExchange modelIdentifier="Me2"/>
  <ModelVariables>
    <ScalarVariable name="i" valueReference="0" causality="output"><Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""

FMI3_ME_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Me3" instantiationToken="{me3}">
  <ModelExchange modelIdentifier="Me3"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="i" valueReference="1" causality="output" variability="continuous"/>
  </ModelVariables>
  <ModelStructure><Output valueReference="1" dependencies=""/></ModelStructure>
</fmiModelDescription>
"""
