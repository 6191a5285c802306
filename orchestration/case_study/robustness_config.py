"""The robustness variants of a controller benchmark (issue 23, part 4): the ``robustness`` section of a study file.

Every controller is designed on the nominal models; a variant runs it against a plant (or a
measurement chain) that differs from them. A variant is a declared overlay on every record x
strategy run of the study, made of real swapped units and parameters:

```yaml
robustness:
  variants:
    bouc-wen:   {label: Bouc-Wen isolator, plant: {isolator: ../fmus/BoucWenIsolator.fmu}}
    mass-1.2:   {scale: {building.m_0: 1.2, building.m_1: 1.2, building.m_2: 1.2, building.m_3: 1.2}}
    noise:      {sensors: {seed: 1, noise_rms: {building.x_0: 1.0e-4, isolator.F: 10.0, ...}}}
    delay-1:    {sensors: {delay: 1}}
    lag-10ms:   {current_lag: 0.010}
```

* ``plant``: unit -> FMU that replaces the record scenario's (relative to the file that wrote it). The
  controller unit cannot be swapped: a variant changes the plant, not the design.
* ``scale``: ``unit.parameter`` -> factor (> 0) on the parameter's nominal value (the record
  scenario's, else the FMU's start value). Only plant units: the controllers keep their own nominal model
  parameters (their ``m_j``, ``k_j``, isolator law), which never read the plant's.
* ``sensors``: every connection into the controller goes through the ``SensorChannels`` unit
  (``components/shells/sensor_channels_fmu.py``): seeded Gaussian noise of the stated RMS per source
  signal (``unit.variable`` -> RMS in that variable's SI unit; when any is given, every signal a strategy
  reads needs one) and ``delay`` whole communication steps.
* ``current_lag``: tau [s] of the ``CurrentLag`` unit inserted between the controller's command and the
  isolator (0: no lag, no unit; < 0 refused).

Problems are reported together, each naming its key and line (exit 2, nothing written).
"""

from __future__ import annotations

import math
import re

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

MAX_DELAY_STEPS = 100_000  # the SensorChannels unit's limit (components/physics/sensor_channels_core.py)
_PORT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\.[A-Za-z_][A-Za-z0-9_.\[\]]*$")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SensorSpec(_Strict):
    """Measurement channels between the plant and the controller: noise and delay."""

    noise_rms: dict[str, float] = Field(default_factory=dict)  # source "unit.variable" -> RMS [its SI unit]
    seed: int = Field(1, ge=0, lt=2**32)  # seed of the SensorChannels unit's noise
    delay: int = Field(0, ge=0, le=MAX_DELAY_STEPS)  # [communication steps]

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


class VariantSpec(_Strict):
    """One variation of the plant or of the measurement chain (see the module)."""

    label: str = ""
    plant: dict[str, str] = Field(default_factory=dict)  # unit -> FMU replacing it
    scale: dict[str, float] = Field(default_factory=dict)  # "unit.parameter" -> factor on its nominal value
    sensors: SensorSpec | None = None
    current_lag: float | None = None  # tau [s] of the CurrentLag unit; 0: no lag

    @field_validator("scale")
    @classmethod
    def _scale(cls, value: dict[str, float]) -> dict[str, float]:
        for key, factor in value.items():
            if not _PORT.match(key):
                raise ValueError(f"scale: {key!r} is not a parameter 'unit.parameter'")
            if not factor > 0:
                raise ValueError(f"scale.{key}: the factor must be positive, got {factor}")
        return value

    @field_validator("current_lag")
    @classmethod
    def _lag(cls, value: float | None) -> float | None:
        if value is not None and not value >= 0:
            raise ValueError(f"the CurrentLag unit's parameter tau must be >= 0 s (0: no lag), got {value}")
        return value

    @model_validator(mode="after")
    def _something(self) -> VariantSpec:
        if not (self.plant or self.scale or self.sensors is not None or self.current_lag is not None):
            raise ValueError("a variant needs at least one of plant, scale, sensors, current_lag")
        return self


class RobustnessSpec(_Strict):
    """The study's variants (run on every record x strategy of the study), and the units they insert."""

    variants: dict[str, VariantSpec]
    sensors_fmu: str = "../fmus/SensorChannels.fmu"  # relative to the file that wrote it; default: the project's
    lag_fmu: str = "../fmus/CurrentLag.fmu"

    @field_validator("variants")
    @classmethod
    def _names(cls, value: dict[str, VariantSpec]) -> dict[str, VariantSpec]:
        if not value:
            raise ValueError("robustness needs at least one variant")
        for name in value:
            if name in ("nominal", "reference") or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.+-]*", name):
                raise ValueError(f"variant name {name!r}: letters, digits, '_.+-' only, not 'nominal' or 'reference'")
        return value
