"""Which controller is better, and how sure: medians with bootstrap intervals and paired tests over records.

Input: an IDA study's ``results.csv`` (one row per component x level x strategy, the criteria J1-J8 against
passive-off at the same component and level, and each run's ``valid``). At one intensity level:

* **The unit is the record** (the suite's pair: both horizontal components of one station), not the
  component: the two components of a station share their event, site and distance, so they are not
  independent draws. A record's value of a criterion is the geometric mean of its valid components' values.
  (Stations of one earthquake are not independent either; the suite does not say which records share an
  event in its results, so the records are the unit here, and the report says so.)
* **Median with a 95 % interval** per strategy and criterion: the median over records, its interval from
  scipy's bootstrap (percentile method, 9,999 resamples of the records, seeded).
* **Paired comparison** of every two strategies on each criterion: the Wilcoxon signed-rank test
  (Wilcoxon 1945; scipy, exact distribution without ties and zeros) on the records' log ratios
  log(J_A / J_B), over the records where both are valid. The p-values of the whole family (every pair x
  criterion) are Holm-corrected (Holm 1979). A pair is called only where the corrected p is below alpha;
  otherwise it is "not distinguishable on N records".
"""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

CRITERIA = ("J1", "J2", "J3", "J4", "J5", "J7", "J8")
RESAMPLES = 9_999
SEED = 20261203


class VerdictError(ValueError):
    """A results file that cannot carry the comparison (missing, no such level, too few records)."""


def read_results(path: Path) -> list[dict[str, str]]:
    """The rows of an IDA study's results.csv; VerdictError naming the file if it is missing or not one."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except OSError as exc:
        raise VerdictError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise VerdictError(f"{path}: not an IDA results file ({type(exc).__name__})") from None
    needed = {"record", "component", "intensity", "strategy", "valid", *CRITERIA}
    if not rows or not needed <= set(rows[0]):
        raise VerdictError(f"{path}: not an IDA results file (needs the columns {', '.join(sorted(needed))})")
    for line, r in enumerate(rows, 2):
        try:
            level = float(r["intensity"])
        except (TypeError, ValueError):
            level = math.nan
        if not (math.isfinite(level) and level > 0):
            raise VerdictError(f"{path}:{line}: intensity {r['intensity']!r} is not a positive number")
    return rows


def levels(rows: list[dict[str, str]]) -> list[float]:
    """The intensity levels of the results [g or the measure's unit], ascending."""
    return sorted({float(r["intensity"]) for r in rows})


def record_values(rows: list[dict[str, str]], level: float, criterion: str) -> dict[str, dict[str, float]]:
    """strategy -> record -> the geometric mean of its valid components' ``criterion`` at ``level``."""
    parts: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        if not math.isclose(float(r["intensity"]), level, rel_tol=1e-9) or r["valid"] != "True":
            continue
        try:
            value = float(r[criterion])
        except ValueError:
            continue
        if math.isfinite(value) and value > 0:
            parts[r["strategy"]][r["record"]].append(value)
    return {s: {rec: float(np.exp(np.mean(np.log(v)))) for rec, v in recs.items()} for s, recs in parts.items()}


def median_interval(values: np.ndarray, confidence: float = 0.95, seed: int = SEED) -> tuple[float, float, float]:
    """The median and its bootstrap interval (percentile method, records resampled with replacement)."""
    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return float(np.median(values)) if len(values) else math.nan, math.nan, math.nan
    res = stats.bootstrap((values,), np.median, confidence_level=confidence, n_resamples=RESAMPLES,
                          method="percentile", random_state=np.random.default_rng(seed))
    return float(np.median(values)), float(res.confidence_interval.low), float(res.confidence_interval.high)


def signed_rank_p(differences: np.ndarray) -> float:
    """Two-sided p of the Wilcoxon signed-rank test (exact without ties or zeros; scipy's choice otherwise)."""
    d = np.asarray(differences, dtype=float)
    if len(d) == 0 or np.all(d == 0):
        return 1.0
    return float(stats.wilcoxon(d, alternative="two-sided").pvalue)


def holm(pvalues: list[float]) -> list[float]:
    """Holm's step-down adjusted p-values (Holm 1979), in the order given."""
    m = len(pvalues)
    order = sorted(range(m), key=lambda k: pvalues[k])
    adjusted = [0.0] * m
    running = 0.0
    for rank, k in enumerate(order):
        running = max(running, min(1.0, (m - rank) * pvalues[k]))
        adjusted[k] = running
    return adjusted


@dataclass(frozen=True)
class Summary:
    """One strategy's median of one criterion over records, with its interval and how many records it rests on."""

    strategy: str
    criterion: str
    median: float
    low: float
    high: float
    records: int


@dataclass(frozen=True)
class Pair:
    """Strategies ``a`` and ``b`` on one criterion: the median log ratio over records and the test."""

    criterion: str
    a: str
    b: str
    records: int
    median_ratio: float  # exp(median of log(J_a / J_b)): below 1, a is lower
    p: float
    p_holm: float = math.nan

    def verdict(self, alpha: float) -> str:
        if not self.p_holm < alpha:
            return f"not distinguishable on {self.records} records"
        lower, ratio = (self.a, self.median_ratio) if self.median_ratio < 1 else (self.b, 1 / self.median_ratio)
        return f"{lower} lower (median ratio {ratio:.3f}, {100 * (ratio - 1):+.1f} %)"


def compare(rows: list[dict[str, str]], level: float, strategies: list[str], criteria: tuple[str, ...] = CRITERIA
            ) -> tuple[list[Summary], list[Pair]]:
    """Medians with intervals and every pair's test at ``level``, Holm-corrected over every pair x criterion."""
    summaries, pairs = [], []
    for c in criteria:
        values = record_values(rows, level, c)
        for s in strategies:
            v = np.array(sorted(values.get(s, {}).values()))
            summaries.append(Summary(s, c, *median_interval(v), len(v)))
        for i, a in enumerate(strategies):
            for b in strategies[i + 1:]:
                common = sorted(set(values.get(a, {})) & set(values.get(b, {})))
                d = np.array([math.log(values[a][r] / values[b][r]) for r in common])
                pairs.append(Pair(c, a, b, len(d), float(np.exp(np.median(d))) if len(d) else math.nan,
                                  signed_rank_p(d) if len(d) else 1.0))
    adjusted = holm([p.p for p in pairs])
    return summaries, [Pair(p.criterion, p.a, p.b, p.records, p.median_ratio, p.p, q) for p, q in zip(pairs, adjusted,
                                                                                                      strict=True)]


def min_records_for(alpha: float) -> int:
    """The fewest records on which the two-sided exact signed-rank test can reach p < alpha at all: its smallest
    p on n records is 2^(1-n) (every difference of one sign)."""
    return math.floor(1 + math.log2(1 / alpha)) + 1
