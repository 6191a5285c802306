"""The identification run: data -> per-condition identification -> generalized model -> outputs."""

from __future__ import annotations

import copy
import json
import os
import shutil
import sys
import tempfile
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from components.identification import bouc_wen_native
from components.identification.bouc_wen_joint import fit_bouc_wen_joint
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
from components.identification.joint_fits import FORMS, bootstrap, fit_joint
from components.identification.model_selection import Candidate, evaluate
from components.identification.models import FitData, fit_data
from components.identification.paper_tables import TEST_MATRIX, Condition
from components.identification.plant_samples import statistics as plant_statistics
from components.identification.plant_samples import write_plant_samples
from components.identification.testdata import (
    SYNTHETIC_NOTE,
    NoiseModel,
    ShakeRecord,
    TestDataError,
    generate_synthetic,
    read_folder,
    write_csv,
)
from components.physics.bouc_wen_core import SYNTHETIC_DEFAULT, BoucWenCurrentModel
from components.physics.mre_isolator_core import TABLE2_PAPER_UNITS
from mre_common.atomic_files import current_umask
from mre_common.folder_claim import claim_folder
from orchestration.identification import ident_report
from orchestration.identification.ident_config import IdentificationConfig
from orchestration.identification.ident_result import RunResult
from orchestration.master.figure_files import PNG_ONLY, FigureFiles


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


MapFunction = Callable[[Callable[[Any], Any], Sequence[Any]], Iterable[Any]]
"""Like the builtin ``map``: apply a module-level function to every item (possibly in other
processes) and give the results in the order of the items."""

# Rough CPU cost of one FFOA fly evaluation [s] (paper fit window, 5 repeats; Bouc-Wen with the
# compiled kernel, or on the numpy path): enough to tell whether spreading the conditions over
# processes is worth it. The structured identifier takes
# milliseconds per condition.
FLY_EVALUATION_S = {"hyperbolic-ffoa": 1.7e-6, "bouc_wen-ffoa": 1.8e-5, "bouc_wen-ffoa/numpy": 3e-4}
PARALLEL_MIN_S = 30.0
"""By default identify_all uses its map function only for FFOA work estimated above this
[s]: starting the studies' engine (a local Dask cluster of two workers) costs seconds of CPU
and of wall time, more than it saves on the default run's FFOA, which one process finishes
sooner than two workers."""


def estimated_ffoa_seconds(conditions: int, identifiers: Sequence[str], n_pop: int, n_iter: int) -> float:
    """Rough CPU seconds of the FFOA identifications of a run (:data:`FLY_EVALUATION_S`)."""
    numpy_path = bouc_wen_native.backend() == "numpy"
    per_fly = sum(FLY_EVALUATION_S.get(f"{name}/numpy" if numpy_path and name == "bouc_wen-ffoa" else name, 0.0)
                  for name in identifiers)
    return conditions * n_pop * (n_iter + 1) * per_fly


@dataclass(frozen=True)
class ConditionTask:
    """Everything needed to identify one condition with every configured identifier (picklable)."""

    index: int
    data: FitData
    identifiers: tuple[str, ...]
    ffoa: FFOASettings
    ffoa_seed: int
    acceptance: Acceptance
    structured: dict[str, Any]


def identify_condition(task: ConditionTask) -> list[IdentResult]:
    """Every identifier of ``task`` on its condition, in the order of ``task.identifiers``.

    FFOA runs are seeded per (ffoa.seed, condition index, identifier index), so the result
    does not depend on which process runs the task, nor on the other tasks.
    """
    results = []
    for j, name in enumerate(task.identifiers):
        rng = np.random.default_rng([task.ffoa_seed, task.index, j])
        if name == "hyperbolic-ffoa":
            results.append(identify_hyperbolic_ffoa(task.data, rng, task.ffoa, task.acceptance))
        elif name == "bouc_wen-ffoa":
            results.append(identify_bouc_wen_ffoa(task.data, rng, task.ffoa, task.acceptance))
        else:
            results.append(identify_structured(task.data, task.acceptance, **task.structured))
    return results


