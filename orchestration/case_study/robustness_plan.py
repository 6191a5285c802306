"""A robustness variant turned into scenario overrides of one record x strategy run.

The overrides come after the study's and the strategy's (:func:`case_plan.run_strategy_overrides`):

* ``plant``: ``units.<unit>.fmu=<path>``; with parameters, ``units.<unit>.parameters=<json>`` (replacing the
  unit's) and the study's overrides of that unit again (its current limit). The unit must be in the record's
  scenario and the swap must change it;
* ``scale``: ``<unit>.<parameter>=<factor x nominal>``, the nominal value read from the record's scenario
  planned with the variant's plant (its parameter, else the FMU's start value), which must not be 0;
* ``sensors``: a ``SensorChannels`` unit named ``sensors``; every connection into the controller
  ``src -> controller.in`` becomes ``src -> sensors.u_<q>_<k>`` (``delayed`` when the delay is >= 1,
  so the unit stores the sample at each communication point; plain with no delay, so its output is
  re-evaluated with the end-of-step value and the chain is an exact pass-through without noise) and
  ``sensors.y_<q>_<k> -> controller.in`` (as the original was, ``delayed``). The channel's quantity
  ``q`` follows the SI unit the source variable declares (m, m/s, m/s2, N);
* ``set``: ``<unit>.<parameter>=<value>``, a Real parameter of the planned plant (the sampled plants');
* ``current_lag`` > 0: a ``CurrentLag`` unit named ``current_lag``: ``controller.i -> current_lag.i_cmd``
  and ``current_lag.i -> <every former target of controller.i>`` (in series with a scenario's own coil lag;
  that one is varied by ``scale``).

The controller unit keeps its own parameters: a variant that names it is refused.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mre_common.fs_limits import path_problem
from orchestration.building_studies.strategies import COMMAND, CONTROLLER
from orchestration.case_study.case_config import LoadedStudy, variant_strategies
from orchestration.case_study.robustness_config import PlantUnit, VariantSpec
from orchestration.engine_hooks import PROJECT_DIR as PROJECT
from orchestration.engine_hooks import plan_scenario
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.yaml_source import dotted, load_tree

SENSORS, LAG = "sensors", "current_lag"  # the units a variant inserts
QUANTITY = {"m": "disp", "m/s": "vel", "m/s2": "acc", "N": "force"}  # SI unit -> channel quantity
CHANNELS = {"disp": 2, "vel": 2, "acc": 6, "force": 2}  # channels of the SensorChannels unit per quantity
NOMINAL = "nominal"  # the variant name of the study's own runs in robustness.csv


def variants(study: LoadedStudy) -> dict[str, VariantSpec]:
    """The study's variants by name, the sampled plants' last (empty without a robustness section)."""
    from orchestration.case_study.plant_uncertainty import sampled_variants

    rob = study.spec.robustness
    return {} if rob is None else {**rob.variants, **sampled_variants(study)}


def _key(name: str, *key: Any) -> tuple[Any, ...]:
    return ("robustness", "variants", name, *key)


def problem(study: LoadedStudy, message: str, name: str, *key: Any) -> Problem:
    """A problem located at a key of variant ``name`` (the nearest line written)."""
    path = _key(name, *key)
    for k in range(len(path), -1, -1):
        hit = study.lines.get(path[:k])
        if hit is not None:
            return Problem(f"robustness variant {name!r}: {message}", dotted(path), hit[0], hit[1])
    return Problem(f"robustness variant {name!r}: {message}", dotted(path), str(study.path))


def _path(study: LoadedStudy, text: str, *key: Any) -> Path:
    p = Path(text)
    return p if p.is_absolute() else (study.base_dir(*key) / p).resolve()


def unit_fmu(study: LoadedStudy, which: str) -> Path:
    """The SensorChannels (``which`` = sensors_fmu) or CurrentLag (lag_fmu) FMU, absolute."""
    rob = study.spec.robustness
    assert rob is not None
    if ("robustness", which) not in study.lines:  # the default: the project's own FMU folder
        return (PROJECT / "fmus" / Path(getattr(rob, which)).name).resolve()
    return _path(study, getattr(rob, which), "robustness", which)


def _as_dict(connection: Any) -> dict[str, Any]:
    """A connection as ``{source, target[, delayed]}``."""
    if isinstance(connection, dict):
        return dict(connection)
    source, _, target = str(connection).partition("->")
    return {"source": source.strip(), "target": target.strip()}


def _unit(port: str) -> str:
    return str(port).strip().split(".")[0]


def _plant_fmu(study: LoadedStudy, name: str, unit: str) -> Path:
    """The FMU file of a variant's swap of ``unit``, absolute."""
    entry = variants(study)[name].plant[unit]
    if isinstance(entry, PlantUnit):
        return _path(study, entry.fmu, *_key(name, "plant", unit, "fmu"))
    return _path(study, entry, *_key(name, "plant", unit))


