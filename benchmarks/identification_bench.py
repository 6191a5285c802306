"""Identification benchmark: one condition by FFOA (hyperbolic and Bouc-Wen) against the structured identifier.

``measure()`` returns a dict that ``benchmarks/run.py`` renders (scalars, then the list of
rounds); ``python benchmarks/identification_bench.py [--rounds N]`` prints it as JSON.

Everything is measured side by side in one run, on the default configuration
(``scenarios/identification.yaml``: SYNTHETIC data, FFOA N_pop 50, N_iter 300, seeds as in
the full command, so the numbers are those of that condition in the full run):

* the three identifiers, in rotated order over ``rounds`` rounds; times are the
  optimisation only (``IdentResult.seconds``, ``perf_counter``), medians; ratios
  FFOA / structured;
* Bouc-Wen FFOA with the population kernel (C, see ``components/identification/
  bouc_wen_native.py``) against the numpy path it replaced, per FFOA iteration, on the
  same seed (``numpy_iterations`` iterations each: the numpy path is slow).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

PROJECT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(PROJECT))

from components.identification import bouc_wen_native  # noqa: E402
from components.identification.ffoa import FFOASettings, ffoa_minimize  # noqa: E402
from components.identification.identifiers import (  # noqa: E402
    BOUC_WEN_TYPICAL,
    IDENTIFIERS,
    Acceptance,
    identify_bouc_wen_ffoa,
    identify_hyperbolic_ffoa,
    identify_structured,
)
from components.identification.models import BOUC_WEN_PARAMS, bouc_wen_objective  # noqa: E402
from orchestration.identification.ident_config import load_config  # noqa: E402
from orchestration.identification.ident_pipeline import group, load_records  # noqa: E402

CONFIG = PROJECT / "scenarios" / "identification.yaml"


def _load() -> str:
    return "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def measure(condition: tuple[float, float, float] = (2.0, 4.0, 2.0), rounds: int = 3,
            numpy_iterations: int = 20) -> dict[str, Any]:
    """Seconds and ratios for one condition (frequency [Hz], amplitude [mm], current [A]); see module doc."""
    load_before = _load()
    cfg = load_config(CONFIG)
    data = group(load_records(cfg, CONFIG.parent), cfg["fit"]["first_cycle"], cfg["fit"]["cycles"])
    if condition not in data:
        raise ValueError(f"condition {condition} is not in the data set")
    k = list(data).index(condition)  # the condition's index in the full run seeds its FFOA streams
    d = data[condition]
    f, st = cfg["ffoa"], cfg["structured"]
    settings = FFOASettings(n_pop=f["n_pop"], n_iter=f["n_iter"], step=f["step"])
    acc = Acceptance(**cfg["acceptance"])
    names = list(IDENTIFIERS)

    def seed(name: str) -> np.random.Generator:
        j = cfg["identifiers"].index(name) if name in cfg["identifiers"] else IDENTIFIERS.index(name)
        return np.random.default_rng([f["seed"], k, j])

    run = {
        "hyperbolic-ffoa": lambda: identify_hyperbolic_ffoa(d, seed("hyperbolic-ffoa"), settings, acc),
        "bouc_wen-ffoa": lambda: identify_bouc_wen_ffoa(d, seed("bouc_wen-ffoa"), settings, acc),
        "hyperbolic-structured": lambda: identify_structured(
            d, acc, beta_bounds=(st["beta_min"], st["beta_max"]), n_grid=st["n_grid"]),
    }
    bouc_wen_native.kernel()  # compile outside the measurement
    rows: list[dict[str, Any]] = []
    seconds: dict[str, list[float]] = {name: [] for name in names}
    for r in range(rounds):
        for name in names[r % len(names):] + names[: r % len(names)]:
            res = run[name]()
            seconds[name].append(res.seconds)
            rows.append({"round": r + 1, "identifier": name, "seconds": res.seconds, "rms_n": res.rms,
                         "converged": res.converged})
    med = {name: statistics.median(v) for name, v in seconds.items()}

    # Bouc-Wen FFOA per iteration: the population kernel against the numpy path (same seed)
    short = FFOASettings(n_pop=f["n_pop"], n_iter=numpy_iterations, step=f["step"])
    typical = [BOUC_WEN_TYPICAL[p] for p in BOUC_WEN_PARAMS]
    per_iteration: dict[str, float] = {}
    for use in ("numpy", None):
        objective = bouc_wen_objective(d, use=use)
        t0 = time.perf_counter()
        ffoa_minimize(objective, typical, seed("bouc_wen-ffoa"), short)
        per_iteration["numpy" if use == "numpy" else "kernel"] = (time.perf_counter() - t0) / (numpy_iterations + 1)

    fr, amp, cur = condition
    return {
        "condition": f"{fr:g} Hz, {amp:g} mm, {cur:g} A",
        "ratio_hyperbolic_ffoa_over_structured": med["hyperbolic-ffoa"] / med["hyperbolic-structured"],
        "ratio_bouc_wen_ffoa_over_structured": med["bouc_wen-ffoa"] / med["hyperbolic-structured"],
        "ratio_bouc_wen_over_hyperbolic_ffoa": med["bouc_wen-ffoa"] / med["hyperbolic-ffoa"],
        "hyperbolic_ffoa_s": med["hyperbolic-ffoa"],
        "bouc_wen_ffoa_s": med["bouc_wen-ffoa"],
        "structured_s": med["hyperbolic-structured"],
        "bouc_wen_kernel": bouc_wen_native.backend(),
        "ratio_bouc_wen_numpy_over_kernel_per_iteration": per_iteration["numpy"] / per_iteration["kernel"],
        "bouc_wen_numpy_s_per_iteration": per_iteration["numpy"],
        "bouc_wen_kernel_s_per_iteration": per_iteration["kernel"],
        "settings": (f"SYNTHETIC data; FFOA N_pop {f['n_pop']}, N_iter {f['n_iter']}; optimisation time only, "
                     f"median of {rounds} rounds in rotated order; numpy vs kernel over {numpy_iterations} "
                     "iterations"),
        "load_before": load_before,
        "load_after": _load(),
        "rounds": rows,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--numpy-iterations", type=int, default=20)
    args = parser.parse_args(argv)
    print(json.dumps(measure(rounds=args.rounds, numpy_iterations=args.numpy_iterations), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
