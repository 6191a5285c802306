"""The paper's case study (section 4.3): records x control strategies on the isolated building.

``case_run`` runs it (``orchestration/study.py``), ``case_plan`` checks and plans it,
``case_jobs`` are its jobs on the batch pool, ``case_records`` the typed records between the
run and the report; the report is ``case_metrics`` (numbers and tables), ``case_figures`` and
``case_rendering`` (Markdown, HTML), assembled by ``case_report``. ``strategies`` maps each
control strategy to scenario overrides; ``tuning`` tunes the SOSM gains (``orchestration/tune.py``),
``base_sensitivity`` varies the base floor, ``claims`` checks the paper's claims, ``analysis``
computes a run's peaks and the evaluation indices.
"""