def plant_overrides(study: LoadedStudy, name: str, base: tuple[str, ...] = ()) -> tuple[str, ...]:
    """``units.<unit>.fmu=...`` of the variant's plant swaps; for a swap with its parameters,
    ``units.<unit>.parameters={...}`` and then the ``base`` overrides of that unit's parameters again (the study's
    current limit)."""
    out = []
    for u, entry in variants(study)[name].plant.items():
        out.append(f"units.{u}.fmu={_plant_fmu(study, name, u)}")
        if isinstance(entry, PlantUnit):
            out.append(f"units.{u}.parameters={json.dumps(entry.parameters)}")
            out += [o for o in base if o.partition("=")[0].strip().split(".")[0] == u
                    and o.partition("=")[0].count(".") == 1]
    return tuple(out)


def _fmu_file_problem(path: Path) -> str | None:
    """Why ``path`` cannot be a plant's FMU file (beyond the file system's limits, missing, not a file), or None."""
    text = path_problem(path)
    if text is not None:
        return f"FMU file: {text}"
    try:
        return None if path.is_file() else f"FMU file {path} does not exist or is not a regular file"
    except OSError as exc:
        return f"FMU file {path}: {exc.strerror or exc}"


class VariantPlanner:
    """Overrides of every run of a study's variants; nominal values and units read once per record and variant."""

    def __init__(self, study: LoadedStudy, base: tuple[str, ...]) -> None:
        self.study, self.base = study, base
        self._plans: dict[tuple[str, str], Any] = {}
        self._trees: dict[str, dict[str, Any]] = {}

    def _tree(self, record: str) -> dict[str, Any]:
        """The record's scenario file as read (units, connections), once per record."""
        if record not in self._trees:
            self._trees[record] = load_tree(self.study.scenario_path(record))[0]
        return self._trees[record]

    def _plan(self, record: str, name: str | None) -> Any:
        """The record's scenario planned with the study's overrides and the variant's plant (its descriptions);
        ``name`` None: the nominal plant."""
        key = (record, name or "")
        if key not in self._plans and name is None:
            self._plans[key] = plan_scenario(self.study.scenario_path(record), self.base)
        if key not in self._plans:
            self._plans[key] = plan_scenario(self.study.scenario_path(record),
                                             (*self.base, *plant_overrides(self.study, name, self.base)))
        return self._plans[key]

    def static_problems(self, name: str) -> list[Problem]:
        """Problems of a variant that need no scenario: controller named, FMU files missing, unit names taken."""
        study, spec = self.study, variants(self.study)[name]
        out = []
        for u in spec.plant:
            if u == CONTROLLER:
                out.append(problem(study, "the controller cannot be swapped (a variant changes the plant, the "
                                          "controller keeps its nominal design)", name, "plant", u))
            else:
                text = _fmu_file_problem(_plant_fmu(study, name, u))
                if text is not None:
                    out.append(problem(study, text, name, "plant", u))
        for key in ("scale", "set"):
            for k in getattr(spec, key):
                if _unit(k) == CONTROLLER:
                    out.append(problem(study, f"{key} applies to the plant only: the controller keeps its nominal "
                                              "model parameters", name, key, k))
        return out

    def overrides(self, record: str, name: str, strategy_overrides: tuple[str, ...]) -> tuple[str, ...]:
        """The overrides of the variant on one run (after the study's and the strategy's); ScenarioError if it
        cannot be applied (a parameter or signal the plant lacks, a signal without its noise RMS, ...)."""
        study, spec = self.study, variants(self.study)[name]
        problems: list[Problem] = []
        out = list(plant_overrides(study, name, self.base))
        nominal = self._plan(record, None)
        missing = [problem(study, f"{record}: the scenario has no unit {u!r} (units: "
                                  f"{', '.join(sorted(nominal.descriptions))}): the swap would change nothing",
                           name, "plant", u) for u in spec.plant if u not in nominal.descriptions]
        if missing:  # before planning the swap: a unit of its own would not even be connected
            raise ScenarioError(missing)
        plan = self._plan(record, name)
        for u, entry in spec.plant.items():
            if (Path(nominal.fmu_paths[u]).resolve() == _plant_fmu(study, name, u)
                  and (not isinstance(entry, PlantUnit) or plan.parameters.get(u) == nominal.parameters.get(u))):
                problems.append(problem(study, f"{record}: {u} is that FMU already, with the same parameters: the "
                                               "swap would change nothing", name, "plant", u))
        out += self._parameters(record, name, plan, problems)
        units = self._tree(record).get("units") or {}
        conns = self._connections(record, strategy_overrides)
        if spec.sensors is not None or spec.current_lag:
            taken = [u for u in (SENSORS, LAG) if u in units]
            if taken:
                problems.append(problem(study, f"{record}: the scenario has a unit named {taken[0]!r} already", name))
        if spec.sensors is not None:
            conns = self._sensors(record, name, conns, plan, out, problems)
        if spec.current_lag:
            conns = self._lag(record, name, conns, out, problems, _command(strategy_overrides))
        if problems:
            raise ScenarioError(problems)
        if spec.sensors is not None or spec.current_lag:
            out.append(f"connections={json.dumps(conns)}")
        return tuple(out)

    def _parameters(self, record: str, name: str, plan: Any, problems: list[Problem]) -> list[str]:
        """The ``scale`` and ``set`` overrides of a variant on the planned plant (problems appended)."""
        study, spec = self.study, variants(self.study)[name]
        out: list[str] = []
        for key, items in (("scale", spec.scale), ("set", spec.set)):
            for k, number in items.items():
                unit, _, param = k.partition(".")
                desc = plan.descriptions.get(unit)
                var = desc.variables.get(param) if desc is not None else None
                if var is None or var.causality != "parameter" or var.type != "Real":
                    problems.append(problem(study, f"{record}: the plant has no Real parameter {k}", name, key, k))
                    continue
                if key == "set":
                    out.append(f"{k}={number!r}")
                    continue
                nominal = plan.parameters.get(unit, {}).get(param, var.start)
                try:
                    value = float(nominal) * number
                except (TypeError, ValueError):
                    problems.append(problem(study, f"{record}: {k} has no numeric nominal value ({nominal!r})", name,
                                            "scale", k))
                    continue
                if value == 0:
                    problems.append(problem(study, f"{record}: {k} is 0 on the nominal plant: scaling it changes "
                                                   "nothing", name, "scale", k))
                    continue
                out.append(f"{k}={value!r}")
        return out

    def _connections(self, record: str, strategy_overrides: tuple[str, ...]) -> list[dict[str, Any]]:
        """The run's connections: the strategy's ``connections=`` override if any, else the scenario's."""
        for o in reversed(strategy_overrides):
            if o.startswith("connections="):
                return [_as_dict(c) for c in json.loads(o.partition("=")[2])]
        return [_as_dict(c) for c in self._tree(record).get("connections") or []]

    def _sensors(self, record: str, name: str, conns: list[dict[str, Any]], plan: Any, out: list[str],
                 problems: list[Problem]) -> list[dict[str, Any]]:
        study, sensors = self.study, variants(self.study)[name].sensors
        assert sensors is not None
        out += [f"units.{SENSORS}.fmu={unit_fmu(study, 'sensors_fmu')}",
                f"units.{SENSORS}.parameters.delay={sensors.delay}", f"units.{SENSORS}.parameters.seed={sensors.seed}"]
        step = (self._tree(record).get("units") or {}).get(CONTROLLER, {}).get("step")
        if step is not None:  # the delay is counted in the sensors' own steps: they sample as the controller does
            out.append(f"units.{SENSORS}.step={step!r}")
        used = dict.fromkeys(CHANNELS, 0)
        channel: dict[str, str] = {}  # source port -> channel
        new = []
        for c in conns:
            if _unit(c["target"]) != CONTROLLER:
                new.append(c)
                continue
            src = str(c["source"]).strip()
            if src not in channel:
                unit, _, var = src.partition(".")
                desc = plan.descriptions.get(unit)
                v = desc.variables.get(var) if desc is not None else None
                q = QUANTITY.get(v.unit if v is not None else None)
                if q is None:
                    problems.append(problem(study, f"{record}: the controller reads {src}, whose unit "
                                                   f"({v.unit if v is not None else 'unknown'}) has no sensor "
                                                   f"channel (channels: {', '.join(QUANTITY)})", name, "sensors"))
                    continue
                used[q] += 1
                if used[q] > CHANNELS[q]:
                    problems.append(problem(study, f"{record}: more than {CHANNELS[q]} {q} signals into the controller",
                                            name, "sensors"))
                    continue
                channel[src] = ch = f"{q}_{used[q]}"
                if sensors.noise_rms and src not in sensors.noise_rms:
                    problems.append(problem(study, f"{record}: no noise RMS for {src}, which the controller reads "
                                                   "(every measured signal needs one)", name, "sensors", "noise_rms"))
                    continue
                rms = float(sensors.noise_rms.get(src, 0.0))
                out.append(f"units.{SENSORS}.parameters.rms_{ch}={rms!r}")
                link: dict[str, Any] = {"source": src, "target": f"{SENSORS}.u_{ch}"}
                if sensors.delay >= 1:
                    link["delayed"] = True
                new.append(link)
            if src in channel:
                into = {"source": f"{SENSORS}.y_{channel[src]}", "target": c["target"]}
                if c.get("delayed"):
                    into["delayed"] = True
                new.append(into)
        return new

    def _lag(self, record: str, name: str, conns: list[dict[str, Any]], out: list[str], problems: list[Problem],
             command: str) -> list[dict[str, Any]]:
        study, tau = self.study, variants(self.study)[name].current_lag
        out += [f"units.{LAG}.fmu={unit_fmu(study, 'lag_fmu')}", f"units.{LAG}.parameters.tau={float(tau)!r}"]
        new = [c for c in conns if str(c["source"]).strip() != command]
        targets = [c for c in conns if str(c["source"]).strip() == command]
        if not targets:
            problems.append(problem(study, f"{record}: no connection from {command} to lag", name, "current_lag"))
            return conns
        new.append({"source": command, "target": f"{LAG}.i_cmd"})
        for c in targets:
            new.append({**c, "source": f"{LAG}.i"})
        return new


