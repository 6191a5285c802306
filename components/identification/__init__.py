"""Identification of the MRE isolator models from shake-table tests (paper section 3).

testdata (CSV format, synthetic generator), models (Eq. 1-5 in paper units), ffoa (the
paper's FFOA), structured (variable projection), identifiers (one result type),
generalized (Eq. 13-16, parameter files), bouc_wen_joint (current-dependent Bouc-Wen),
bouc_wen_native (the population kernel in C), joint_fits (current-dependent forms fitted to all
conditions at once, and their bootstrap), model_selection (the table that picks the plant), plant_samples
(the sampled-plant file and its loader), paper_tables (the paper's Tables 1-2 and test
matrix the fits and the synthetic data use). This is the fitting library; the application
(configuration, pipeline, report, figures) is :mod:`orchestration.identification`, run by
orchestration/identify.py. See docs/identification.md. All data shipped with the toolkit are synthetic.
"""
