"""The robustness variants of a controller benchmark: the ``robustness`` section of a study file.

Every controller is designed on the nominal models; a variant runs it against a plant (or a
measurement chain) that differs from them. A variant is a declared overlay on every record x
strategy run of the study, made of real swapped units and parameters:

```yaml
robustness:
  variants:
    paper-law:  {plant: {isolator: {fmu: ../fmus/MreIsolator.fmu, parameters: {n_isolators: 2}}}}
    mass-1.2:   {scale: {building.m_0: 1.2, building.m_1: 1.2, building.m_2: 1.2, building.m_3: 1.2}}
    lag-x3:     {scale: {coil.tau: 3.0}}
    noise:      {sensors: {seed: 1, noise_rms: {building.x_0: 1.0e-4, isolator.F: 10.0, ...}}}
    delay-1:    {sensors: {delay: 1}}
    lag-10ms:   {current_lag: 0.010}
```

* ``plant``: unit -> FMU that replaces the record scenario's (relative to the file that wrote it), or
  ``{fmu: ..., parameters: {...}}``, whose parameters replace the unit's (the study's current limit is set on
  top again). The unit must be in the scenario, and the swap must change it. The controller unit cannot be
  swapped: a variant changes the plant, not the design.
* ``scale``: ``unit.parameter`` -> factor (> 0, not 1) on the parameter's nominal value (the record
  scenario's, else the FMU's start value), which must not be 0. Only plant units: the controllers keep their
  own nominal model parameters (their ``m_j``, ``k_j``, isolator law), which never read the plant's.
* ``sensors``: every connection into the controller goes through the ``SensorChannels`` unit
  (``components/shells/sensor_channels_fmu.py``): seeded Gaussian noise of the stated RMS per source
  signal (``unit.variable`` -> RMS in that variable's SI unit; when any is given, every signal a strategy
  reads needs one) and ``delay`` whole communication steps. A delay of 0 without noise is refused (an exact
  pass-through). ``seed`` is an FMI Integer (int32): 0 ... 2**31 - 1.
* ``current_lag``: tau [s] > 0 of a ``CurrentLag`` unit inserted between the controller's command and the
  isolator (in series with the scenario's own coil lag, if it has one; a scenario's lag is varied by ``scale``).

A variant that would run the nominal plant unchanged is refused, and numbers are numbers: ``true``, ``'0.01'``
or ``1.5`` for an integer are refused (pydantic strict types). Problems are reported together, each naming
its key and line (exit 2, nothing written).
"""

from __future__ import annotations

import math
import re

from pydantic import BaseModel, ConfigDict, Field, StrictFloat, StrictInt, StrictStr, field_validator, model_validator

MAX_DELAY_STEPS = 100_000  # the SensorChannels unit's limit (components/physics/sensor_channels_core.py)
MAX_SEED = 2**31 - 1  # the SensorChannels unit's seed is an FMI Integer: a signed 32-bit integer
_PORT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\.[A-Za-z_][A-Za-z0-9_.\[\]]*$")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SensorSpec(_Strict):
    """Measurement channels between the plant and the controller: noise and delay."""

    noise_rms: dict[str, StrictFloat] = Field(default_factory=dict)  # source "unit.variable" -> RMS [its SI unit]
    seed: StrictInt = Field(1, ge=0, le=MAX_SEED)  # seed of the SensorChannels unit's noise (an FMI Integer)
    delay: StrictInt = Field(0, ge=0, le=MAX_DELAY_STEPS)  # [communication steps]

    @field_validator("noise_rms")
    @classmethod
    def _rms(cls, value: dict[str, float]) -> dict[str, float]:
        for port, rms in value.items():
            if not _PORT.match(port):
                raise ValueError(f"noise_rms: {port!r} is not a signal 'unit.variable'")
            if not (math.isfinite(rms) and rms >= 0):
                raise ValueError(f"noise_rms.{port}: the SensorChannels unit's noise RMS must be >= 0 (SI unit of "
                                 f"{port}), got {rms}")
        return value

    @model_validator(mode="after")
    def _changes_something(self) -> SensorSpec:
        if self.delay == 0 and not any(self.noise_rms.values()):
            raise ValueError("sensors with no delay and no noise are an exact pass-through: the variant would be "
                             "the nominal run (give a delay >= 1 or a noise_rms > 0)")
        return self


class PlantUnit(_Strict):
    """A plant unit's replacement: its FMU and the parameters that replace the scenario's for it."""

    fmu: StrictStr
    parameters: dict[str, StrictFloat | StrictInt | StrictStr | bool] = Field(default_factory=dict)


class VariantSpec(_Strict):
    """One variation of the plant or of the measurement chain (see the module)."""

    label: StrictStr = ""
    plant: dict[str, StrictStr | PlantUnit] = Field(default_factory=dict)  # unit -> FMU (and parameters) replacing it
    scale: dict[str, StrictFloat] = Field(default_factory=dict)  # "unit.parameter" -> factor on its nominal value
    sensors: SensorSpec | None = None
    current_lag: StrictFloat | None = None  # tau [s] > 0 of an inserted CurrentLag unit

    @field_validator("scale")
    @classmethod
    def _scale(cls, value: dict[str, float]) -> dict[str, float]:
        for key, factor in value.items():
            if not _PORT.match(key):
                raise ValueError(f"scale: {key!r} is not a parameter 'unit.parameter'")
            if not factor > 0:
                raise ValueError(f"scale.{key}: the factor must be positive, got {factor}")
            if factor == 1:
                raise ValueError(f"scale.{key}: a factor of 1 changes nothing (the variant would be the nominal run)")
        return value

    @field_validator("current_lag")
    @classmethod
    def _lag(cls, value: float | None) -> float | None:
        if value is not None and not value > 0:
            raise ValueError(f"the CurrentLag unit's parameter tau must be > 0 s (0 would insert no lag: the "
                             f"nominal run), got {value}")
        return value

    @model_validator(mode="after")
    def _something(self) -> VariantSpec:
        if not (self.plant or self.scale or self.sensors is not None or self.current_lag is not None):
            raise ValueError("a variant needs at least one of plant, scale, sensors, current_lag")
        return self


class RobustnessSpec(_Strict):
    """The study's variants (run on every record x strategy of the study), and the units they insert."""

    variants: dict[str, VariantSpec]
    sensors_fmu: StrictStr = "../fmus/SensorChannels.fmu"  # relative to the file that wrote it; default: the project's
    lag_fmu: StrictStr = "../fmus/CurrentLag.fmu"

    @field_validator("variants")
    @classmethod
    def _names(cls, value: dict[str, VariantSpec]) -> dict[str, VariantSpec]:
        if not value:
            raise ValueError("robustness needs at least one variant")
        for name in value:
            if name in ("nominal", "reference") or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.+-]*", name):
                raise ValueError(f"variant name {name!r}: letters, digits, '_.+-' only, not 'nominal' or 'reference'")
        return value
