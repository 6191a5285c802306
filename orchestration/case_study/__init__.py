"""The paper's case study (section 4.3): records x control strategies on the isolated building.

``case_run`` runs it (``orchestration/study.py``), ``case_plan`` checks and plans it,
``case_jobs`` are its jobs on the batch pool (their typed payloads and results), ``case_records``
the typed records between the run and the report; the report is ``case_metrics`` (numbers and
tables), ``case_figures`` and ``case_rendering`` (Markdown, HTML), assembled by ``case_report``.
``objective`` is the peaks of one setting and the objective J, ``current_sweep`` the best-constant
strategy's sweep, ``tuning`` tunes the SOSM gains (``orchestration/tune.py``); ``benchmark_criteria``
and ``benchmark_report`` are the controller benchmark, ``robustness_*`` its plant variants;
``base_sensitivity`` varies the base floor, ``claims`` checks the paper's claims. What it shares with
the IDA (strategies, run settings, the in-process model, run metrics, ...) is in
:mod:`orchestration.building_studies`.
"""
