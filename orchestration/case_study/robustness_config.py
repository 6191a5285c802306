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
* ``set``: ``unit.parameter`` -> value [the parameter's SI unit] on top of the record scenario's. Only plant
  units. The sampled plants below are variants of this kind.
* ``current_lag``: tau [s] > 0 of a ``CurrentLag`` unit inserted between the controller's command and the
  isolator (in series with the scenario's own coil lag, if it has one; a scenario's lag is varied by ``scale``).

``plant_samples`` (beside or instead of ``variants``) draws plants from the isolator's identified uncertainty
(:mod:`components.identification.plant_sampling`): ``lhs`` variants ``lhs-001`` ... from a Latin hypercube, for
each criterion's spread, and ``sobol`` base points of SALib's Saltelli design on the first ``axes`` principal axes
(``sobol-0001`` ..., N (axes + 2) variants), for the Sobol indices; each sets the unit's coefficients::

    plant_samples: {file: plants/plant_samples_bouc_wen-joint.yaml, unit: isolator, lhs: 32, sobol: 16, axes: 4}

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
SAMPLED = re.compile(r"(lhs-\d{3,}|sobol-\d{4,})")  # the names of the sampled plants (RobustnessSpec.variant_names)
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
    set: dict[str, StrictFloat] = Field(default_factory=dict)  # "unit.parameter" -> value [SI] on the plant

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

    @field_validator("set")
    @classmethod
    def _set(cls, value: dict[str, float]) -> dict[str, float]:
        for key in value:
            if not _PORT.match(key):
                raise ValueError(f"set: {key!r} is not a parameter 'unit.parameter'")
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
        if not (self.plant or self.scale or self.set or self.sensors is not None or self.current_lag is not None):
            raise ValueError("a variant needs at least one of plant, scale, set, sensors, current_lag")
        return self


class PlantSamplingSpec(_Strict):
    """Plants drawn from a plant-sample file's covariance (see the module): how many, for what, and the seed."""

    file: StrictStr  # a plant-sample file (kind: plant-samples), relative to the file that wrote it
    unit: StrictStr = "isolator"  # the unit whose coefficients each sample sets
    lhs: StrictInt = Field(32, ge=0, le=4096)  # Latin-hypercube samples (0: none)
    sobol: StrictInt = Field(0, ge=0, le=4096)  # SALib's base sample N (a power of 2; 0: no Sobol indices)
    axes: StrictInt = Field(4, ge=1, le=12)  # principal axes the Sobol design varies (the others at 0)
    seed: StrictInt = Field(1, ge=0, le=2**32 - 1)

    @field_validator("unit")
    @classmethod
    def _unit_name(cls, value: str) -> str:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", value):
            raise ValueError(f"unit {value!r}: a unit name of the scenario (letters, digits, '_')")
        return value

    def names(self, axes: int | None = None) -> tuple[list[str], list[str]]:
        """(Latin-hypercube names lhs-001 ..., Saltelli names sobol-0001 ...) for ``axes`` principal axes
        (default ``self.axes``): the one place the sampled plants are named."""
        k = self.axes if axes is None else axes
        return ([f"lhs-{j:03d}" for j in range(1, self.lhs + 1)],
                [f"sobol-{j:04d}" for j in range(1, self.sobol * (k + 2) + 1)])

    @field_validator("sobol")
    @classmethod
    def _power_of_two(cls, value: int) -> int:
        if value and value & (value - 1):
            raise ValueError(f"sobol = {value}: SALib's Saltelli design needs a power of 2 (e.g. "
                             f"{1 << (value.bit_length() - 1)} or {1 << value.bit_length()})")
        return value

    @field_validator("lhs")
    @classmethod
    def _spread(cls, value: int) -> int:
        if value == 1:
            raise ValueError("lhs = 1: a spread needs at least 2 samples")
        return value

    @model_validator(mode="after")
    def _some(self) -> PlantSamplingSpec:
        if not (self.lhs or self.sobol):
            raise ValueError("plant_samples needs lhs > 0 or sobol > 0 (it would draw no plant)")
        return self


class RobustnessSpec(_Strict):
    """The study's variants (run on every record x strategy of the study), and the units they insert."""

    variants: dict[str, VariantSpec] = Field(default_factory=dict)
    plant_samples: PlantSamplingSpec | None = None
    strategies: list[StrictStr] | None = None  # the strategies run under the variants (default: all the study's)
    sensors_fmu: StrictStr = "../fmus/SensorChannels.fmu"  # relative to the file that wrote it; default: the project's
    lag_fmu: StrictStr = "../fmus/CurrentLag.fmu"

    @field_validator("variants")
    @classmethod
    def _names(cls, value: dict[str, VariantSpec]) -> dict[str, VariantSpec]:
        for name in value:
            if name in ("nominal", "reference") or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.+-]*", name):
                raise ValueError(f"variant name {name!r}: letters, digits, '_.+-' only, not 'nominal' or 'reference'")
            if SAMPLED.fullmatch(name):
                raise ValueError(f"variant name {name!r}: lhs-NNN and sobol-NNNN are the sampled plants' names")
        return value

    @model_validator(mode="after")
    def _any(self) -> RobustnessSpec:
        if not self.variants and self.plant_samples is None:
            raise ValueError("robustness needs at least one variant (or plant_samples)")
        return self

    def variant_names(self) -> list[str]:
        """Every variant's name: the declared ones, then the sampled plants' (lhs-001 ..., sobol-0001 ...)."""
        names = list(self.variants)
        if self.plant_samples is not None:
            lhs, sobol = self.plant_samples.names()
            names += lhs + sobol
        return names
