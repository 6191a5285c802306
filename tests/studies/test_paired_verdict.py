"""The verdict's statistics against independent computations: the exact signed-rank distribution by enumeration,
Holm's procedure by hand, the bootstrap percentile interval of a median against its exact bootstrap distribution
(binomial order statistics), and the record (not the component) as the unit; the command's bad input."""

from __future__ import annotations

import csv
import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import special

from orchestration.ida_study.paired_verdict import (
    compare,
    holm,
    median_interval,
    min_records_for,
    record_values,
    signed_rank_p,
)
from orchestration.verdict import main


def _exact_signed_rank_p(d: np.ndarray) -> float:
    """Two-sided p by enumerating all 2^n sign patterns of the ranks of |d| (no ties, no zeros)."""
    ranks = np.argsort(np.argsort(np.abs(d))) + 1
    w = float(ranks[d > 0].sum())
    all_w = np.array([sum(r for r, s in zip(ranks, signs, strict=True) if s)
                      for signs in itertools.product((0, 1), repeat=len(d))])
    return min(1.0, 2 * min(np.mean(all_w <= w), np.mean(all_w >= w)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_signed_rank_p_is_the_exact_enumeration(seed):
    d = np.random.default_rng(seed).normal(0.3, 1.0, 10)
    assert signed_rank_p(d) == pytest.approx(_exact_signed_rank_p(d), rel=1e-12)


def test_the_smallest_p_on_n_records_decides_how_many_are_needed():
    assert signed_rank_p(np.arange(1.0, 5.0)) == pytest.approx(0.125)  # 4 records: the 0.125
    assert signed_rank_p(np.arange(1.0, 6.0)) == pytest.approx(2 ** -4)
    assert min_records_for(0.05) == 6 and 2 ** (1 - 6) < 0.05 <= 2 ** (1 - 5)


def test_holm_by_hand():
    # sorted 0.005, 0.01, 0.03, 0.04 -> 4*0.005, 3*0.01, 2*0.03, max(0.06, 1*0.04)
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def _exact_bootstrap_quantiles(values: np.ndarray, q: tuple[float, float]) -> tuple[float, float]:
    """Quantiles of the median of n draws with replacement from n values (n odd): the median is the value at order
    (n+1)/2, so P(median <= v_k) = P(at least (n+1)/2 draws are among the k smallest), a binomial tail."""
    v = np.sort(values)
    n, m = len(v), (len(v) + 1) // 2
    cdf = [sum(special.comb(n, j) * (k / n) ** j * (1 - k / n) ** (n - j) for j in range(m, n + 1))
           for k in range(1, n + 1)]
    return tuple(float(v[next(k for k, c in enumerate(cdf) if c >= level)]) for level in q)


@pytest.mark.parametrize("values", [[1.0, 2, 3, 4, 5], [0.3, 0.5, 0.6, 0.9, 1.4, 2.0, 3.1]])
def test_the_bootstrap_interval_is_the_exact_bootstrap_distributions(values):
    med, lo, hi = median_interval(np.array(values))
    assert med == float(np.median(values))
    assert (lo, hi) == _exact_bootstrap_quantiles(np.array(values), (0.025, 0.975))


def _rows(values: dict[tuple[str, str, str], float], valid: set[tuple[str, str, str]] | None = None
          ) -> list[dict[str, str]]:
    rows = []
    for (record, component, strategy), j in values.items():
        ok = valid is None or (record, component, strategy) in valid
        rows.append({"record": record, "component": component, "intensity": "0.1", "strategy": strategy,
                     "valid": str(ok), **{c: repr(j) for c in ("J1", "J2", "J3", "J4", "J5", "J7", "J8")}})
    return rows


def test_a_record_is_the_geometric_mean_of_its_valid_components():
    values = {("FF01", "1", "a"): 0.5, ("FF01", "2", "a"): 2.0, ("FF02", "1", "a"): 0.8, ("FF02", "2", "a"): 9.0}
    got = record_values(_rows(values, valid={k for k in values if k != ("FF02", "2", "a")}), 0.1, "J3")
    assert got == {"a": {"FF01": pytest.approx(1.0), "FF02": pytest.approx(0.8)}}


def test_a_consistent_difference_on_eight_records_is_called_and_a_mixed_one_is_not():
    rng = np.random.default_rng(7)
    values = {}
    for k in range(8):
        base = float(rng.uniform(0.3, 1.0))
        for comp in "12":
            values[(f"FF{k:02d}", comp, "b")] = base
            values[(f"FF{k:02d}", comp, "a")] = 0.9 * base  # a is 10 % lower on every record
            values[(f"FF{k:02d}", comp, "c")] = base * (1.2 if k % 2 else 0.8)  # c is mixed
    summaries, pairs = compare(_rows(values), 0.1, ["a", "b", "c"], ("J3",))
    by = {(p.a, p.b): p for p in pairs}
    assert by["a", "b"].records == 8 and by["a", "b"].median_ratio == pytest.approx(0.9)
    assert by["a", "b"].p == pytest.approx(2 / 2 ** 8)  # every record one sign: the exact smallest p
    assert by["a", "b"].p_holm == pytest.approx(3 * 2 / 2 ** 8)  # the smallest of 3 p-values, times 3
    assert by["a", "b"].verdict(0.05) == "a lower (median ratio 0.900, -10.0 %)"
    assert by["b", "c"].verdict(0.05) == "not distinguishable on 8 records"
    assert {(s.strategy, s.records) for s in summaries} == {("a", 8), ("b", 8), ("c", 8)}


def _results(folder: Path) -> None:
    folder.mkdir()
    rows = _rows({(f"R{k}", "-", s): 1.0 + k + (0.1 if s == "b" else 0) for k in range(6) for s in ("a", "b")})
    with open(folder / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def test_the_command_writes_its_tables(tmp_path, capsys):
    _results(tmp_path / "ida")
    assert main([str(tmp_path / "ida"), "--out", str(tmp_path / "v"), "--criteria", "J3", "J5"]) == 0
    assert sorted(p.name for p in (tmp_path / "v").iterdir()) == ["pairs.csv", "summary.csv", "verdict.md"]
    with open(tmp_path / "v" / "pairs.csv") as f:
        pairs = list(csv.DictReader(f))
    assert [(p["criterion"], p["a"], p["b"]) for p in pairs] == [("J3", "a", "b"), ("J5", "a", "b")]
    assert float(pairs[0]["p"]) == pytest.approx(2 / 2 ** 6)
    assert math.isclose(float(pairs[0]["p_holm"]), 2 * 2 / 2 ** 6)
    # one sign on all 6 records gives p = 1/32; Holm over the 2 criteria doubles it past 0.05: not called
    assert "not distinguishable on 6 records" in capsys.readouterr().out
    assert main([str(tmp_path / "ida"), "--out", str(tmp_path / "v3"), "--criteria", "J3"]) == 0
    assert "| J3 | a | b | 6 | 0.9" in capsys.readouterr().out
    assert "a lower" in (tmp_path / "v3" / "verdict.md").read_text()


@pytest.mark.parametrize("case", ["no results", "level", "criterion", "strategy", "out not empty"])
def test_bad_input_is_exit_2_and_writes_nothing(tmp_path, capsys, case):
    _results(tmp_path / "ida")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine").write_text("x")
    args = {"no results": [str(tmp_path), "--out", str(tmp_path / "v")],
            "level": [str(tmp_path / "ida"), "--level", "0.3", "--out", str(tmp_path / "v")],
            "criterion": [str(tmp_path / "ida"), "--criteria", "J6", "--out", str(tmp_path / "v")],
            "strategy": [str(tmp_path / "ida"), "--strategies", "a", "zz", "--out", str(tmp_path / "v")],
            "out not empty": [str(tmp_path / "ida"), "--out", str(tmp_path / "full")]}[case]
    assert main(args) == 2
    err = capsys.readouterr().err
    expected = {"no results": "results.csv: No such file or directory", "level": "--level 0.3: the study ran 0.1",
                "criterion": "unknown J6", "strategy": "zz not in the study (it ran a, b)",
                "out not empty": "exists and is not an empty folder"}[case]
    assert expected in err and "Traceback" not in err
    assert not (tmp_path / "v").exists()
    assert [p.name for p in (tmp_path / "full").iterdir()] == ["mine"]
