"""The plant's own uncertainty in a controller benchmark: sampled plants as robustness variants, and what they give.

A study's ``robustness.plant_samples`` (robustness_config) becomes ``set`` variants, one per drawn plant, each
setting the isolator unit's coefficients (SI, the FMU's names) from a plant-sample file's covariance
(:mod:`components.identification.plant_sampling`). They run like any variant. Afterwards:

* ``plant_design.csv``: per sampled variant its design (lhs or sobol), its coordinates on the principal axes and
  the coefficients it set;
* ``plant_uncertainty.csv``: per strategy and criterion (J1-J9 over the benchmark baseline on the nominal plant,
  as criteria.csv) the nominal value and the median, 5 % and 95 % quantiles and count of valid runs over the
  Latin-hypercube plants, per record (a run that failed or is numerically invalid is left out and not counted);
* ``sobol.csv``: per strategy, record, criterion (J3, J5) and axis, the first-order and total Sobol indices with
  their 95 % confidence half-widths (SALib), computed only when every run of the Saltelli design is valid.
"""

from __future__ import annotations

import csv
import functools
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from components.identification.plant_samples import PlantSampleError, load_plant_samples
from components.identification.plant_sampling import (
    COEFFICIENTS,
    PlantDistribution,
    distribution,
    lhs_normal,
    sobol_design,
    sobol_indices,
)
from components.physics.bouc_wen_core import BoucWenCurrentModel, device_problem
from components.physics.mre_isolator_core import ParameterError
from mre_common.atomic_files import atomic_write_text
from orchestration.case_study.benchmark_criteria import CRITERIA, j6_reference, normalised
from orchestration.case_study.case_rendering import Block, fmt
from orchestration.case_study.robustness_config import PlantSamplingSpec, VariantSpec
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.yaml_source import dotted

KEY = ("robustness", "plant_samples")
SOBOL_CRITERIA = ("J3", "J5")
SPREAD_CRITERIA = CRITERIA


Drawn = tuple[PlantDistribution, list[tuple[str, str, np.ndarray, np.ndarray]], list[tuple[str, str]]]


@functools.lru_cache(maxsize=8)
def _drawn(path: str, mtime_ns: int, spec_json: str) -> Drawn:
    """(distribution, [(variant, design, xi, coefficients)], [(variant, why it is no device)]) of a plant-sample
    file and a spec, computed once per file version and spec (every run's plan asks for them)."""
    spec = PlantSamplingSpec.model_validate_json(spec_json)
    nominal, samples = load_plant_samples(path)
    dist = distribution(nominal, samples)
    if spec.sobol and spec.axes > len(dist.variances):
        raise ValueError(f"axes = {spec.axes}: the file's samples vary along {len(dist.variances)} principal axes")
    lhs_names, sobol_names = spec.names()
    drawn: list[tuple[str, str, np.ndarray, np.ndarray]] = []
    if spec.lhs:
        xi = lhs_normal(spec.lhs, len(dist.variances), spec.seed)
        drawn += [(n, "lhs", x, c) for n, x, c in zip(lhs_names, xi, dist.coefficients(xi), strict=True)]
    if spec.sobol:
        xi = sobol_design(spec.sobol, spec.axes, spec.seed)
        drawn += [(n, "sobol", x, c) for n, x, c in zip(sobol_names, xi, dist.coefficients(xi), strict=True)]
    no_device = []
    for name, _, _, c in drawn:
        try:
            device_problem(BoucWenCurrentModel(**dict(zip(COEFFICIENTS, c, strict=True))), beyond_range="stop")
        except ParameterError as exc:
            no_device.append((name, str(exc)))
    return dist, drawn, no_device


def _problem(study: Any, message: str, *key: Any) -> Problem:
    path = (*KEY, *key)
    for k in range(len(path), -1, -1):
        hit = study.lines.get(path[:k])
        if hit is not None:
            return Problem(f"robustness.plant_samples: {message}", dotted(path), hit[0], hit[1])
    return Problem(f"robustness.plant_samples: {message}", dotted(path), str(study.path))


def samples_path(study: Any) -> Path:
    """The plant-sample file, absolute (relative to the file that wrote the key)."""
    spec = study.spec.robustness.plant_samples
    p = Path(spec.file)
    return p if p.is_absolute() else (study.base_dir(*KEY, "file") / p).resolve()


def drawn(study: Any) -> tuple[PlantDistribution, list[tuple[str, str, np.ndarray, np.ndarray]]]:
    """The study's sampled plants; ScenarioError naming the key and line if the file or a plant is unusable."""
    spec = study.spec.robustness.plant_samples
    path = samples_path(study)
    if spec.sobol:
        try:
            import SALib  # noqa: F401
        except ImportError:
            raise ScenarioError([_problem(study, "sobol needs SALib (pip install -e \".[uncertainty]\")",
                                          "sobol")]) from None
    try:
        dist, plants, no_device = _drawn(str(path), path.stat().st_mtime_ns, spec.model_dump_json())
    except OSError as exc:
        raise ScenarioError([_problem(study, f"cannot read {path} ({exc.strerror or exc})", "file")]) from None
    except (PlantSampleError, ValueError) as exc:
        raise ScenarioError([_problem(study, str(exc), "axes" if str(exc).startswith("axes") else "file")]) from None
    if no_device:
        raise ScenarioError([_problem(study, f"plant {name} is no device ({why}); another seed draws other plants",
                                      "seed") for name, why in no_device])
    return dist, plants


