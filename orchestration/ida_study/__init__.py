"""Incremental dynamic analysis and fragility of the isolated building (``orchestration/ida.py``).

``ida_run`` runs it, ``ida_plan`` checks and plans it (record components, every run's plan),
``ida_jobs`` is its job on the batch pool, ``ida_records`` the typed records between run and
report; the report is ``ida_metrics`` (result rows, fragility fits, tables), ``ida_figures`` and
``ida_rendering`` (Markdown, HTML), assembled by ``ida_report``. ``suites`` reads record suites,
``intensity`` measures PGA and Sa, ``fragility`` fits lognormal fragility curves. What it shares
with the case study (strategies, run settings, the in-process model, run metrics, ...) is in
:mod:`orchestration.building_studies`.
"""
