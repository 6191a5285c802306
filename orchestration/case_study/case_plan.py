"""A case study checked and planned before anything is written: gain sets, records, every job.

:func:`prepare` checks every record x strategy through the engine's checks (ScenarioError or
NotMonolithic before a folder exists); :func:`plan_job` turns one job into its content key,
portable plan and inputs (see :mod:`orchestration.batch.portable`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

from components.physics.shear_building_core import BuildingParams
from orchestration.batch.portable import PortablePlan, job_key, plan_content, portable
from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.in_process_model import monolithic_problem, system_setup
from orchestration.building_studies.run_settings import run_overrides
from orchestration.building_studies.strategies import COMMAND, check_strategy
from orchestration.case_study import case_jobs
from orchestration.case_study.case_config import GAIN_SETS, LoadedStudy
from orchestration.case_study.case_records import CaseStudyRecord, PreparedStudy, RecordInfo, RunEntry
from orchestration.case_study.robustness_plan import check_variants
from orchestration.case_study.run_numbers import NumberInputs
from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.yaml_source import load_tree


class PlannedJob(NamedTuple):
    """One job as planned: its label (``record/...``), content key, portable plan and the inputs of its payload."""

    label: str
    key: str
    plan: PortablePlan
    inputs: dict[str, Any]


def gain_sets(study: LoadedStudy) -> dict[str, dict[str, Any]]:
    """SOSM gain set -> its gains file's document; ScenarioError if tuned for another current limit."""
    spec = study.spec
    sets: dict[str, Any] = {}
    used = {study.strategy(s).entry.gains for s in spec.strategies}
    for gain_set in (g for g in GAIN_SETS if g in used):
        path = study.gain_set_path(gain_set)
        gains, sets[gain_set] = read_gains(path)
        i_max = study.gain_set(gain_set)[0]
        if abs(gains.i_max - i_max) > 1e-12:
            key = "i_max" if gain_set == GAIN_SETS[0] else "fig15.i_max"
            raise ScenarioError(f"{path}: gains tuned for i_max = {gains.i_max} A, the study's {key} is "
                                f"{i_max} A: re-run the tuning")
    return sets


def check_record(study: LoadedStudy, record: str, sets: dict[str, dict[str, Any]]) -> tuple[RecordInfo, Any]:
    """Plan a record under every kind of controller the study uses; its facts and its last plan."""
    spec = study.spec
    path = study.scenario_path(record)
    base = run_overrides(spec)
    plans, problems = {}, []
    uncontrolled = study.uncontrolled
    for s in sorted({uncontrolled, *(s for s in spec.strategies if not study.strategy(s).needs_sweep)}):
        strategy = study.strategy(s)
        g = sets[strategy.entry.gains]["gains"] if strategy.entry.gains in sets else None
        try:
            if strategy.entry.fmu is not None or strategy.entry.connections is not None:
                check_strategy(strategy, path, base, spec.i_max, g, 0.0)  # problems at the strategy entry's lines
            plans[s] = plan_scenario(path, (*strategy.common(base),
                                            *run_strategy_overrides(study, s, path, spec.i_max, g, 0.0)))
        except ScenarioError as exc:
            problems += [p for p in exc.problems if p not in problems]
    if problems:
        raise ScenarioError(problems)
    plan = plans[uncontrolled]
    sim = plan.loaded.scenario.simulation
    # the in-process model: for the Radau reference, and for the sweep on the paper's system (another plant's sweep
    # co-simulates its FMUs, current_sweep.sweep_currents)
    needs_model = spec.reference.enabled or (study.needs_sweep and monolithic_problem(plan) is None)
    setup = system_setup(plan, 0.0) if needs_model else None
    masses = list(setup.building.m) if setup else list(BuildingParams.dyke().m)
    ground = plan.parameters.get("ground", {})
    info = RecordInfo(str(path), sim.stop_time, masses, str(plan.data_files.get("ground.record", "")),
                      ground.get("scale"), ground.get("time_scale", 1.0),
                      plan.parameters.get("isolator", {}).get("n_isolators"), record_name(plan))
    return info, plan


def record_name(plan: Any) -> str | None:
    """The scenario's readable name of its ground record (``report.labels``: ``ground.record=FILE: name``), or
    None: the study's record id stands for it."""
    played = Path(str(plan.data_files.get("ground.record", ""))).name
    for key, label in plan.report.labels.items():
        variable, _, value = key.partition("=")
        if variable == "ground.record" and value and Path(value).name == played:
            return str(label)
    return None


