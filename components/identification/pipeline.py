"""The identification run: data -> per-condition identification -> generalized model -> outputs."""

from __future__ import annotations

import json
import os
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from components.bouc_wen_core import SYNTHETIC_DEFAULT
from components.identification import report
from components.identification.bouc_wen_joint import JointFit, fit_bouc_wen_joint
from components.identification.config import IdentificationConfig
from components.identification.ffoa import FFOASettings
from components.identification.generalized import (
    GeneralizationError,
    GeneralizedFit,
    fit_generalized,
    generalized_rms,
    physical_problems,
    write_parameter_file,
)
from components.identification.identifiers import (
    Acceptance,
    IdentResult,
    identify_bouc_wen_ffoa,
    identify_hyperbolic_ffoa,
    identify_structured,
)
from components.identification.models import FitData, fit_data
from components.identification.paper_tables import TEST_MATRIX, Condition
from components.identification.testdata import (
    SYNTHETIC_NOTE,
    NoiseModel,
    ShakeRecord,
    TestDataError,
    generate_synthetic,
    read_folder,
    write_csv,
)
from components.mre_isolator_core import TABLE2_PAPER_UNITS


@dataclass
class RunResult:
    """Everything a run produced (also written to the output folder)."""

    data: dict[Condition, FitData]
    results: dict[str, dict[Condition, IdentResult]]
    generalized: dict[str, GeneralizedFit] = field(default_factory=dict)
    generalization_errors: dict[str, str] = field(default_factory=dict)
    synthetic: bool = False
    joint: JointFit | None = None
    generalized_rms: dict[str, dict[Condition, float]] = field(default_factory=dict)

    @property
    def not_converged(self) -> list[IdentResult]:
        return [r for per in self.results.values() for r in per.values() if not r.converged]


def load_records(cfg: IdentificationConfig, base: Path) -> list[ShakeRecord]:
    """The test records the configuration names (synthetic or a folder of CSVs)."""
    d = cfg["data"]
    if d["source"] == "folder":
        folder = Path(d["folder"])
        if not folder.is_absolute():
            folder = base / folder
        if not folder.is_dir():
            raise TestDataError(f"{folder}: data.folder is not a folder")
        records = read_folder(folder)
        if cfg.conditions is not None:
            records = [r for r in records if r.condition in cfg.conditions]
            if not records:
                raise TestDataError(f"{folder}: no file matches data.conditions")
        return records
    s = d["synthetic"]
    conditions = cfg.conditions or TEST_MATRIX
    return generate_synthetic(
        s["seed"],
        NoiseModel(**s["noise"]),
        conditions=conditions,
        repeats=s["repeats"],
        model=s["model"],
        fs_hz=s["sampling_hz"],
        cycles=s["cycles"],
        F0_n=s["F0_n"],
        include_velocity=s["include_velocity"],
        bouc_wen=SYNTHETIC_DEFAULT,
    )


def group(records: list[ShakeRecord], first_cycle: int, cycles: int) -> dict[Condition, FitData]:
    """Fit data per condition (repeats of a condition are fitted together)."""
    by: dict[Condition, list[ShakeRecord]] = {}
    for r in records:
        by.setdefault(r.condition, []).append(r)
    return {c: fit_data(by[c], first_cycle, cycles) for c in sorted(by)}


def identify_all(
    data: dict[Condition, FitData],
    cfg: IdentificationConfig,
    progress: bool = True,
    on_result: Callable[[IdentResult], None] | None = None,
) -> dict[str, dict[Condition, IdentResult]]:
    """Run every configured identifier on every condition (progress bar over conditions).

    FFOA runs are seeded per (ffoa.seed, condition index, identifier), so each is
    reproducible on its own.
    """
    f = cfg["ffoa"]
    settings = FFOASettings(n_pop=f["n_pop"], n_iter=f["n_iter"], step=f["step"])
    acc = Acceptance(**cfg["acceptance"])
    st = cfg["structured"]
    results: dict[str, dict[Condition, IdentResult]] = {name: {} for name in cfg["identifiers"]}
    bar = tqdm(list(data.items()), desc="conditions", unit="cond", disable=not progress)
    for k, (cond, d) in enumerate(bar):
        bar.set_postfix_str(f"{cond[0]:g} Hz {cond[1]:g} mm {cond[2]:g} A")
        for j, name in enumerate(cfg["identifiers"]):
            rng = np.random.default_rng([f["seed"], k, j])
            if name == "hyperbolic-ffoa":
                res = identify_hyperbolic_ffoa(d, rng, settings, acc)
            elif name == "bouc_wen-ffoa":
                res = identify_bouc_wen_ffoa(d, rng, settings, acc)
            else:
                res = identify_structured(
                    d, acc, beta_bounds=(st["beta_min"], st["beta_max"]), n_grid=st["n_grid"]
                )
            results[name][cond] = res
            if on_result:
                on_result(res)
    return results


