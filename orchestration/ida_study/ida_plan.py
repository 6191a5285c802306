"""An IDA study checked and planned before anything runs: its record components and every run's plan.

:func:`prepare_ida` reads the suite, cuts each component to its strong-motion window and
stages it as a record file, plans every component x strategy through the engine's checks
and measures each component's intensity at scale 1; whatever is wrong is reported at once
(ScenarioError listing every problem), before a worker starts.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from components.physics.building_periods import isolated_period
from components.physics.shear_building_core import BuildingParams
from orchestration.batch.portable import PortablePlan, portable
from orchestration.building_studies.gains_file import read_gains
from orchestration.building_studies.in_process_model import NotMonolithic, system_setup
from orchestration.building_studies.run_settings import RECORDED
from orchestration.building_studies.strategies import Strategy, check_strategy
from orchestration.engine_hooks import plan_scenario
from orchestration.ida_study.ida_config import IdaSpec, LoadedIda
from orchestration.ida_study.intensity import measure
from orchestration.ida_study.suites import (
    SuiteRecord,
    Window,
    choose_window,
    load_suite,
    record_csv,
    stop_time,
    windowed,
)
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.scenario import load_scenario
from orchestration.master.yaml_source import load_tree

# The IDA records the case study's variables and the floors' velocities (the residual drift needs them).
IDA_RECORDED = (*RECORDED, "building.v_1", "building.v_2", "building.v_3")
OUTPUTS_OVERRIDE = "outputs=[" + ", ".join(IDA_RECORDED) + "]"


@dataclass
class RecordComponent:
    """One record component of the suite as the study plays it (not a unit of the co-simulation)."""

    rec: SuiteRecord
    window: Window
    stop_time_s: float
    im: float  # intensity of the windowed component at scale 1 [g]
    csv: Path  # staged record file


@dataclass
class PreparedIda:
    """Everything checked, every run planned: nothing is left that could be a configuration error."""

    study: LoadedIda
    components: list[RecordComponent]
    strategies: dict[str, tuple[str, ...]]
    period_s: float | None
    plans: dict[tuple[str, str], PortablePlan]
    masses: list[float]
    gains: dict[str, Any] | None
    staging: Path
    planning_s: float = 0.0
    notes: list[str] = field(default_factory=list)
    storeys: dict[str, list[float]] | None = None  # a ShearBuilding's k, c, P/h per storey (residual drift)
    gain_sets: dict[str, dict[str, Any]] = field(default_factory=dict)  # gain set -> gains document (those used)
    unlimited: list[str] = field(default_factory=list)  # strategies whose controller FMU has no i_max
    named: dict[str, Strategy] = field(default_factory=dict)  # the strategies that are entries (not {name, overrides})

    def cleanup(self) -> None:
        shutil.rmtree(self.staging, ignore_errors=True)


def _masses(plan: Any) -> list[float]:
    m = list(BuildingParams.dyke().m)
    for name, value in plan.parameters.get("building", {}).items():
        kind, _, j = name.partition("_")
        if kind == "m" and j.isdigit():
            while len(m) <= int(j):
                m.append(m[-1])
            m[int(j)] = float(value)
    return m


def storey_constants(plan: Any) -> dict[str, list[float]] | None:
    """k_j [N/m], c_j [N s/m] and pdelta_j = P_j/h_j [N/m] of storeys 1..n when the building unit is a ShearBuilding
    (it has parameters k_j, c_j: start values, with the scenario's values over them); None for another unit."""
    desc = plan.descriptions.get("building")
    if desc is None or "k_1" not in desc.variables or "c_1" not in desc.variables:
        return None
    values = {name: v.start for name, v in desc.variables.items() if v.causality == "parameter"}
    values.update(plan.parameters.get("building", {}))

    def number(name: str) -> float:
        return float(values.get(name) or 0.0)

    n = 0
    while f"k_{n + 1}" in desc.variables:
        n += 1
    k = [number(f"k_{j}") for j in range(1, n + 1)]
    c = [number(f"c_{j}") for j in range(1, n + 1)]
    m = [number(f"m_{j}") for j in range(0, n + 1)]
    pdelta = [0.0] * n
    if str(values.get("p_delta", "false")).lower() in ("true", "1"):
        g = 9.80665  # [m/s^2], as the unit
        pdelta = [g * sum(m[j:]) / number(f"h_{j}") if number(f"h_{j}") > 0 else 0.0 for j in range(1, n + 1)]
    return {"k": k, "c": c, "pdelta": pdelta}


def _suite(path: Path, spec: IdaSpec | None, raw: Any, problems: list[Problem], base: Path | None = None
           ) -> list[SuiteRecord]:
    """The suite's records (problems appended); without a spec, a folder suite and the file's kind are checked."""
    if spec is not None:
        suite = spec.suite if isinstance(spec.suite, str) else spec.suite.model_dump()
        records, found = load_suite(suite, base or path.parent)
        problems += found
        return records
    if isinstance(raw, dict):
        if isinstance(raw.get("suite"), dict) and isinstance(raw["suite"].get("folder"), str):
            _, found = load_suite(raw["suite"], path.parent)
            problems += found
        for key, tool in (("records", "study.py"), ("units", "run.py")):
            if key in raw:
                problems.append(Problem(f"this looks like a file for {tool} (it has '{key}'), not an IDA study",
                                        key, str(path)))
    return []


def _chosen_events(records: list[SuiteRecord], events: list[str] | None, loaded: LoadedIda,
                   problems: list[Problem]) -> list[SuiteRecord]:
    """The components of the records (events) ``events`` names, both components of each (every one for None);
    an unknown name is a problem at its key."""
    if events is None or not records:
        return records
    known = list(dict.fromkeys(r.record for r in records))
    for k, name in enumerate(events):
        if name not in known:
            file, line = loaded.lines.get(("events", k)) or loaded.lines.get(("events",), (str(loaded.path), None))
            problems.append(Problem(f"unknown record {name!r} (the suite's: {', '.join(known)})", f"events.{k}",
                                    file, line))
    return [r for r in records if r.record in events]


def _gain_sets(loaded: LoadedIda, used: set[str | None], problems: list[Problem]) -> dict[str, dict[str, Any]]:
    """Gain set (``sosm``, ``sosm-fig15``) the named strategies use -> its gains file's document (problems
    appended: a missing or invalid file, gains tuned for another current limit)."""
    spec = loaded.spec
    docs: dict[str, dict[str, Any]] = {}
    for gain_set, key in (("sosm", "gains"), ("sosm-fig15", "fig15_gains")):
        if gain_set not in used:
            continue
        try:
            gains, docs[gain_set] = read_gains(loaded.resolve(getattr(spec, key), key))
        except ScenarioError as exc:
            problems += exc.problems
            continue
        if gain_set == "sosm" and abs(gains.i_max - spec.i_max) > 1e-12:
            problems.append(Problem(f"gains tuned for i_max = {gains.i_max} A, the study uses {spec.i_max} A: "
                                    "re-run the tuning", "gains"))
        elif gain_set == "sosm-fig15" and gains.i_max > spec.i_max + 1e-12:
            problems.append(Problem(f"the sosm-fig15 gains limit the controller to {gains.i_max} A, above the "
                                    f"study's i_max = {spec.i_max} A", key))
    return docs


def run_commons(common: tuple[str, ...], strategies: dict[str, tuple[str, ...]], named: dict[str, Strategy]
                ) -> dict[str, tuple[str, ...]]:
    """Strategy -> the overrides every run of it gets first: ``common``, its current limit set on a strategy entry's
    own limit parameter or left out for a controller FMU without one (:meth:`Strategy.common`: a user's own; its
    limit is its own business); a ``{name, overrides}`` strategy gets ``common`` as it is."""
    return {s: named[s].common(common) if s in named else common for s in strategies}


def _strategies(loaded: LoadedIda, scenario: Path, common: tuple[str, ...], problems: list[Problem]
                ) -> tuple[dict[str, tuple[str, ...]], dict[str, dict[str, Any]], set[str], dict[str, Strategy]]:
    """Strategy -> scenario overrides, gain set -> its gains document (those the strategies use), the
    strategies whose controller FMU has no current limit (:func:`run_commons`) and the named strategies' entries.

    A named strategy is an entry of the strategy files, as in the case study
    (:mod:`orchestration.building_studies.strategies`): the controller FMU, its parameters, its gain set and its
    connections become overrides of the system scenario. An entry with its own FMU or connections is checked
    on the scenario first, so a missing FMU or a connection to a variable it lacks is a problem at the entry's
    own key and line. ``{name, overrides}`` strategies are taken as written.
    """
    spec = loaded.spec
    found = loaded.strategy_problems()
    if found:
        problems += found
        return {}, {}, set(), {}
    named = {s: loaded.library[s] for s in spec.strategies if isinstance(s, str)}
    docs = _gain_sets(loaded, {st.entry.gains for st in named.values()}, problems)
    try:
        connections = list(load_tree(scenario)[0].get("connections") or [])
    except ScenarioError:  # an unreadable scenario: prepare_ida reports it (load_scenario)
        return {}, docs, set(), {}
    strategies: dict[str, tuple[str, ...]] = {}
    unlimited = {s for s, st in named.items() if st.limit_parameter() is None}
    for s in spec.strategies:
        if not isinstance(s, str):
            strategies[s.name] = tuple(s.overrides)
            continue
        st = named[s]
        if st.entry.gains is not None and st.entry.gains not in docs:
            continue  # its gains file is a problem already
        gains = docs[st.entry.gains]["gains"] if st.entry.gains is not None else None
        try:
            if st.entry.fmu is not None or st.entry.connections is not None:
                check_strategy(st, scenario, (*common, "simulation.stop_time=1.0"), spec.i_max, gains, None)
            strategies[s] = (*st.overrides(spec.i_max, gains, None), *st.wiring_overrides(connections))
        except ScenarioError as exc:  # a problem the entry did not write (the scenario's) still names the strategy
            problems += [p if "(strategy " in p.message else Problem(f"{p.message} (strategy {s!r})", p.key, p.file,
                                                                     p.line) for p in exc.problems]
    return strategies, docs, unlimited, named


def _stage(records: list[SuiteRecord], spec: IdaSpec, step: float, staging: Path) -> list[RecordComponent]:
    """Each record cut to its window, written to ``staging/records/<id>.csv``; intensities still unknown (nan)."""
    (staging / "records").mkdir()
    components = []
    for rec in records:
        window = choose_window(rec, spec.window.strong_motion)
        played = windowed(rec, window)
        csv = staging / "records" / f"{rec.id}.csv"
        csv.write_text(record_csv(played, f"{rec.source}\nwindow {window.start:.3f}-{window.end:.3f} s of the "
                                          f"record, shifted to t = 0 (strong motion: {spec.window.strong_motion})"))
        components.append(RecordComponent(rec, window, stop_time(window, spec.time_scale, spec.window.tail_s, step),
                                          math.nan, csv))
    return components


def _plans(components: list[RecordComponent], strategies: dict[str, tuple[str, ...]], scenario: Path,
           commons: dict[str, tuple[str, ...]], outputs: dict[str, str], problems: list[Problem]
           ) -> dict[tuple[str, str], PortablePlan]:
    """(component id, strategy) -> checked portable plan (``commons``: each strategy's first overrides; ``outputs``:
    its recorded variables); a strategy's problems are reported once."""
    plans: dict[tuple[str, str], PortablePlan] = {}
    failing: set[str] = set()
    for c in components:
        for name, extra in strategies.items():
            if name in failing:
                continue
            try:
                plan = plan_scenario(scenario, (*commons[name], *extra, f"ground.record=!record {c.csv}",
                                                f"simulation.stop_time={c.stop_time_s!r}", outputs[name]))
            except ScenarioError as exc:
                failing.add(name)
                problems += [Problem(f"strategy {name}: {p.message}", p.key, p.file, p.line) for p in exc.problems]
                continue
            plans[(c.rec.id, name)] = portable(plan)
    return plans


def _measure(components: list[RecordComponent], spec: IdaSpec, first: Any, problems: list[Problem]) -> float | None:
    """Each component's intensity at scale 1 (set in place); returns the period of Sa [s] (None for PGA)."""
    intensity = spec.intensity
    period = intensity.period_s
    if intensity.measure == "sa" and period is None:
        try:
            setup = system_setup(first, 0.0)
        except (NotMonolithic, KeyError) as exc:
            raise ScenarioError(Problem(f"the isolated period cannot be computed for this system ({exc}): "
                                        "give intensity.period_s", "intensity.period_s")) from None
        period = isolated_period(setup.building, setup.coeffs, setup.n_isolators, intensity.period_current_A,
                                 intensity.period_displacement_m)
    for c in components:
        c.im = measure(windowed(c.rec, c.window), intensity.measure, spec.time_scale, period, intensity.damping)
        if not (math.isfinite(c.im) and c.im > 0):
            problems.append(Problem(f"record {c.rec.id} has no motion ({intensity.measure} = {c.im})", "suite"))
    return period


def prepare_ida(path: Path, loaded: LoadedIda | None, problems: list[Problem], raw: Any) -> PreparedIda:
    """Check the whole study and plan every run; ScenarioError listing every problem (nothing computed).

    ``path`` is the study file, ``problems`` those found reading it (``loaded`` is None then)
    and ``raw`` its data: a folder suite is checked even when other keys are wrong.
    """
    started = time.perf_counter()
    problems = list(problems)
    spec = loaded.spec if loaded is not None else None
    records = _suite(path, spec, raw, problems, loaded.base_dir("suite", "folder") if loaded is not None else None)
    if spec is None or loaded is None:
        raise ScenarioError(problems)
    records = _chosen_events(records, spec.events, loaded, problems)
    scenario = loaded.resolve(spec.scenario, "scenario")
    common = (*spec.overrides, f"isolator.i_max={spec.i_max!r}", f"controller.i_max={spec.i_max!r}",
              f"ground.time_scale={spec.time_scale!r}")
    strategies, gain_sets, unlimited, named = _strategies(loaded, scenario, common, problems)
    step = None
    try:
        loaded_scenario = load_scenario(scenario, (*common, "simulation.stop_time=1.0")).scenario
        sim = loaded_scenario.simulation
        # every run's span is a whole number of the coarsest period, so that each unit's own step (units.X.step,
        # e.g. a controller sampling at 1 ms over a 0.25 ms plant) ends on stop_time
        multiples = [round(u.step / sim.step) for u in loaded_scenario.units.values() if u.step is not None]
        step = sim.step * math.lcm(1, *multiples)  # output_interval/format: an IDA run keeps no time series
    except ScenarioError as exc:
        problems += exc.problems
    if problems or not records or step is None:
        raise ScenarioError(problems or [Problem("the suite has no record", "suite")])
    staging = Path(tempfile.mkdtemp(prefix="mre-cosim-ida-"))
    try:
        components = _stage(records, spec, step, staging)
        outputs = {s: named[s].recorded(OUTPUTS_OVERRIDE) if s in named else OUTPUTS_OVERRIDE for s in strategies}
        plans = _plans(components, strategies, scenario, run_commons(common, strategies, named), outputs, problems)
        if problems:
            raise ScenarioError(problems)
        first = plans[(components[0].rec.id, next(iter(strategies)))].plan
        period = _measure(components, spec, first, problems)
        if problems:
            raise ScenarioError(problems)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    masses = _masses(first)
    if spec.storey_heights is not None and len(spec.storey_heights) != len(masses) - 1:
        shutil.rmtree(staging, ignore_errors=True)
        raise ScenarioError(Problem(f"storey_heights gives {len(spec.storey_heights)} heights, the building has "
                                    f"{len(masses) - 1} storeys", "storey_heights"))
    return PreparedIda(loaded, components, strategies, period, plans, masses, gain_sets.get("sosm"), staging,
                       time.perf_counter() - started, storeys=storey_constants(first),
                       gain_sets=gain_sets, unlimited=sorted(unlimited), named=named)
