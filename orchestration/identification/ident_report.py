"""Tables of an identification run: Table 1 and Table 2 layouts, RMS error and run time, summary."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from components.identification.generalized import LINEAR_IN_CURRENT, table2_from_table1
from components.identification.models import BOUC_WEN_PARAMS, HYPERBOLIC_PARAMS
from components.identification.testdata import SYNTHETIC_NOTE
from components.physics.mre_isolator_core import TABLE2_PAPER_UNITS
from mre_common.atomic_files import atomic_write, atomic_write_text

if TYPE_CHECKING:
    from orchestration.identification.ident_config import IdentificationConfig
    from orchestration.identification.ident_result import RunResult

NOT_CONVERGED = "not converged"
_UNITS = {
    "k0": "N/mm",
    "c0": "N*s/mm",
    "alpha": "N",
    "beta": "1/mm",
    "k": "N/mm",
    "c": "N*s/mm",
    "gamma": "1/mm",
    "n": "-",
    "F0": "N",
}


def _csv(rows: list[list[object]]) -> str:
    def cell(v: object) -> str:
        if isinstance(v, float):
            return f"{v:.6g}"
        s = str(v)
        return f'"{s}"' if ("," in s or '"' in s) else s

    return "\n".join(",".join(cell(v) for v in row) for row in rows) + "\n"


def _md(rows: list[list[object]]) -> str:
    def cell(v: object) -> str:
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    head, *body = rows
    lines = ["| " + " | ".join(map(str, head)) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in body]
    return "\n".join(lines) + "\n"


def table1_rows(rr: RunResult, name: str) -> list[list[object]]:
    """Table 1 layout: frequency, amplitude, parameter, one column per current."""
    per = rr.results[name]
    params = HYPERBOLIC_PARAMS if name.startswith("hyperbolic") else BOUC_WEN_PARAMS
    params = (*params, "F0")
    currents = sorted({c[2] for c in per})
    rows: list[list[object]] = [
        ["frequency_hz", "amplitude_mm", "parameter", "unit", *[f"{i:g}A" for i in currents]]
    ]
    for f, a in sorted({(c[0], c[1]) for c in per}):
        for p in params:
            row: list[object] = [f, a, p, _UNITS[p]]
            for i in currents:
                r = per.get((f, a, i))
                row.append("" if r is None else (r.params[p] if r.converged else NOT_CONVERGED))
            rows.append(row)
    return rows


def error_rows(rr: RunResult) -> list[list[object]]:
    """RMS error [N], RMS / noise RMS, run time [s], converged, reason per condition and identifier."""
    names = list(rr.results)
    head: list[object] = ["frequency_hz", "amplitude_mm", "current_a", "force_rms_n", "noise_rms_n"]
    for n in names:
        head += [f"{n}.rms_n", f"{n}.rms_over_noise", f"{n}.seconds", f"{n}.converged", f"{n}.reason"]
    rows = [head]
    for cond, d in rr.data.items():
        noise = d.noise_rms
        row: list[object] = [*cond, d.force_rms, "" if noise is None else noise]
        for n in names:
            r = rr.results[n][cond]
            row += [r.rms, "" if noise is None else r.rms / noise, r.seconds, r.converged, r.reason]
        rows.append(row)
    return rows


def table2_rows(rr: RunResult) -> list[list[object]]:
    """Table 2 layout: coefficient, paper, LS on the paper's Table 1 means, then each identifier."""
    ref = table2_from_table1().coefficients
    hyper = [n for n in rr.generalized if n.startswith("hyperbolic")]
    rows: list[list[object]] = [
        ["coefficient", "paper_table2", "ls_on_paper_table1_means", "rel_diff_percent", *hyper]
    ]
    for key, paper in TABLE2_PAPER_UNITS.items():
        rows.append(
            [
                key,
                paper,
                ref[key],
                100 * (ref[key] / paper - 1),
                *[rr.generalized[n].coefficients[key] for n in hyper],
            ]
        )
    return rows


def bouc_wen_table2_rows(rr: RunResult) -> list[list[object]]:
    """Generalized Bouc-Wen coefficients (mm-based units): FFOA averages and the joint LS fit."""
    names = [n for n in ("bouc_wen-ffoa", "bouc_wen-joint") if n in rr.generalized]
    if not names:
        return []
    keys = [f"{p}_{s}" for p in LINEAR_IN_CURRENT["bouc_wen"] for s in (0, 1)] + ["n", "delta"]
    return [
        ["coefficient", *names],
        *[[k, *[rr.generalized[n].coefficients[k] for n in names]] for k in keys],
    ]


