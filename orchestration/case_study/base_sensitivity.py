"""Sensitivity of the case study's conclusions to the base floor the paper does not give (m_b, k_b, c_b).

The paper's building (Dyke et al., Table 3) has no base floor; the project assumes
m_b = 98.3 kg and k_b = c_b = 0 (README, Assumptions). This module re-runs the case
study's comparisons (passive-off, passive-on at i_max, both SOSM gain sets) for m_b at
0.5x, 1x and 2x and for a few non-zero k_b and c_b, in-process
(:func:`orchestration.inprocess.simulate_coupled`: the same cores, step and scheme
as the co-simulation, which the study's tests match to 1e-6), on the first ``window_s``
seconds of each record, and says whether each conclusion of the study still holds::

    python orchestration/study.py scenarios/case_study.yaml --base-sensitivity --out DIR

It writes ``base_sensitivity.csv`` (every run's peaks and current statistics),
``base_sensitivity.md`` (the table of conclusions) and ``base_sensitivity.json``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from components.physics.shear_building_core import BuildingParams
from components.physics.sosm_controller_core import SosmGains
from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.run_metrics import csv_text
from orchestration.building_studies.run_settings import run_overrides
from orchestration.case_study.case_config import LoadedStudy
from orchestration.case_study.claims import PINNED_SHARE
from orchestration.case_study.tuning import RECORD_COLUMNS, pool_evaluate_many
from orchestration.engine_hooks import plan_scenario
from orchestration.master.runfolder import write_json, write_text

TIE = 0.01  # as the study's verdicts: a relative difference within 1 % is a tie
WINDOW_S = 40.0  # s: the strong motion of every record (Kobe 5.4-20 s, El Centro within its first 30 s)


def variants(m_b: float) -> list[tuple[str, dict[str, float]]]:
    """(label, base-floor parameters) of the sensitivity runs; ``m_b`` is the default base mass [kg].

    k_b and c_b are set against the two isolators at 0 A (k0_1 = 3343 N/m and c0_1 = 339.6 N s/m
    per device, Table 2): about 0.15x and 0.75x their linear stiffness, 0.15x and 0.75x their damping.
    """
    return [("m_b ×0.5", {"m_0": 0.5 * m_b}), ("m_b ×1 (default)", {}), ("m_b ×2", {"m_0": 2.0 * m_b}),
            ("k_b = 1 kN/m", {"k_0": 1.0e3}), ("k_b = 5 kN/m", {"k_0": 5.0e3}),
            ("c_b = 100 N·s/m", {"c_0": 100.0}), ("c_b = 500 N·s/m", {"c_0": 500.0})]


def _verdict(a: float, b: float) -> str:
    r = a / b - 1
    return "−" if r < -TIE else "+" if r > TIE else "="


def conclusions(rows: Sequence[Mapping[str, Any]], records: Sequence[str], range_top: float
                ) -> dict[str, dict[str, Any]]:
    """Per variant, each conclusion of the case study: holds (bool) and the numbers behind it.

    ``rows``: one per variant x record x strategy with the keys of :func:`objective.peak_values`
    (a3 [m/s^2], d [m], s_bound, i_max [A], ...). Conclusions:

    * ``sosm_reduces``: SOSM lowers peak a_3 and peak drift against passive-off on every record;
    * ``sosm_vs_on``: the SOSM-vs-passive-on sign on a_3 per record (− lower, + higher, = tie);
    * ``fig15_reduces``: the same as ``sosm_reduces`` for sosm-fig15;
    * ``fig15_current``: the sosm-fig15 current stays within 0-``range_top`` A and at its limit for at
      most :data:`claims.PINNED_SHARE` of the window on every record.
    """
    by = {(r["variant"], r["record"], r["strategy"]): r for r in rows}
    out: dict[str, dict[str, Any]] = {}
    for v in dict.fromkeys(r["variant"] for r in rows):
        def get(rec: str, s: str, v: str = v) -> Mapping[str, Any] | None:
            return by.get((v, rec, s))

        c: dict[str, Any] = {}
        for name, s in (("sosm_reduces", "sosm"), ("fig15_reduces", "sosm-fig15")):
            pairs = [(get(rec, s), get(rec, "passive-off")) for rec in records]
            if all(a and b for a, b in pairs):
                ratios = [(a["a3"] / b["a3"], a["d"] / b["d"]) for a, b in pairs]
                c[name] = {"holds": all(ra < 1 - TIE and rd < 1 - TIE for ra, rd in ratios),
                           "a3_ratios": [ra for ra, _ in ratios], "drift_ratios": [rd for _, rd in ratios]}
        pairs = [(get(rec, "sosm"), get(rec, "passive-on")) for rec in records]
        if all(a and b for a, b in pairs):
            c["sosm_vs_on"] = {"signs": "".join(_verdict(a["a3"], b["a3"]) for a, b in pairs),
                               "a3_change": [a["a3"] / b["a3"] - 1 for a, b in pairs]}
        fig = [get(rec, "sosm-fig15") for rec in records]
        if all(fig):
            c["fig15_current"] = {"holds": all(f["i_min"] >= -1e-9 and f["i_max"] <= range_top + 1e-9
                                               and f["s_bound"] <= PINNED_SHARE for f in fig),
                                  "max_share_at_limit": max(f["s_bound"] for f in fig)}
        out[v] = c
    return out


def run_sensitivity(study: LoadedStudy, pool: Any, window_s: float = WINDOW_S) -> dict[str, Any]:
    """Every variant x record x strategy on the pool; returns rows, conclusions and provenance."""
    spec = study.spec
    started = time.time()
    gain_sets: dict[str, SosmGains] = {}
    for s in ("sosm", "sosm-fig15"):
        gains, _ = read_gains(study.gain_set_path(s))
        gain_sets[s] = gains
    m_b = BuildingParams.dyke().m[0]
    settings: list[tuple[str, float | SosmGains]] = [("passive-off", 0.0), ("passive-on", float(spec.i_max)),
                                                     *gain_sets.items()]
    plans, jobs, meta = {}, [], []
    for label, params in variants(m_b):
        for r in spec.records:
            over = (*run_overrides(spec), *(f"building.{k}={v!r}" for k, v in params.items()))
            plans[f"{label}|{r}"] = plan_scenario(study.scenario_path(r), over)
            for s, setting in settings:
                jobs.append((f"{label}|{r}", setting))
                meta.append({"variant": label, "record": r, "strategy": s, **{f"building.{k}": v
                                                                                 for k, v in params.items()}})
    results = pool_evaluate_many(pool, plans)(jobs, window_s)
    rows = [{**m, **res} for m, res in zip(meta, results, strict=True)]
    range_top = spec.paper_current_range[1]
    return {"window_s": window_s, "records": list(spec.records), "variants": [v for v, _ in variants(m_b)],
            "m_b_default_kg": m_b, "rows": rows, "conclusions": conclusions(rows, list(spec.records), range_top),
            "gains": {s: vars(g) for s, g in gain_sets.items()}, "wall_time_s": time.time() - started,
            "range_top_A": range_top}


def report_text(data: dict[str, Any], command: str) -> str:
    """Markdown of the sensitivity: what ran, the table of conclusions, where the numbers are."""
    recs = data["records"]
    lines = ["# Base-floor sensitivity", "",
             f"The case study's comparisons for base-floor variants (default m_b = {data['m_b_default_kg']:g} kg, "
             f"k_b = c_b = 0), in-process, first {data['window_s']:g} s of each record "
             f"({', '.join(recs)}), records as in the study. Regenerate: `{command}` "
             f"({data['wall_time_s']:.0f} s). Every run's peaks: `base_sensitivity.csv`.", "",
             "Columns: *SOSM reduces*: `sosm` lowers peak a_3 and peak drift against passive-off on every record "
             "(largest a_3 ratio in brackets); *sosm vs passive-on*: the a_3 verdict per record in the order "
             f"{', '.join(recs)} (− lower, + higher, = within 1 %); *fig15 reduces*: the same for `sosm-fig15`; "
             f"*fig15 current*: its current within 0-{data['range_top_A']:g} A and at its limit for at most "
             f"{100 * PINNED_SHARE:g} % of the window on every record (largest share in brackets).", "",
             "| variant | SOSM reduces | sosm vs passive-on (a_3) | fig15 reduces | fig15 current |",
             "|---|---|---|---|---|"]

    def yes(c: dict[str, Any] | None, extra: str) -> str:
        return "–" if not c else f"{'holds' if c['holds'] else 'FAILS'} ({extra})"

    for v in data["variants"]:
        c = data["conclusions"].get(v, {})
        red, fig, cur = c.get("sosm_reduces"), c.get("fig15_reduces"), c.get("fig15_current")
        vs_on = c.get("sosm_vs_on")
        red_txt = yes(red, f"{max(red['a3_ratios']):.3g}" if red else "")
        fig_txt = yes(fig, f"{max(fig['a3_ratios']):.3g}" if fig else "")
        cur_txt = yes(cur, f"{100 * cur['max_share_at_limit']:.0f} %" if cur else "")
        signs = " ".join(vs_on["signs"]) if vs_on else "–"
        lines.append(f"| {v} | {red_txt} | {signs} | {fig_txt} | {cur_txt} |")
    return "\n".join(lines) + "\n"


def write_sensitivity(folder: Path, data: dict[str, Any], command: str) -> None:
    """base_sensitivity.csv, .md and .json into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    cols = ("variant", "record", "strategy", "building.m_0", "building.k_0", "building.c_0", "a3", "d", "x0",
            "i_min", "i_max", *(k for k in RECORD_COLUMNS if k not in ("a3", "d", "x0")))
    write_text(folder / "base_sensitivity.csv", csv_text(cols, data["rows"]))
    write_text(folder / "base_sensitivity.md", report_text(data, command))
    write_json(folder / "base_sensitivity.json", {k: v for k, v in data.items()
                                                  if not (isinstance(v, float) and math.isnan(v))})
