"""The identification application (paper section 3), run by ``orchestration/identify.py``.

ident_config (the YAML configuration and its checks), ident_pipeline (data -> per-condition
identification -> generalized model -> output folder), ident_result (what a run found),
ident_report (tables, results.json, summary.md), ident_figures (Fig. 6-12), paper_figures
(Fig. 3(b) and Fig. 13 from the paper's tables). The fitting itself (FFOA, the models, the
Bouc-Wen kernels, the identifiers, the generalized fit, test data) is the library
:mod:`components.identification`. May import that library, :mod:`components.physics`,
:mod:`orchestration.batch` and :mod:`mre_common`. See docs/identification.md.
"""