def generalize(results: dict[str, dict[Condition, IdentResult]]):
    """Eq. (13)-(16) from the converged identifications of each identifier."""
    fits, errors = {}, {}
    for name, per in results.items():
        model = name.split("-")[0]
        rows = [(c[2], r.params) for c, r in per.items() if r.converged]
        try:
            fits[name] = fit_generalized(rows, model)
        except GeneralizationError as exc:
            errors[name] = str(exc)
    return fits, errors


def prepare_output(out: Path, overwrite: bool) -> Path:
    """A fresh staging folder next to ``out``; refuses an existing ``out`` unless overwrite."""
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out}: output folder exists; choose another with --out or pass --overwrite")
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = out.parent / f".{out.name}.partial-{os.getpid()}"
    if stage.exists():
        shutil.rmtree(stage)
    stage.mkdir()
    return stage


def commit_output(stage: Path, out: Path) -> None:
    """Move the finished staging folder into place (replacing ``out`` only if it was allowed)."""
    if out.exists():
        shutil.rmtree(out)
    os.replace(stage, out)


def run(
    cfg: IdentificationConfig,
    out: Path,
    overwrite: bool = False,
    progress: bool = True,
    base: Path | None = None,
) -> RunResult:
    """Full run; writes every output into ``out`` (see docs/identification.md)."""
    base = base or (cfg.path.parent if cfg.path else Path.cwd())
    records = load_records(cfg, base)
    data = group(records, cfg["fit"]["first_cycle"], cfg["fit"]["cycles"])
    synthetic = all(r.synthetic for r in records)
    stage = prepare_output(out, overwrite)
    try:
        if synthetic and cfg["data"]["synthetic"]["write_csv"]:
            (stage / "data").mkdir()
            for r in records:
                f, a, i = r.condition
                write_csv(r, stage / "data" / f"synthetic_f{f:g}Hz_A{a:g}mm_I{i:g}A_r{r.repeat}.csv")
        results = identify_all(data, cfg, progress)
        fits, errors = generalize(results)
        run_result = RunResult(data, results, fits, errors, synthetic)
        joint_cfg = cfg["bouc_wen_joint"]
        if joint_cfg["enabled"] and "bouc_wen-ffoa" in fits:
            start = fits["bouc_wen-ffoa"]
            if progress:
                print("joint least-squares fit of the current-dependent Bouc-Wen model ...", file=sys.stderr)
            joint = fit_bouc_wen_joint(data, start.coefficients, joint_cfg["max_nfev"])
            run_result.joint = joint
            if joint.success:
                fits["bouc_wen-joint"] = GeneralizedFit(
                    "bouc_wen", start.means, start.counts, joint.coefficients
                )
            else:
                errors["bouc_wen-joint"] = f"least squares did not converge: {joint.message}"
        run_result.generalized_rms["paper Table 2"] = generalized_rms("hyperbolic", TABLE2_PAPER_UNITS, data)
        for name, fit in fits.items():
            run_result.generalized_rms[name] = generalized_rms(fit.model, fit.coefficients, data)
        note = SYNTHETIC_NOTE if synthetic else "identified from measured data"
        i_max = max(c[2] for c in data)
        for name, fit in list(fits.items()):
            problems = physical_problems(fit, i_max)
            if problems:
                errors[name] = "parameter file not written, not physical: " + "; ".join(problems)
                continue
            write_parameter_file(
                stage / f"generalized_{name}.yaml", fit, f"{note}; identifier {name}", synthetic
            )
        report.write_tables(stage, run_result, cfg)
        (stage / "config_used.json").write_text(json.dumps(cfg.raw, indent=2))
        if cfg["figures"]:
            from components.identification import figures

            figures.write_all(stage / "figures", run_result, cfg)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    commit_output(stage, out)
    return run_result
