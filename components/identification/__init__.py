"""Identification of the MRE isolator models from shake-table tests (paper section 3).

testdata (CSV format, synthetic generator), models (Eq. 1-5 in paper units), ffoa (the
paper's FFOA), structured (variable projection), identifiers (one result type),
generalized (Eq. 13-16, parameter files), bouc_wen_joint (current-dependent Bouc-Wen),
config / pipeline / report / figures (the CLI orchestration/identify.py).
See docs/identification.md. All data shipped with the toolkit are synthetic.
"""