def generalized_rows(rr: RunResult) -> list[list[object]]:
    """How well each generalized (current-dependent) model explains every condition's data."""
    rows: list[list[object]] = [
        ["generalized model", "median RMS [N]", "max RMS [N]", "median RMS/noise", "max RMS/noise"]
    ]
    for name, per in rr.generalized_rms.items():
        rms = np.array([per[c] for c in rr.data])
        noise = [rr.data[c].noise_rms for c in rr.data]
        if all(n is not None for n in noise):
            ratio = rms / np.array(noise, dtype=float)
            med, mx = float(np.median(ratio)), float(np.max(ratio))
        else:
            med = mx = "n/a"
        rows.append([name, float(np.median(rms)), float(np.max(rms)), med, mx])
    return rows


def selection_rows(rr: RunResult) -> list[list[object]]:
    """The model-selection table (components/identification/model_selection.py), one row per candidate."""
    rows: list[list[object]] = [["model", "parameters", "median RMS/noise", "max RMS/noise",
                                 "median |peak error| %", "max |peak error| %", "F(14.9 mm)/F(8 mm) 1 Hz 3 A",
                                 "AIC sample", "BIC sample", "AIC condition", "BIC condition"]]
    for sel in rr.selection:
        s = sel.summary()
        rows.append([sel.name, sel.parameters, s["rms_noise_median"], s["rms_noise_max"],
                     100 * s["peak_error_median"], 100 * s["peak_error_max"], s["stroke_ratio"],
                     sel.aic["sample"], sel.bic["sample"], sel.aic["condition"], sel.bic["condition"]])
    return rows


def bootstrap_rows(rr: RunResult) -> list[list[object]]:
    """Nominal, bootstrap mean and standard deviation of every coefficient of the sampled plant."""
    b = rr.bootstrap
    if b is None:
        return []
    nominal = rr.generalized["bouc_wen-joint"].coefficients
    rows: list[list[object]] = [["coefficient (paper units)", "joint fit", "bootstrap mean", "bootstrap std"]]
    for j, name in enumerate(b.names):
        rows.append([name, nominal[name], float(b.samples[:, j].mean()), float(b.samples[:, j].std(ddof=1))])
    return rows


def summary_rows(rr: RunResult) -> list[list[object]]:
    """Per identifier: converged count, RMS error and seconds per condition (median, max)."""
    rows: list[list[object]] = [
        [
            "identifier",
            "converged",
            "median RMS [N]",
            "median RMS/noise",
            "max RMS/noise",
            "n within 5% of noise",
            "median s/cond",
            "max s/cond",
            "total s",
        ]
    ]
    for name, per in rr.results.items():
        res = list(per.values())
        rms = np.array([r.rms for r in res])
        sec = np.array([r.seconds for r in res])
        noise = [r.noise_rms for r in res]
        if all(n is not None for n in noise):
            ratio = rms / np.array(noise, dtype=float)
            med_r, max_r, within = float(np.median(ratio)), float(np.max(ratio)), int(np.sum(ratio <= 1.05))
        else:
            med_r = max_r = within = "n/a"
        rows.append(
            [
                name,
                f"{sum(r.converged for r in res)}/{len(res)}",
                float(np.median(rms)),
                med_r,
                max_r,
                f"{within}/{len(res)}" if within != "n/a" else within,
                float(np.median(sec)),
                float(np.max(sec)),
                float(np.sum(sec)),
            ]
        )
    return rows