def identify_all(
    data: dict[Condition, FitData],
    cfg: IdentificationConfig,
    progress: bool = True,
    on_result: Callable[[IdentResult], None] | None = None,
    map_fn: MapFunction | None = None,
    min_parallel_s: float = PARALLEL_MIN_S,
) -> dict[str, dict[Condition, IdentResult]]:
    """Run every configured identifier on every condition (progress bar over conditions).

    Conditions are independent tasks (:func:`identify_condition`) handed to ``map_fn``
    (default: the builtin ``map``, in this process); pass a parallel map to spread them
    over processes. It is used only if the FFOA work is estimated above ``min_parallel_s``
    seconds (:func:`estimated_ffoa_seconds`; 0 = always). The results do not depend on the map.
    """
    f = cfg["ffoa"]
    st = cfg["structured"]
    names = tuple(cfg["identifiers"])
    if "bouc_wen-ffoa" in names and bouc_wen_native.kernel() is None:  # compiled once, before the workers
        print(f"note: no compiled Bouc-Wen kernel, Bouc-Wen FFOA takes minutes instead of seconds "
              f"({bouc_wen_native.unavailable_reason()})", file=sys.stderr)
    tasks = [
        ConditionTask(
            k, d, names, FFOASettings(n_pop=f["n_pop"], n_iter=f["n_iter"], step=f["step"]), f["seed"],
            Acceptance(**cfg["acceptance"]),
            {"beta_bounds": (st["beta_min"], st["beta_max"]), "n_grid": st["n_grid"]},
        )
        for k, d in enumerate(data.values())
    ]
    if estimated_ffoa_seconds(len(tasks), names, f["n_pop"], f["n_iter"]) < min_parallel_s:
        map_fn = None
    results: dict[str, dict[Condition, IdentResult]] = {name: {} for name in names}
    bar = tqdm(total=len(tasks), desc="conditions", unit="cond", disable=not progress)
    try:
        for task, per in zip(tasks, (map_fn or map)(identify_condition, tasks), strict=True):
            cond = task.data.condition
            bar.set_postfix_str(f"{cond[0]:g} Hz {cond[1]:g} mm {cond[2]:g} A")
            bar.update(1)
            for name, res in zip(names, per, strict=True):
                results[name][cond] = res
                if on_result:
                    on_result(res)
    finally:
        bar.close()
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


def synthetic_data(cfg: IdentificationConfig, base: Path, seed: int) -> dict[Condition, FitData]:
    """The configuration's data set with another noise seed (synthetic), or the data themselves (measured)."""
    raw = copy.deepcopy(cfg.raw)
    if raw["data"]["source"] == "synthetic":
        raw["data"]["synthetic"]["seed"] = int(seed)
    other = IdentificationConfig(raw, cfg.path)
    return group(load_records(other, base), cfg["fit"]["first_cycle"], cfg["fit"]["cycles"])


def select_models(rr: RunResult, cfg: IdentificationConfig, synthetic: bool, base: Path, stage: Path,
                  progress: bool) -> None:
    """Joint fits of the forms of :mod:`joint_fits`, the model-selection table and the plant samples.

    Candidates: the paper's Table 2, the joint hyperbolic fit of Eq. (13)-(17), the joint Bouc-Wen fit
    (``bouc_wen-joint``, when it ran) and the Bouc-Wen form quadratic in the current. The hyperbolic joint fit
    becomes ``generalized_hyperbolic-joint.yaml``; the quadratic form has no FMU and stays a table row.
    """
    sel = cfg["model_selection"]
    if not sel["enabled"]:
        return
    data = rr.data
    if progress:
        print("joint least-squares fits of the current-dependent forms, model selection ...", file=sys.stderr)
    candidates = [Candidate("paper Table 2", "hyperbolic", dict(TABLE2_PAPER_UNITS), fitted=False)]
    try:
        hyp = fit_joint("hyperbolic", data, TABLE2_PAPER_UNITS, sel["max_nfev"])
    except ValueError as exc:
        rr.generalization_errors["hyperbolic-joint"] = str(exc)
    else:
        candidates.append(Candidate("hyperbolic-joint", "hyperbolic", hyp.coefficients))
        if hyp.success:
            rr.generalized["hyperbolic-joint"] = GeneralizedFit("hyperbolic", {}, {}, hyp.coefficients)
        else:
            rr.generalization_errors["hyperbolic-joint"] = f"least squares did not converge: {hyp.message}"
    joint = rr.generalized.get("bouc_wen-joint")
    if joint is not None:
        start = dict(joint.coefficients)
        candidates.append(Candidate("bouc_wen-joint", "bouc_wen", start))
        quad_start = {**start, **{f"{p}_2": 0.0 for p in FORMS["bouc_wen-quadratic"].current_params}}
        try:
            quad = fit_joint("bouc_wen-quadratic", data, quad_start, sel["max_nfev"])
        except ValueError as exc:
            rr.generalization_errors["bouc_wen-quadratic"] = str(exc)
        else:
            candidates.append(Candidate("bouc_wen-quadratic", "bouc_wen-quadratic", quad.coefficients))
            rr.generalization_errors["bouc_wen-quadratic"] = ("no parameter file: no FMU runs the quadratic "
                                                              "current rule (model-selection table only)")
    if synthetic:
        rr.selection = [evaluate(c, data) for c in candidates]
    unc = cfg["plant_uncertainty"]
    if joint is None or not unc["enabled"]:
        return
    if progress:
        print(f"bootstrap of the Bouc-Wen joint fit ({unc['samples']} refits) ...", file=sys.stderr)
    boot = bootstrap("bouc_wen", lambda seed: synthetic_data(cfg, base, seed), joint.coefficients,
                     unc["samples"], unc["seed"], sel["max_nfev"])
    rr.bootstrap = boot
    to_si = [BoucWenCurrentModel.from_paper_units(**dict(zip(boot.names, row, strict=True)), delta=1.0)
             for row in boot.samples]
    note = (f"{SYNTHETIC_NOTE if synthetic else 'identified from measured data'}; bootstrap of the Bouc-Wen "
            f"joint fit: {unc['samples']} refits, each on a new noise realisation with the conditions drawn with "
            f"replacement (seed {unc['seed']})")
    write_plant_samples(stage / "plant_samples_bouc_wen-joint.yaml",
                        BoucWenCurrentModel.from_paper_units(**joint.coefficients), to_si,
                        plant_statistics(boot.names, boot.samples), note, synthetic)


