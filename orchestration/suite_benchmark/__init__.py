"""The suite benchmark: every strategy tuned alike on some events of a record suite, scored on the others.

An application over both studies: the strategy tuner's search (:mod:`orchestration.case_study.strategy_tuner`) on
the IDA's planned runs (:mod:`orchestration.ida_study`), then the IDA's runs and the paired verdict on the events
not trained on. ``python orchestration/study.py scenarios/controller_suite_benchmark.yaml``.
"""