def sampled_variants(study: Any) -> dict[str, VariantSpec]:
    """The sampled plants as ``set`` variants of the unit (empty without ``plant_samples``)."""
    rob = study.spec.robustness
    if rob is None or rob.plant_samples is None:
        return {}
    drawn(study)  # the checks, each time (cached draw)
    path = samples_path(study)
    return dict(_variants(str(path), path.stat().st_mtime_ns, rob.plant_samples.model_dump_json()))


@functools.lru_cache(maxsize=8)
def _variants(path: str, mtime_ns: int, spec_json: str) -> tuple[tuple[str, VariantSpec], ...]:
    unit = PlantSamplingSpec.model_validate_json(spec_json).unit
    _, plants, _ = _drawn(path, mtime_ns, spec_json)
    return tuple((name, VariantSpec(label=f"{design} plant {name.partition('-')[2].lstrip('0')}",
                                    set={f"{unit}.{n}": float(v) for n, v in zip(COEFFICIENTS, c, strict=True)}))
                 for name, design, _, c in plants)


# -- after the runs ---------------------------------------------------------------------------------------------
def _csv(header: list[str], rows: list[list[Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def design_csv(dist: PlantDistribution, plants: list[tuple[str, str, np.ndarray, np.ndarray]]) -> str:
    """plant_design.csv: variant, design, xi_1 ... xi_n (0 beyond the design's axes), the coefficients [SI]."""
    n = len(dist.variances)
    rows = [[name, design, *[repr(float(v)) for v in np.pad(x, (0, n - len(x)))], *[repr(float(v)) for v in c]]
            for name, design, x, c in plants]
    return _csv(["variant", "design", *[f"xi_{k + 1}" for k in range(n)], *COEFFICIENTS], rows)


def write_design(folder: Path, study: Any) -> None:
    """plant_design.csv and plant_design.json (the file, the spec, the axes' variances) before the runs: what the
    report reads back, so that ``--report`` needs neither the study file nor the plant-sample file."""
    spec = study.spec.robustness.plant_samples
    dist, plants = drawn(study)
    atomic_write_text(folder / "plant_design.csv", design_csv(dist, plants))
    atomic_write_text(folder / "plant_design.json", json.dumps({
        "file": str(samples_path(study)), "bootstrap_samples": dist.n_samples, "spec": spec.model_dump(),
        "free": dist.free_names, "variances": dist.variances.tolist(),
        "lhs": [n for n, d, _, _ in plants if d == "lhs"], "sobol": [n for n, d, _, _ in plants if d == "sobol"],
    }, indent=1) + "\n")


def _values(vraw: dict[tuple[str, str, str], dict[str, float] | None], strategy: str, record: str,
            names: list[str], j: str, base: dict[str, float], j6_reference: dict[str, float],
            invalid: set[tuple[str, str, str]]) -> np.ndarray:
    """J of the strategy's runs on the named variants, normalised as criteria.csv (over the nominal plant's
    baseline, J6 over the nominal J6 reference), NaN where a run failed or is numerically invalid."""
    out = []
    for v in names:
        raw = vraw.get((record, strategy, v))
        bad = raw is None or (record, strategy, v) in invalid
        out.append(math.nan if bad else normalised(raw, base, j6_reference)[j])
    return np.array(out, dtype=float)


def _order_rows(vraw: dict[tuple[str, str, str], Any], strategies: list[str], record: str, names: list[str],
                base: dict[str, float], ref: dict[str, float], invalid: set[tuple[str, str, str]]) -> list[list[str]]:
    """The same plants under two strategies: on how many the first is lower, and the range of J_A / J_B."""
    rows = []
    for k, a in enumerate(strategies):
        for b in strategies[k + 1:]:
            for j in ("J3", "J4", "J5"):
                ya, yb = (_values(vraw, x, record, names, j, base, ref, invalid) for x in (a, b))
                both = np.isfinite(ya) & np.isfinite(yb)
                if both.any():
                    q = ya[both] / yb[both]
                    rows.append([a, b, record, j, f"{int(np.sum(q < 1))} of {int(both.sum())}",
                                 f"{float(q.min()):.4f} to {float(q.max()):.4f}"])
    return rows


def uncertainty_blocks(folder: Path, study: Any, vraw: dict[tuple[str, str, str], Any],
                       raw: dict[tuple[str, str], dict[str, float]], baseline: str) -> list[Block]:
    """Write plant_uncertainty.csv and sobol.csv from the runs; the report's section on the plant's uncertainty.

    ``study``: the study record (strategies, records); ``vraw``: raw criteria per (record, strategy, variant),
    None for a failed run; ``raw``: the nominal runs'. The design is the one plant_design.json recorded."""
    design = json.loads((folder / "plant_design.json").read_text(encoding="utf-8"))
    spec = PlantSamplingSpec.model_validate(design["spec"])
    variances = np.asarray(design["variances"], dtype=float)
    lhs, sob = list(design["lhs"]), list(design["sobol"])

    def explained(k: int) -> float:
        return float(variances[:k].sum() / variances.sum())

    # a run that ended but whose energy books do not close is not counted (its validity, read by variant_raw)
    invalid = {(e.record, e.strategy, e.variant) for e in study.variant_runs if e.valid is False}
    spread_rows, sobol_rows = [], []
    table, order = [], []
    sampled = [s for s in study.strategies if any(k[1] == s for k in vraw)]  # the strategies run on the plants
    for r in study.records:
        base, ref = raw.get((r, baseline), {}), raw.get((r, j6_reference(study.config)), {})
        order += _order_rows(vraw, sampled, r, lhs, base, ref, invalid)
        for s in sampled:
            nominal = normalised(raw.get((r, s), {}), base, ref)
            for j in SPREAD_CRITERIA:
                nom = nominal[j]
                y = _values(vraw, s, r, lhs, j, base, ref, invalid) if lhs else np.array([])
                ok = y[np.isfinite(y)]
                q = np.quantile(ok, [0.05, 0.5, 0.95]) if len(ok) else [math.nan] * 3
                spread_rows.append([s, r, j, repr(nom), repr(float(q[1])), repr(float(q[0])), repr(float(q[2])),
                                    len(ok), len(y)])
                if j in ("J3", "J4", "J5") and lhs:
                    table.append([s, r, j, fmt(nom), f"{fmt(float(q[1]))} [{fmt(float(q[0]))}, {fmt(float(q[2]))}]",
                                  f"{len(ok)}/{len(y)}"])
            if not sob:
                continue
            k_axes = spec.axes
            for j in SOBOL_CRITERIA:
                y = _values(vraw, s, r, sob, j, base, ref, invalid)
                if not np.all(np.isfinite(y)):
                    bad = int(np.sum(~np.isfinite(y)))
                    sobol_rows.append([s, r, j, "", "", "", "", "", "",
                                       f"not computed: {bad} of {len(y)} runs failed or invalid"])
                    continue
                ind = sobol_indices(y, k_axes, spec.seed)
                for a in range(k_axes):
                    sobol_rows.append([s, r, j, a + 1, repr(explained(a + 1) - explained(a)),
                                       *[repr(float(ind[key][a])) for key in ("S1", "S1_conf", "ST", "ST_conf")], ""])
    atomic_write_text(folder / "plant_uncertainty.csv", _csv(
        ["strategy", "record", "criterion", "nominal", "median", "q05", "q95", "valid", "runs"], spread_rows))
    blocks = [Block("h", "The plant's own uncertainty (sampled isolators)"),
              Block("p", f"{len(lhs)} Latin-hypercube and {len(sob)} Saltelli-design plants drawn from the "
                         f"covariance of {design['bootstrap_samples']} bootstrap refits ({Path(spec.file).name}), "
                         f"centred on the nominal fit, seed {spec.seed} (plant_design.csv). Criteria over {baseline} "
                         "on the nominal plant, as criteria.csv (plant_uncertainty.csv has J1-J9).")]
    if table:
        blocks += [Block("h", "Spread over the Latin-hypercube plants", level=3),
                   Block("table", header=["strategy", "record", "criterion", "nominal plant",
                                          "median [5 %, 95 %]", "valid runs"], rows=table)]
    if order:
        blocks += [Block("h", "Order on the same plants", level=3),
                   Block("p", "Each pair of strategies on each Latin-hypercube plant: on how many plants the first has "
                              "the lower criterion, and the range of the ratio J_A / J_B over the plants (the spread "
                              "of one criterion alone mixes in what the plant does to every strategy alike)."),
                   Block("table", header=["A", "B", "record", "criterion", "J_A < J_B on", "J_A / J_B"],
                         rows=order)]
    if sob:
        atomic_write_text(folder / "sobol.csv", _csv(
            ["strategy", "record", "criterion", "axis", "axis_variance_share", "S1", "S1_conf", "ST", "ST_conf",
             "note"], sobol_rows))
        body = [[row[0], row[1], row[2], str(row[3]), fmt(float(row[4])),
                 f"{fmt(float(row[5]))} ± {fmt(float(row[6]))}", f"{fmt(float(row[7]))} ± {fmt(float(row[8]))}"]
                if row[3] != "" else [row[0], row[1], row[2], "–", "–", row[9], "–"] for row in sobol_rows]
        k_axes = spec.axes
        blocks += [Block("h", "Sobol indices on the principal axes", level=3),
                   Block("p", f"SALib's Saltelli design, N = {spec.sobol}, on the first {k_axes} principal axes "
                              f"({100 * explained(k_axes):.0f} % of the standardised variance; the others held at 0); "
                              "± the 95 % confidence half-width."),
                   Block("table", header=["strategy", "record", "criterion", "axis", "axis variance share",
                                          "S1", "ST"], rows=body)]
    return blocks