def write_tables(out: Path, rr: RunResult, cfg: IdentificationConfig) -> None:
    """Write table1_*.csv, errors_and_times.csv, table2*.csv, results.json and summary.md."""
    head = f"# {SYNTHETIC_NOTE}\n" if rr.synthetic else ""  # every CSV says when its data are synthetic
    for name in rr.results:
        atomic_write_text(out / f"table1_{name}.csv", head + _csv(table1_rows(rr, name)))
    atomic_write_text(out / "errors_and_times.csv", head + _csv(error_rows(rr)))
    atomic_write_text(out / "table2.csv", head + _csv(table2_rows(rr)))
    atomic_write_text(out / "generalized_models_rms.csv", head + _csv(generalized_rows(rr)))
    bw = bouc_wen_table2_rows(rr)
    if bw:
        atomic_write_text(out / "table2_bouc_wen.csv", head + _csv(bw))
    if rr.selection:
        atomic_write_text(out / "model_selection.csv", head + _csv(selection_rows(rr)))
    if rr.bootstrap is not None:
        atomic_write_text(out / "plant_bootstrap.csv", head + _csv(bootstrap_rows(rr)))
    payload = {
        "synthetic": rr.synthetic,
        "note": SYNTHETIC_NOTE if rr.synthetic else "measured data",
        "results": [
            {
                "identifier": r.identifier,
                "condition": list(r.condition),
                "converged": r.converged,
                "reason": r.reason,
                "rms_n": r.rms,
                "noise_rms_n": r.noise_rms,
                "seconds": r.seconds,
                "params_paper_units": r.params if r.converged else None,
            }
            for per in rr.results.values()
            for r in per.values()
        ],
        "generalization_errors": rr.generalization_errors,
    }
    atomic_write_text(out / "results.json", json.dumps(payload, indent=1))
    write_ffoa_traces(out / "ffoa_traces.npz", rr)
    atomic_write_text(out / "summary.md", summary_text(rr, cfg))


def write_ffoa_traces(path: Path, rr: RunResult) -> None:
    """FFOA convergence histories and flight paths (Fig. 6 data) of every run, as one .npz.

    Keys ``<identifier>|<f>Hz|<A>mm|<i>A|history`` (n_iter,) and ``...|path``
    (n_iter + 1, n_params, 2): swarm (X, Y) per parameter.
    """
    arrays = {}
    for name, per in rr.results.items():
        for (f, a, i), r in per.items():
            if r.history is not None:
                key = f"{name}|{f:g}Hz|{a:g}mm|{i:g}A"
                arrays[f"{key}|history"] = r.history
                arrays[f"{key}|path"] = r.path
    if not arrays:
        return
    atomic_write(path, lambda f: np.savez_compressed(f, **arrays), binary=True)


def summary_text(rr: RunResult, cfg: IdentificationConfig) -> str:
    """Human-readable summary (also printed by the CLI)."""
    lines = []
    if rr.synthetic:
        lines += [f"**{SYNTHETIC_NOTE}.**", ""]
    f = cfg["ffoa"]
    first, last = cfg["fit"]["first_cycle"], cfg["fit"]["first_cycle"] + cfg["fit"]["cycles"] - 1
    lines += [
        f"# Isolator identification ({len(rr.data)} conditions)",
        "",
        f"FFOA: N_pop = {f['n_pop']}, N_iter = {f['n_iter']}, step = {f['step']:g}, seed = {f['seed']}; "
        f"fit window: cycles {first}..{last}"
        " of every repeat.",
        "",
        "## RMS error and run time per condition (side by side)",
        "",
        _md(summary_rows(rr)),
        "## Table 2: generalized coefficients (paper units)",
        "",
        _md(table2_rows(rr)),
    ]
    bw = bouc_wen_table2_rows(rr)
    if bw:
        lines += ["Bouc-Wen generalized coefficients (mm-based units):", "", _md(bw)]
    if rr.joint is not None:
        j = rr.joint
        lines += [
            f"Joint Bouc-Wen least squares: cost {j.cost_start:.4g} -> {j.cost:.4g} in {j.seconds:.1f} s "
            f"({j.message}).",
            "",
        ]
    if rr.generalized_rms:
        lines += ["## Generalized models on the data of every condition", "", _md(generalized_rows(rr))]
    if rr.selection:
        lines += ["## Model selection (sinusoidal drive against Table 1; AIC/BIC, docs/identification.md)", "",
                  _md(selection_rows(rr))]
    if rr.bootstrap is not None:
        lines += [f"## Sampled plants: bootstrap of the Bouc-Wen joint fit ({len(rr.bootstrap.samples)} refits, "
                  f"{rr.bootstrap.seconds:.0f} s)", "", _md(bootstrap_rows(rr))]
    bad = rr.not_converged
    if bad:
        lines += ["## Not converged (no parameters written)", ""]
        lines += [
            f"- {r.identifier} at {r.condition[0]:g} Hz, {r.condition[1]:g} mm, {r.condition[2]:g} A: "
            f"{r.reason}"
            for r in bad
        ]
        lines.append("")
    for name, msg in rr.generalization_errors.items():
        lines.append(f"- generalized model from {name} not written: {msg}")
    return "\n".join(lines) + "\n"
