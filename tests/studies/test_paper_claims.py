"""The paper's case-study claims as checks (orchestration.case_study.claims), on hand-made peaks."""

from __future__ import annotations

from orchestration.case_study.claims import check_claims


def peaks(acc: list[float], drift: list[float]) -> dict[str, float]:
    m = {f"acc_{j}": a for j, a in enumerate(acc)} | {f"drift_{j}_mm": d for j, d in enumerate(drift, start=1)}
    return m | {"drift_max_mm": max(drift)}


def by_claim(checks, claim_start: str, record: str, strategy: str):
    [found] = [c for c in checks if c.claim.startswith(claim_start) and c.record == record and c.strategy == strategy]
    return found


def test_profiles_rise_and_drop_with_height_within_the_tie():
    metrics = {
        ("a", "passive-off"): peaks([1.0, 2.0, 3.0, 4.0], [3.0, 2.0, 1.0]),   # both claims hold
        ("a", "sosm"): peaks([1.0, 0.995, 3.0, 4.0], [3.0, 3.02, 1.0]),     # dips within 1 %: still hold
        ("b", "passive-off"): peaks([5.0, 2.0, 3.0, 4.0], [1.0, 2.0, 1.0]),   # base peaks first; drift rises
        ("b", "sosm"): peaks([1.0, 2.0, 3.0, 2.0], [3.0, 2.0, 1.0]),
    }
    checks = check_claims(metrics, ["a", "b"], ["passive-off", "sosm"], controlled="sosm", uncontrolled="passive-off",
                          tie=0.01)
    assert by_claim(checks, "floor peak acceleration rises", "a", "passive-off").holds is True
    assert by_claim(checks, "floor peak acceleration rises", "a", "sosm").holds is True
    assert by_claim(checks, "inter-storey drift drops", "a", "sosm").holds is True
    assert by_claim(checks, "floor peak acceleration rises", "b", "passive-off").holds is False
    assert by_claim(checks, "inter-storey drift drops", "b", "passive-off").holds is False
    assert by_claim(checks, "floor peak acceleration rises", "b", "sosm").holds is False  # top below level 2


def test_control_reduction_and_where_it_is_largest():
    def pair(off_a3: float, sosm_a3: float):
        return peaks([1, 1, 1, off_a3], [2, 1, 0.5]), peaks([1, 1, 1, sosm_a3], [1, 0.5, 0.2])

    metrics = {}
    for record, (off, ctl) in {"elcentro": pair(10, 2), "hachinohe": pair(10, 3), "kobe": pair(10, 9.95),
                               "northridge": pair(10, 5)}.items():
        metrics[(record, "passive-off")], metrics[(record, "sosm")] = off, ctl
    records = ["elcentro", "hachinohe", "northridge", "kobe"]
    checks = check_claims(metrics, records, ["passive-off", "sosm"], controlled="sosm", uncontrolled="passive-off")
    assert by_claim(checks, "control reduces the top-floor", "elcentro", "sosm").holds is True
    assert by_claim(checks, "control reduces the top-floor", "kobe", "sosm").holds is False  # 0.5 % is a tie
    assert by_claim(checks, "control reduces the peak inter-storey", "kobe", "sosm").holds is True
    assert by_claim(checks, "the benefit", "all", "sosm").holds is True  # 80 % and 70 % lead 50 % and 0.5 %
    metrics[("northridge", "sosm")] = peaks([1, 1, 1, 1.0], [1, 0.5, 0.2])  # 90 %: northridge now leads
    again = check_claims(metrics, records, ["passive-off", "sosm"], controlled="sosm", uncontrolled="passive-off")
    assert by_claim(again, "the benefit", "all", "sosm").holds is False


def test_a_missing_run_is_not_judged():
    metrics = {("a", "passive-off"): peaks([1, 2, 3, 4], [3, 2, 1])}
    checks = check_claims(metrics, ["a"], ["passive-off", "sosm"], controlled="sosm", uncontrolled="passive-off")
    assert by_claim(checks, "control reduces the top-floor", "a", "sosm").holds is None


def current_metrics(i_min: float, i_max: float, at_top: float, at_zero: float) -> dict[str, float]:
    return {"current_min_A": i_min, "current_max_A": i_max, "current_mean_A": (i_min + i_max) / 2,
            "current_share_at_range_top": at_top, "current_share_at_zero": at_zero}


def test_the_fig15_current_claim_needs_the_range_and_no_plateau():
    from orchestration.case_study.claims import PINNED_SHARE, current_claim

    assert current_claim(current_metrics(0.0, 2.5, 0.10, 0.05), (0.0, 2.5), "a", "s").holds is True
    assert current_claim(current_metrics(0.0, 3.0, 0.00, 0.05), (0.0, 2.5), "a", "s").holds is False  # above 2.5 A
    # held at the top of the range longer than the plateau allowance: not "varying continuously"
    assert current_claim(current_metrics(0.0, 2.5, PINNED_SHARE + 0.01, 0.0), (0.0, 2.5), "a", "s").holds is False
    assert current_claim(current_metrics(0.0, 2.5, PINNED_SHARE, 0.0), (0.0, 2.5), "a", "s").holds is True
    assert current_claim(current_metrics(0.0, 2.0, 0.0, 0.6), (0.0, 2.5), "a", "s").holds is False  # mostly off


def test_claims_are_checked_for_each_controlled_strategy():
    off = peaks([1, 1, 1, 10], [2, 1, 0.5])
    metrics = {("a", "passive-off"): off,
               ("a", "sosm"): peaks([1, 1, 1, 2], [1, 0.5, 0.2]) | current_metrics(0.0, 3.0, 0.9, 0.0),
               ("a", "sosm-fig15"): peaks([1, 1, 1, 12], [1, 0.5, 0.2]) | current_metrics(0.0, 2.5, 0.1, 0.1)}
    checks = check_claims(metrics, ["a"], ["passive-off", "sosm", "sosm-fig15"], controlled=["sosm", "sosm-fig15"],
                          uncontrolled="passive-off",
                          current_range=(0.0, 2.5))
    assert by_claim(checks, "control reduces the top-floor", "a", "sosm").holds is True
    assert by_claim(checks, "control reduces the top-floor", "a", "sosm-fig15").holds is False  # 12 > 10
    assert by_claim(checks, "the current varies", "a", "sosm").holds is False
    assert by_claim(checks, "the current varies", "a", "sosm-fig15").holds is True
    # the profile claims are made once per strategy, not once per controlled strategy
    assert len([c for c in checks if c.claim.startswith("inter-storey drift drops")]) == 3


def test_the_html_tables_align_numbers_right_and_words_left(tmp_path):
    """A column of numbers (with a unit or % at most, – for a missing one) is right-aligned, header included;
    every other column left-aligned (the claims table's words had been pushed right)."""
    import re

    from orchestration.case_study.case_rendering import Block, to_html

    html = to_html([Block("table", header=["claim", "record", "ratio", "change", "quantity"],
                          rows=[["control reduces", "kobe", "0.171", "+3.5 %", "3.02 vs 17.7 m/s²"],
                                ["drift drops", "elcentro", "–", "-12 %", "1.5 vs 2 mm"]])], tmp_path)
    header = re.findall(r"<th class='(\w)'>", html)
    assert header == ["t", "t", "n", "n", "t"]
    assert re.findall(r"<td class='(\w)'>", html) == header * 2
