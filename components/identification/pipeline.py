"""The identification run: data -> per-condition identification -> generalized model -> outputs."""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import uuid
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from tqdm import tqdm

from components.identification import report
from components.identification.bouc_wen_joint import fit_bouc_wen_joint
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
from components.identification.run_result import RunResult
from components.identification.testdata import (
    SYNTHETIC_NOTE,
    NoiseModel,
    ShakeRecord,
    TestDataError,
    generate_synthetic,
    read_folder,
    write_csv,
)
from components.physics.bouc_wen_core import SYNTHETIC_DEFAULT
from components.physics.mre_isolator_core import TABLE2_PAPER_UNITS


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
        mask = os.umask(0)
        os.umask(mask)
        stage.chmod(0o777 & ~mask)  # mkdtemp makes it private; the output gets the usual permissions
        (stage / MARKER).write_text(json.dumps({"tool": "mre-cosim identify", "pid": os.getpid(),
                                                "time": datetime.now(UTC).isoformat()}))
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
    commit_output(stage, out, overwrite)
    return run_result