MARKER = ".mre-cosim-identification"
"""Written into every output folder this tool creates; --overwrite replaces only folders that hold it."""


class OutputFolderError(FileExistsError):
    """The output folder cannot be used (exists, not ours to replace, or not writable); nothing was deleted."""


def _protected(out: Path) -> str | None:
    """Why ``out`` (resolved) may never be replaced, or None."""
    cwd = Path.cwd().resolve()
    if out == Path(out.anchor):
        return "it is the filesystem root"
    if out == cwd:
        return "it is the current working directory"
    if out in cwd.parents:
        return "it contains the current working directory"
    try:
        if out == Path.home().resolve():
            return "it is the home folder"
    except RuntimeError:  # no home folder known
        pass
    return None


def _check_replaceable(out: Path, shown: Path) -> None:
    """Refuse to replace ``out`` unless this tool made it (marker) or it is an empty folder."""
    why = _protected(out)
    if why is None and not out.is_dir():
        why = "it is not a folder"
    if why is None and not (out / MARKER).is_file() and any(out.iterdir()):
        why = f"it was not written by this tool (no {MARKER} marker)"
    if why:
        raise OutputFolderError(f"{shown}: refusing to overwrite, {why}; choose another --out (nothing was deleted)")


def prepare_output(out: Path, overwrite: bool) -> Path:
    """A fresh, marked staging folder next to ``out``.

    Refuses an existing ``out`` unless ``overwrite``; even then only a folder this tool
    wrote (it holds :data:`MARKER`) or an empty one is replaced, never the working
    directory, one of its ancestors, the root or the home folder. All checks happen here,
    before anything is identified.
    """
    target = out.resolve()
    if out.exists() or out.is_symlink():
        if not overwrite:
            raise OutputFolderError(f"{out}: output folder exists; choose another with --out or pass --overwrite")
        _check_replaceable(target, out)
    elif _protected(target):
        raise OutputFolderError(f"{out}: refusing to write there, {_protected(target)}")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
    except OSError as exc:
        raise OutputFolderError(f"{out}: cannot create the output folder ({exc.strerror or exc}); "
                                "choose another --out") from None
    try:
        stage.chmod(0o777 & ~current_umask())  # mkdtemp makes it private; the output gets the usual permissions
        claim_folder(stage, MARKER, {"tool": "mre-cosim identify", "pid": os.getpid(),
                                     "time": datetime.now(UTC).isoformat()})
    except OSError as exc:
        shutil.rmtree(stage, ignore_errors=True)
        raise OutputFolderError(f"{out}: cannot write the output folder ({exc.strerror or exc}); "
                                "choose another --out") from None
    return stage


def commit_output(stage: Path, out: Path, overwrite: bool = False) -> None:
    """Move the finished staging folder into place.

    An old ``out`` (checked again: marked or empty) is first renamed aside, the new one is
    renamed into place, and only then is the old one deleted, so at every moment either
    the old or the new complete output is at ``out``.
    """
    target = out.resolve()
    old = None
    if target.exists() or target.is_symlink():
        if not overwrite:
            raise OutputFolderError(f"{out}: output folder appeared during the run; the new results are in {stage}")
        try:
            _check_replaceable(target, out)
        except OutputFolderError as exc:
            raise OutputFolderError(f"{exc}; the new results are in {stage}") from None
        old = target.parent / f".{target.name}.old-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    try:
        if old is not None:
            os.rename(target, old)
        try:
            os.rename(stage, target)
        except BaseException:
            if old is not None:
                os.rename(old, target)
            raise
    except OSError as exc:
        raise OutputFolderError(f"{out}: cannot move the new results into place ({exc.strerror or exc}); "
                                f"they are in {stage}") from None
    if old is not None:
        shutil.rmtree(old)


def run(
    cfg: IdentificationConfig,
    out: Path,
    overwrite: bool = False,
    progress: bool = True,
    base: Path | None = None,
    map_fn: MapFunction | None = None,
    min_parallel_s: float = PARALLEL_MIN_S,
    files: FigureFiles = PNG_ONLY,
) -> RunResult:
    """Full run; writes every output into ``out`` (see docs/identification.md); ``files``: the figures' dpi and
    vector formats.

    ``map_fn``, ``min_parallel_s``: how the conditions are spread (see :func:`identify_all`;
    default in this process).
    """
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
        results = identify_all(data, cfg, progress, map_fn=map_fn, min_parallel_s=min_parallel_s)
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
        select_models(run_result, cfg, synthetic, base, stage, progress)
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
        ident_report.write_tables(stage, run_result, cfg)
        (stage / "config_used.json").write_text(json.dumps(cfg.raw, indent=2))
        if cfg["figures"]:
            from orchestration.identification import ident_figures

            ident_figures.write_all(stage / "figures", run_result, cfg, files)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    commit_output(stage, out, overwrite)
    return run_result