def _command(strategy_overrides: tuple[str, ...]) -> str:
    """The controller's current-command output in a run: the strategy's ``report.current=`` if any, else ours."""
    for o in reversed(strategy_overrides):
        if o.startswith("report.current="):
            return o.partition("=")[2].strip()
    return f"{CONTROLLER}.{COMMAND}"


def check_variants(study: LoadedStudy, base: tuple[str, ...], sets: dict[str, dict[str, Any]],
                   run_strategy_overrides: Callable[..., tuple[str, ...]]) -> None:
    """Every variant on every record x strategy planned through the engine's checks before anything is written;
    one ScenarioError with every problem, each naming the variant's key and line (or the strategy's).

    ``run_strategy_overrides``: :func:`case_plan.run_strategy_overrides` (the strategy's part of a run)."""
    names = variants(study)
    if not names:
        return
    planner = VariantPlanner(study, base)
    problems = [p for name in names for p in planner.static_problems(name)]
    if problems:
        raise ScenarioError(problems)
    spec = study.spec
    for name in names:
        for r in spec.records:
            path = study.scenario_path(r)
            for s in variant_strategies(spec):
                strategy = study.strategy(s)
                if strategy.needs_sweep:  # its current is known after the sweep; checked with its unit's others
                    continue
                g = sets[strategy.entry.gains]["gains"] if strategy.entry.gains in sets else None
                try:
                    extra = run_strategy_overrides(study, s, path, spec.i_max, g, 0.0)
                    plan_scenario(path, (*strategy.common(base), *extra, *planner.overrides(r, name, extra)))
                except ScenarioError as exc:
                    new = [p if p.message.startswith("robustness variant") else
                           Problem(f"robustness variant {name!r}, {r}, strategy {s!r}: {p.message}", p.key, p.file,
                                   p.line) for p in exc.problems]
                    problems += [p for p in new if p not in problems]
    if problems:
        raise ScenarioError(problems)
