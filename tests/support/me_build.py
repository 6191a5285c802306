"""Build the tests' FMI 2.0 Model Exchange FMUs from C (``tests/support/me/*.c`` on the frame
``tests/support/me/fmi2_frame.h``).

* ``Oscillator.fmu``: a damped oscillator driven by a force input, Model Exchange only;
* ``OscillatorCS.fmu``: the same model with Co-Simulation only;
* ``OscillatorBoth.fmu``: the same model with Model Exchange and Co-Simulation (its
  ``fmi2DoStep`` integrates with 4th-order Runge-Kutta, 10 sub-steps per step; the output
  ``cosim`` says which interface the importer instantiated);
* ``BouncingBall.fmu``: a state event (event indicator h) that resets the velocity;
* ``Pulse.fmu``: time events (``nextEventTime``) switching the input of a first-order lag;
  ``PulseBoth.fmu`` the same with Co-Simulation too.

Each is compiled with the system C compiler (``$CC``, default ``cc``) against the FMI 2.0
headers fmpy ships (``fmpy/c-code``), like ``tests/support/fmi3_build.py``; the modelDescription.xml
is written here, with the value references of each model's C enum.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import fmpy

from .fmi3_build import compile_fmu

SOURCES = Path(__file__).resolve().parent / "me"
FRAME = SOURCES / "fmi2_frame.h"
CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=hidden", "-Wall", "-Wextra", "-Werror")


@dataclass(frozen=True)
class Var:
    """One variable of a test model: value reference as in its C enum."""

    name: str
    vr: int
    causality: str
    variability: str = "continuous"
    start: float | int | None = None
    unit: str | None = None
    type: str = "Real"
    derivative: str | None = None  # the state this variable is the derivative of
    description: str = ""


@dataclass(frozen=True)
class Model:
    """A C model and what its modelDescription declares."""

    identifier: str
    source: str
    variables: tuple[Var, ...]
    states: tuple[str, ...]
    indicators: int = 0
    dependencies: tuple[tuple[str, tuple[str, ...]], ...] = ()  # output -> what it depends on
    co_simulation: bool = False
    completed_step_needed: bool = False  # the importer must call fmi2CompletedIntegratorStep
    model_exchange: bool = True  # declare the Model Exchange interface

    def var(self, name: str) -> Var:
        return next(v for v in self.variables if v.name == name)


def _par(name: str, vr: int, start: float, unit: str | None, description: str) -> Var:
    return Var(name, vr, "parameter", "fixed", start, unit, description=description)


OSCILLATOR_VARIABLES = (
    Var("x", 0, "output", unit="m", description="displacement"),
    Var("v", 1, "output", unit="m/s", description="velocity"),
    Var("der_x", 2, "local", unit="m/s", derivative="x"),
    Var("der_v", 3, "local", unit="m/s2", derivative="v"),
    Var("u", 4, "input", start=0.0, unit="N", description="driving force"),
    _par("m", 5, 1.0, "kg", "mass"),
    _par("c", 6, 0.4, "N.s/m", "damping"),
    _par("k", 7, 4.0, "N/m", "stiffness"),
    _par("x0", 8, 1.0, "m", "initial displacement"),
    _par("v0", 9, 0.0, "m/s", "initial velocity"),
    _par("fail_at", 10, -1.0, "s", "fmi2GetDerivatives fails once the time passes this (negative: never)"),
    Var("a", 11, "output", unit="m/s2", description="acceleration (direct feedthrough from u)"),
    Var("cosim", 12, "output", "discrete", description="1 when instantiated for Co-Simulation, 0 for Model Exchange"),
)
_OSCILLATOR_DEPS = (("x", ("x",)), ("v", ("v",)), ("a", ("x", "v", "u")), ("cosim", ()))

OSCILLATOR = Model("Oscillator", "oscillator.c", OSCILLATOR_VARIABLES, ("x", "v"), 0, _OSCILLATOR_DEPS)
OSCILLATOR_BOTH = Model("OscillatorBoth", "oscillator.c", OSCILLATOR_VARIABLES, ("x", "v"), 0, _OSCILLATOR_DEPS,
                        co_simulation=True)
BOUNCING_BALL = Model("BouncingBall", "bouncing_ball.c", (
    Var("h", 0, "output", unit="m", description="height above the floor"),
    Var("v", 1, "output", unit="m/s", description="velocity (up)"),
    Var("der_h", 2, "local", unit="m/s", derivative="h"),
    Var("der_v", 3, "local", unit="m/s2", derivative="v"),
    _par("g", 4, 9.81, "m/s2", "gravity"),
    _par("e", 5, 0.7, None, "coefficient of restitution"),
    _par("h0", 6, 1.0, "m", "initial height"),
    Var("t_bounce", 7, "output", "discrete", unit="s", description="time of the last bounce (-1: none yet)"),
    Var("v_before", 8, "output", "discrete", unit="m/s", description="velocity just before the last bounce"),
    Var("bounces", 0, "output", "discrete", type="Integer", description="bounces so far"),
    Var("max_bounces", 1, "parameter", "fixed", 0, type="Integer",
        description="terminate the simulation at this bounce (0: never)"),
), ("h", "v"), 1, (("h", ("h",)), ("v", ("v",)), ("t_bounce", ()), ("v_before", ()), ("bounces", ())),
    completed_step_needed=True)
PULSE = Model("Pulse", "pulse.c", (
    Var("y", 0, "output", description="lag output"),
    Var("der_y", 1, "local", unit="1/s", derivative="y"),
    Var("level", 2, "output", "discrete", description="pulse level"),
    _par("tau", 3, 0.2, "s", "time constant"),
    _par("amplitude", 4, 1.0, None, "pulse level when on"),
    _par("t_on", 5, 0.1234, "s", "first switch on"),
    _par("width", 6, 0.3333, "s", "time on per period"),
    _par("period", 7, 1.0, "s", "period"),
    Var("switches", 0, "output", "discrete", type="Integer", description="switches so far"),
), ("y",), 0, (("y", ("y",)), ("level", ()), ("switches", ())))

OSCILLATOR_CS = Model("OscillatorCS", "oscillator.c", OSCILLATOR_VARIABLES, ("x", "v"), 0, _OSCILLATOR_DEPS,
                      co_simulation=True, model_exchange=False)
PULSE_BOTH = Model("PulseBoth", PULSE.source, PULSE.variables, PULSE.states, PULSE.indicators, PULSE.dependencies,
                   co_simulation=True)

MODELS = {m.identifier: m for m in (OSCILLATOR, OSCILLATOR_BOTH, OSCILLATOR_CS, BOUNCING_BALL, PULSE, PULSE_BOTH)}


def _fmt(value: float | int) -> str:
    return repr(value) if isinstance(value, float) else str(value)


def model_description(model: Model, guid: str) -> str:
    """The model's modelDescription.xml (FMI 2.0)."""
    index = {v.name: k + 1 for k, v in enumerate(model.variables)}
    rows = []
    for v in model.variables:
        attributes = f'name="{v.name}" valueReference="{v.vr}" causality="{v.causality}" variability="{v.variability}"'
        if v.description:
            attributes += f' description="{v.description}"'
        inner = []
        if v.start is not None:
            inner.append(f'start="{_fmt(v.start)}"')
        if v.unit:
            inner.append(f'unit="{v.unit}"')
        if v.derivative:
            inner.append(f'derivative="{index[v.derivative]}"')
        rows.append(f'    <ScalarVariable {attributes}><{v.type} {" ".join(inner)}/></ScalarVariable>')
    units = sorted({v.unit for v in model.variables if v.unit})
    deps = dict(model.dependencies)

    def unknown(name: str) -> str:
        listed = " ".join(str(index[d]) for d in deps.get(name, ()))
        return f'      <Unknown index="{index[name]}" dependencies="{listed}"/>'

    outputs = [v.name for v in model.variables if v.causality == "output"]
    derivatives = [next(v.name for v in model.variables if v.derivative == s) for s in model.states]
    initial = sorted({*outputs, *model.states, *derivatives}, key=index.__getitem__)
    cs = (f'  <CoSimulation modelIdentifier="{model.identifier}" canHandleVariableCommunicationStepSize="true"/>\n'
          if model.co_simulation else "")
    me = (f'  <ModelExchange modelIdentifier="{model.identifier}" '
          f'completedIntegratorStepNotNeeded="{str(not model.completed_step_needed).lower()}"/>\n'
          if model.model_exchange else "")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{model.identifier}" guid="{guid}"
  description="test model {model.source}" generationTool="tests/support/me_build.py"
  numberOfEventIndicators="{model.indicators}">
{me}{cs}  <UnitDefinitions>
{chr(10).join(f'    <Unit name="{u}"/>' for u in units)}
  </UnitDefinitions>
  <LogCategories>
    <Category name="logEvents"/>
    <Category name="logStatusError"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stopTime="1"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{chr(10).join(unknown(n) for n in outputs)}
    </Outputs>
    <Derivatives>
{chr(10).join(f'      <Unknown index="{index[d]}"/>' for d in derivatives)}
    </Derivatives>
    <InitialUnknowns>
{chr(10).join(f'      <Unknown index="{index[n]}"/>' for n in initial)}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def build(model: Model, dest: Path) -> Path:
    """Compile ``model`` and package ``dest/<identifier>.fmu``; raises CalledProcessError on a C error."""
    return compile_fmu(dest, model.identifier, SOURCES / model.source, lambda guid: model_description(model, guid),
                       token_define="MODEL_GUID", platform=fmpy.platform, headers=(FRAME,),
                       defines=["-DCO_SIMULATION"] if model.co_simulation else [], cflags=CFLAGS, libs=["-lm"])


def build_all(dest: Path) -> dict[str, Path]:
    """Every test model, built into ``dest``: identifier -> FMU path."""
    return {name: build(model, dest) for name, model in MODELS.items()}
