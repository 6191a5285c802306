"""What every study of the isolated building shares: the case study, its controller benchmark and robustness
variants (:mod:`orchestration.case_study`) and the IDA (:mod:`orchestration.ida_study`).

``strategies`` maps each control strategy to scenario overrides (the shipped library and a study's own entries);
``run_settings`` is what every run of a study gets (the study's overrides, the recorded variables, the every-step
results file); ``study_file`` reads a study file's ``--set`` overrides and which file wrote each key;
``gains_file`` reads a SOSM gains file; ``in_process_model`` builds the in-process model of a planned scenario
(the paper's system only), ``isolated_structure`` its building and isolators alone (a run's periods);
``run_metrics`` computes a run's peaks and the evaluation indices; ``pool_arguments`` are the command-line
options of the batch pool. The two studies build on this package and never on each other.
"""
