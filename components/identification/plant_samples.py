"""A file of sampled plants: N coefficient sets of the current-dependent isolator model, for studies.

Written by the identification run from the bootstrap of :mod:`joint_fits` (each sample one refit on a
fresh noise realisation with the conditions drawn with replacement), YAML, SI units, the FMU's variable
names::

    kind: plant-samples
    fmu: BoucWenIsolator
    model: bouc_wen
    synthetic: true
    coefficients: [k_0, k_1, ...]          # every sample has exactly these
    units: {k_0: N/(m.A), ...}
    nominal: {k_0: ..., ...}              # the joint fit on the data set itself
    samples: [{k_0: ..., ...}, ...]
    statistics: {...}                     # covariance, correlation, principal axes (paper units)

:func:`load_plant_samples` refuses a sample with a missing, extra, non-numeric or non-finite coefficient,
or one that is no device (``bouc_wen_core.device_problem``: beta + gamma <= 0, a force that does not rise
with displacement), naming the file, the sample and the coefficient (:class:`PlantSampleError`; the
command-line check ``python -m orchestration.identification.check_plants FILE`` exits 2).
"""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import yaml

from components.identification.generalized import SI_UNITS_OF, GeneralizationError
from components.physics.bouc_wen_core import COEFFICIENT_DOCS, BoucWenCurrentModel, device_problem
from components.physics.mre_isolator_core import ParameterError
from mre_common.atomic_files import atomic_write_text

KIND = "plant-samples"
COEFFICIENTS = tuple(COEFFICIENT_DOCS)  # BoucWenIsolator's coefficient parameters


class PlantSampleError(GeneralizationError):
    """A plant-sample file is unusable; the message names the file, the sample and the coefficient."""


def write_plant_samples(path: str | os.PathLike, nominal: BoucWenCurrentModel,
                        samples: Sequence[BoucWenCurrentModel], statistics: Mapping, note: str,
                        synthetic: bool) -> None:
    """Write the samples (SI) with their provenance and statistics."""
    doc = {
        "kind": KIND,
        "fmu": "BoucWenIsolator",
        "model": "bouc_wen",
        "synthetic": bool(synthetic),
        "note": note,
        "coefficients": list(COEFFICIENTS),
        "units": {k: SI_UNITS_OF[k] for k in COEFFICIENTS},
        "nominal": {k: float(v) for k, v in nominal.as_dict().items()},
        "samples": [{k: float(v) for k, v in s.as_dict().items()} for s in samples],
        "statistics": statistics,
    }
    head = "# SYNTHETIC DATA - not measured. " if synthetic else "# "
    text = head + "Sampled isolator plants (BoucWenIsolator coefficients, SI units).\n"
    atomic_write_text(path, text + yaml.safe_dump(doc, sort_keys=False, width=120))


def _model(path: Path, where: str, entry: object, i_max: float) -> BoucWenCurrentModel:
    if not isinstance(entry, dict):
        raise PlantSampleError(f"{path}: {where} is not a mapping of coefficient: value")
    missing = [k for k in COEFFICIENTS if k not in entry]
    extra = [str(k) for k in entry if k not in COEFFICIENTS]
    if missing:
        raise PlantSampleError(f"{path}: {where}: missing coefficient {missing[0]} ({COEFFICIENT_DOCS[missing[0]][0]})")
    if extra:
        raise PlantSampleError(f"{path}: {where}: extra coefficient {extra[0]} (a BoucWenIsolator sample has exactly "
                               f"{', '.join(COEFFICIENTS)})")
    values = {}
    for k in COEFFICIENTS:
        v = entry[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise PlantSampleError(f"{path}: {where}: coefficient {k} = {v!r} is not a finite number "
                                   f"({COEFFICIENT_DOCS[k][0]})")
        values[k] = float(v)
    model = BoucWenCurrentModel(**values)
    try:
        device_problem(model, i_max, beyond_range="extrapolate")
    except ParameterError as exc:
        raise PlantSampleError(f"{path}: {where}: coefficient {exc.parameter}: {exc}") from None
    return model


def load_plant_samples(path: str | os.PathLike, i_max: float = 3.0) -> tuple[BoucWenCurrentModel,
                                                                             list[BoucWenCurrentModel]]:
    """(nominal, samples) of a file written by :func:`write_plant_samples`; PlantSampleError if unusable."""
    path = Path(path)
    try:  # a device, FIFO or folder is refused before it is read: /dev/zero would never end
        if not stat.S_ISREG(path.stat().st_mode):
            raise PlantSampleError(f"{path}: not a regular file (a plant-sample file is YAML)")
    except OSError as exc:
        raise PlantSampleError(f"{path}: cannot read a plant-sample file ({exc.strerror or exc})") from None
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise PlantSampleError(f"{path}: cannot read a plant-sample file ({exc})") from None
    if not isinstance(doc, dict) or doc.get("kind") != KIND:
        raise PlantSampleError(f"{path}: not a plant-sample file (kind: {KIND} missing)")
    samples = doc.get("samples")
    if not isinstance(samples, list) or not samples:
        raise PlantSampleError(f"{path}: 'samples' must be a non-empty list")
    nominal = _model(path, "nominal", doc.get("nominal"), i_max)
    return nominal, [_model(path, f"sample {k + 1}", s, i_max) for k, s in enumerate(samples)]


def statistics(names: Sequence[str], rows: np.ndarray) -> dict:
    """Mean, standard deviation, correlation and principal axes of sampled coefficients (paper units).

    A coefficient that does not vary over the samples (one on its bound in every refit) is listed under
    ``fixed`` and left out of the correlation and the principal axes (the eigen-decomposition of the
    correlation matrix of the others: axes of the standardised coefficients, largest variance first).
    """
    rows = np.asarray(rows, dtype=float)
    std = rows.std(axis=0, ddof=1)
    scale = np.maximum(np.abs(rows.mean(axis=0)), 1e-300)
    varying = std > 1e-3 * scale  # below: a coefficient held by its bound (beta_1 = 1e-4/mm)
    free = [n for n, ok in zip(names, varying, strict=True) if ok]
    corr = np.corrcoef(rows[:, varying], rowvar=False)
    values, vectors = np.linalg.eigh(corr)
    order = np.argsort(values)[::-1]
    rnd = lambda a: np.round(np.asarray(a, dtype=float), 6).tolist()  # noqa: E731
    return {
        "units": "paper (mm-based: k, c per mm; beta, gamma per mm; alpha N; n 1)",
        "names": list(names),
        "mean": rnd(rows.mean(axis=0)),
        "std": rnd(std),
        "covariance": np.cov(rows, rowvar=False).tolist(),
        "fixed": [n for n, ok in zip(names, varying, strict=True) if not ok],
        "correlation": {"names": list(free), "matrix": rnd(corr)},
        "principal_axes": {"names": list(free), "eigenvalues": rnd(values[order]),
                           "vectors_columns": rnd(vectors[:, order])},
    }