def prepare(study: LoadedStudy) -> PreparedStudy:
    """Check every run of the study before anything is written; raises ScenarioError or NotMonolithic."""
    sets = gain_sets(study)
    records: dict[str, RecordInfo] = {}
    algorithms: dict[str, str] = {}
    step = None
    for r in study.spec.records:
        records[r], plan = check_record(study, r, sets)
        sim = plan.loaded.scenario.simulation
        algorithms[r], step = sim.algorithm, sim.step
    heights = study.spec.figure_units.storey_heights
    wrong = {r: len(info.masses_kg) - 1 for r, info in records.items() if heights and len(heights) !=
             len(info.masses_kg) - 1}
    if wrong:
        file, line = study.lines.get(("figure_units", "storey_heights")) or (str(study.path), None)
        raise ScenarioError(Problem(f"{len(heights or [])} storey heights, but the building has "
                                    f"{', '.join(f'{n} storeys ({r})' for r, n in wrong.items())}",
                                    "figure_units.storey_heights", file, line))
    if study.spec.robustness is not None:
        check_variants(study, run_overrides(study.spec), sets, run_strategy_overrides)
    return PreparedStudy(records, sets, algorithms, step)


def run_strategy_overrides(study: LoadedStudy, strategy: str, scenario: Path, i_max: float,
                           gains: dict[str, float] | None, best: float | None) -> tuple[str, ...]:
    """The overrides of one record x strategy run after the study's (``strategy.common(base)``): the controller
    unit, then its wiring (connections, the report's current) if the entry changes it."""
    s = study.strategy(strategy)
    rewired = s.entry.connections is not None or s.entry.current != COMMAND
    wiring = s.wiring_overrides(list(load_tree(scenario)[0].get("connections") or [])) if rewired else ()
    return (*s.overrides(i_max, gains, best), *wiring)


def number_inputs(study: LoadedStudy, record: CaseStudyRecord, entry: RunEntry, figures: bool) -> NumberInputs:
    """What the run of ``entry`` needs to compute its numbers in the run (:mod:`.run_numbers`): the record's masses,
    the controller's current limit (its gain set's own where the entry says ``gains_limit``, else the study's),
    the paper's current range, its SOSM gain set if it has one, and whether it keeps its figure series
    (``figures``: the study's own runs, which the figures draw) and its time series (the study's ``timeseries``)."""
    spec, info = study.spec, record.records[entry.record]
    strategy = study.strategy(entry.strategy)
    doc = record.gain_sets.get(strategy.entry.gains or "")
    gains = dict(doc["gains"]) if doc else None
    limit = float(gains["i_max"]) if gains is not None and strategy.entry.gains_limit else float(spec.i_max)
    return NumberInputs(masses=list(info.masses_kg), current_limit=limit,
                        paper_current_range=tuple(spec.paper_current_range), sosm_gains=gains,
                        n_isolators=int(info.n_isolators or 2), figure_series=figures, timeseries=spec.timeseries)


def plan_cosim(study: LoadedStudy, label: str, overrides: tuple[str, ...], outputs: str, numbers: NumberInputs
               ) -> PlannedJob:
    """A co-simulation job recording ``outputs`` (an ``outputs=[...]`` override, last) that computes ``numbers``;
    the isolator's ``F_off`` among them only where the isolator FMU has it (an isolator from another tool may not:
    its J6 is then NaN)."""
    extra = {"numbers": numbers.to_json()}
    try:
        return plan_job(study, label, "cosim", (*overrides, outputs), extra)
    except ScenarioError as exc:
        name = case_jobs.FORCE_OFF_OUTPUT
        if name not in outputs or not any(name in p.message for p in exc.problems):
            raise
    return plan_job(study, label, "cosim", (*overrides, outputs.replace(f", {name}", "")), extra)


def plan_job(study: LoadedStudy, label: str, kind: str, overrides: tuple[str, ...], extra: dict[str, Any]
             ) -> PlannedJob:
    """Label, content key, portable plan and payload inputs of one job (label ``record/...``)."""
    plan = plan_scenario(study.scenario_path(label.split("/")[0]), overrides)
    pp = portable(plan)
    return PlannedJob(label, job_key(kind, {"job": label, "plan": plan_content(pp), **extra}, case_jobs.CODE_SOURCES),
                      pp, extra)
