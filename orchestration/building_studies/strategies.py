"""The control strategies of the studies: entries of a strategy file, turned into scenario overrides.

A strategy is an entry of ``scenarios/strategies.yaml`` (shipped; a study may add files with
``strategy_files`` or entries with ``strategy_definitions``): a controller FMU (or none: the
record scenario's own controller unit), its parameters, its sensor connections, a gain set and
a label. The built-in ones:

| strategy | controller unit |
|---|---|
| ``passive-off`` | constant 0 A (``controller.mode=passive``) |
| ``passive-on`` | constant i_max |
| ``best-constant`` | the constant current chosen by the case study's sweep |
| ``sosm`` | the SOSM controller with the tuned gains (``scenarios/sosm_gains.yaml``) |
| ``sosm-fig15`` | SOSM, second gain set: own limit (2.5 A), release band s_release (not in the paper) |
| ``on-off`` | the ``SwitchingCurrentController`` FMU: i_max while the base moves away from 0, else 0 |
| ``clipped-optimal`` | ``ClippedOptimalCurrentController``, Dyke's clipping (Dyke et al. 1996) |
| ``clipped-optimal-inverse`` | the same, current from the inverse of Eq. 17 |
| ``lyapunov`` | ``LyapunovCurrentController`` (after Jansen & Dyke 2000) |
| ``frequency`` | ``FrequencyCurrentController`` (after Gu et al. 2015) |

An entry may declare ``tunable:``, FMU parameter -> range (``{low, high, scale: log|linear}``), the space the
strategy tuner (:mod:`orchestration.case_study.strategy_tuner`) searches; a range that is empty, inverted, not
finite, or log through zero is refused when the file is read, a parameter the FMU lacks by :func:`tunable_problems`.
A tuned entry (written by that tuner) says what it was tuned on under ``tuned:``.

Problems (unknown strategy, missing FMU, a connection to a variable a unit lacks) are
ScenarioErrors naming the file, line and key of the strategy entry; :func:`check_strategy`
runs the engine's own checks (:func:`orchestration.engine_hooks.resolve_scenario`) on the
record scenario with the strategy applied.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError, field_validator, model_validator

from orchestration.building_report import REPORT
from orchestration.engine_hooks import PROJECT_DIR as PROJECT
from orchestration.engine_hooks import resolve_scenario
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.scenario import validate_scenario, validation_problems
from orchestration.master.unit import UnitDescription
from orchestration.master.unit_check import warn_once
from orchestration.master.yaml_source import Lines, apply_override, dotted, load_tree
from orchestration.roles import check_variable, read_unit

SHIPPED = PROJECT / "scenarios" / "strategies.yaml"
CONTROLLER = "controller"  # the unit a strategy replaces
COMMAND, LIMIT = "i", "i_max"  # our controllers' names for the current command and its limit (orchestration.roles)
LIMIT_OVERRIDE = f"{CONTROLLER}.{LIMIT}="  # the studies' override of the controller's current limit
I_MAX, BEST = "${i_max}", "${best_current}"  # placeholders in parameter values


class TunableRange(BaseModel):
    """The range a tuner searches for one FMU parameter, in the parameter's own unit: ``scale`` log (low > 0) or
    linear; empty, inverted and non-finite ranges are refused."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    low: float
    high: float
    scale: Literal["log", "linear"] = "linear"

    @model_validator(mode="after")
    def _check(self) -> TunableRange:
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            raise ValueError(f"a tunable range needs finite low and high, got low = {self.low!r}, high = {self.high!r}")
        if self.low == self.high:
            raise ValueError(f"the tunable range is empty: low = high = {self.low!r}")
        if self.low > self.high:
            raise ValueError(f"the tunable range is inverted: low = {self.low!r} > high = {self.high!r}")
        if self.scale == "log" and self.low <= 0:
            raise ValueError(f"a log range must lie above 0, got low = {self.low!r} (use scale: linear, or low > 0)")
        return self


LINE_STYLES = ("-", "--", "-.", ":")  # matplotlib's named line styles; or dashes: on/off lengths in line widths
MARKERS = ("o", "s", "^", "v", "<", ">", "D", "d", "P", "X", "p", "h", "H", "8", "*")  # filled matplotlib markers


class StrategyStyle(BaseModel):
    """How the figures draw a strategy: a matplotlib colour, a line (``-``, ``--``, ``-.``, ``:`` or dashes, on/off
    lengths in line widths; ``[]`` solid) and a filled marker. Unset: one by the strategy's place in the study."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    color: str | None = None
    line: str | list[float] | None = None
    marker: str | None = None

    @field_validator("color")
    @classmethod
    def _color(cls, value: str | None) -> str | None:
        from matplotlib.colors import is_color_like

        if value is not None and not is_color_like(value):
            raise ValueError(f"{value!r} is not a matplotlib colour (a name like tab:red, a grey level like '0.3', "
                             "or #rrggbb)")
        return value

    @field_validator("line")
    @classmethod
    def _line(cls, value: str | list[float] | None) -> str | list[float] | None:
        if isinstance(value, str) and value not in LINE_STYLES:
            raise ValueError(f"line must be one of {', '.join(LINE_STYLES)} or dashes (on/off lengths), got {value!r}")
        if isinstance(value, list) and (len(value) % 2 or len(value) > 16 or
                                        not all(math.isfinite(v) and v > 0 for v in value)):
            raise ValueError(f"dashes are pairs of positive on/off lengths (at most 8 pairs), got {value!r}")
        return value

    @field_validator("marker")
    @classmethod
    def _marker(cls, value: str | None) -> str | None:
        if value is not None and value not in MARKERS:
            raise ValueError(f"marker must be one of {' '.join(MARKERS)}, got {value!r}")
        return value


class StrategyEntry(BaseModel):
    """One strategy as written in a strategy file (``fmu`` relative to that file).

    Besides the controller, an entry says what a study does with it (no strategy's name means anything to the
    code): ``uncontrolled`` marks the uncontrolled case (the indices J, the objectives of the sweep and the tuners,
    the IDA's and the suite benchmark's criteria are over its runs; a study lists exactly one); ``radau_reference``
    a constant current the case study checks against the monolithic Radau solution; ``paper_figures`` its part in
    the paper's figures and claims (``controlled``: Fig. 15's current, Fig. 16, the claims checked and the verdict
    per record; ``passive``: drawn beside it in Fig. 16); a parameter set to ``${best_current}`` makes it need the
    case study's constant-current sweep (:attr:`Strategy.needs_sweep`); ``style`` its line in the figures.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    label: str = ""
    fmu: str | None = None  # None: the record scenario's controller unit
    parameters: dict[str, Any] = Field(default_factory=dict)
    gains: Literal["sosm", "sosm-fig15"] | None = None  # the study's gain set: lambda, rho, zeta, theta, s_release
    gains_limit: bool = False  # the gain set's i_max limits the controller
    connections: list[Any] | None = None  # replace the scenario's connections into the controller
    current: str = COMMAND  # the controller output that is its current command [A] (the role's ``i``)
    limit: str | None = None  # the parameter the study's current limit sets [A]; None: i_max where the FMU has it
    tunable: dict[str, TunableRange] = Field(default_factory=dict)  # FMU parameter -> the range the tuner searches
    tuned: dict[str, Any] | None = None  # a tuned entry: what it was tuned on (records, objective, budget, seed, ...)
    uncontrolled: StrictBool = False  # the uncontrolled case: the studies' indices and criteria are over its runs
    radau_reference: StrictBool = False  # its constant current is checked against the monolithic Radau solution
    paper_figures: Literal["controlled", "passive"] | None = None  # its part in the paper's Fig. 15-17 and claims
    style: StrategyStyle | None = None  # how the figures draw it

    @field_validator("tunable")
    @classmethod
    def _parameter_names(cls, value: dict[str, TunableRange]) -> dict[str, TunableRange]:
        for name in value:
            if not name.strip() or name != name.strip() or "\x00" in name or "." in name:
                raise ValueError(f"tunable: {name!r} is not the name of one of the controller FMU's parameters")
        return value

    @field_validator("current", "limit")
    @classmethod
    def _a_variable_name(cls, value: str | None) -> str | None:
        if value is not None and (not value.strip() or value != value.strip() or "\x00" in value or "->" in value):
            raise ValueError(f"must be the name of one of the controller FMU's variables, got {value!r}")
        return value


class StrategyFile(BaseModel):
    """A strategy file: a description and its entries."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    description: str = ""
    strategies: dict[str, StrategyEntry] = Field(default_factory=dict)


@dataclass(frozen=True)
class Strategy:
    """A strategy entry with where it was written (file, lines, key path) for located problems."""

    name: str
    entry: StrategyEntry
    file: Path  # the file it was written in
    lines: Lines  # that file's key lines
    prefix: tuple[Any, ...]  # its key path in that file (``("strategies", name)``)

    @property
    def label(self) -> str:
        """How the report names it."""
        return self.entry.label or self.name

    def where(self, *key: Any) -> tuple[str, int | None]:
        """File and line of a key of the entry (the entry's own line if the key has none)."""
        for k in range(len(key), -1, -1):
            hit = self.lines.get((*self.prefix, *key[:k]))
            if hit is not None:
                return hit
        return str(self.file), None

    def problem(self, message: str, *key: Any) -> Problem:
        """A problem located at a key of the entry."""
        file, line = self.where(*key)
        return Problem(message, dotted((*self.prefix, *key)), file, line)

    @property
    def fmu_path(self) -> Path | None:
        """The controller FMU (absolute), or None: the record scenario's own controller."""
        if self.entry.fmu is None:
            return None
        p = Path(self.entry.fmu)
        file = Path(self.where("fmu")[0])
        return p if p.is_absolute() else (file.parent / p).resolve()

    @property
    def needs_sweep(self) -> bool:
        """Whether a parameter takes the record's best constant current (``${best_current}``): the case study's
        constant-current sweep must run first, and an IDA cannot run it."""
        return any(v == BEST for v in self.entry.parameters.values())

    def flags(self) -> dict[str, Any]:
        """What a study's report needs of the entry once it has run (``study.json``'s ``strategy_flags``)."""
        e = self.entry
        return {"label": self.label, "uncontrolled": e.uncontrolled, "radau_reference": e.radau_reference,
                "paper_figures": e.paper_figures, "needs_sweep": self.needs_sweep, "gains_limit": e.gains_limit,
                "style": e.style.model_dump() if e.style is not None else None}

    @property
    def current_ref(self) -> str:
        """The controller output the runs connect, record and report as the current command."""
        return f"{CONTROLLER}.{self.entry.current}"

    def limit_parameter(self) -> str | None:
        """The controller parameter the study's current limit sets, or None: the FMU has none (it keeps its own).

        ``limit:`` if the entry names one; else ``i_max`` for the record scenario's own controller and for an FMU
        that has it (an FMU that cannot be read is taken to have it: the engine's checks report it).
        """
        if self.entry.limit is not None:
            return self.entry.limit
        if self.fmu_path is None:
            return LIMIT
        variables = fmu_variables(self.fmu_path)
        return LIMIT if variables is None or LIMIT in variables else None

    def common(self, base: tuple[str, ...] | list[str]) -> tuple[str, ...]:
        """The study's overrides of every run (``base``), its current limit set on this controller's own limit
        parameter (:meth:`limit_parameter`), or left out for a controller without one."""
        limit = self.limit_parameter()
        out = []
        for o in base:
            if o.startswith(LIMIT_OVERRIDE):
                if limit is None:
                    continue
                o = f"{CONTROLLER}.{limit}={o[len(LIMIT_OVERRIDE):]}"
            out.append(o)
        return tuple(out)

    def recorded(self, outputs_override: str) -> str:
        """An ``outputs=[...]`` override with our current command replaced by this controller's."""
        return outputs_override.replace(f"{CONTROLLER}.{COMMAND},", f"{self.current_ref},").replace(
            f"{CONTROLLER}.{COMMAND}]", f"{self.current_ref}]")

    def values(self, i_max: float, best: float | None) -> dict[str, Any]:
        """The controller's parameters with the placeholders filled in."""
        return {k: i_max if v == I_MAX else best if v == BEST else v for k, v in self.entry.parameters.items()}

    def constant_current(self, i_max: float, best: float | None) -> float | None:
        """The constant current [A] of a passive strategy (SOSM unit in passive mode), else None."""
        if self.entry.fmu is not None or self.entry.parameters.get("mode") != "passive":
            return None
        v = self.values(i_max, best).get("i_passive", 0.0)
        return None if v is None else float(v)

    def overrides(self, i_max: float, gains: dict[str, float] | None, best: float | None) -> tuple[str, ...]:
        """Scenario overrides for the controller unit: FMU, parameters, then the gain set's gains."""
        out = [f"units.{CONTROLLER}.fmu={self.fmu_path}"] if self.entry.fmu is not None else []
        out += [f"{CONTROLLER}.{k}={_yaml_value(v)}" for k, v in self.values(i_max, best).items()]
        if self.entry.gains is not None:
            if gains is None:
                raise ScenarioError(self.problem(f"no gains for the gain set {self.entry.gains!r}", "gains"))
            out += [f"{CONTROLLER}.{k}={gains[k]!r}" for k in ("lambda", "rho", "zeta", "theta")]
            if self.entry.gains_limit:
                out.append(f"{CONTROLLER}.{self.limit_parameter() or LIMIT}={float(gains['i_max'])!r}")
            if "s_release" in gains:
                out.append(f"{CONTROLLER}.s_release={float(gains['s_release'])!r}")
        return tuple(out)

    def connections(self, scenario_connections: list[Any]) -> list[Any] | None:
        """The run's connections (None: the scenario's, unchanged): those into the controller replaced by the
        entry's, and the scenario's connections from ``controller.i`` made from the entry's ``current``."""
        if self.entry.connections is None and self.entry.current == COMMAND:
            return None
        conns = list(scenario_connections) if self.entry.connections is None else [
            *(c for c in scenario_connections if _target_unit(c) != CONTROLLER), *self.entry.connections]
        return [_from_source(c, f"{CONTROLLER}.{COMMAND}", self.current_ref) for c in conns]

    def wiring_overrides(self, scenario_connections: list[Any]) -> tuple[str, ...]:
        """``connections=[...]`` if the run's connections differ from the scenario's, and the report's current
        role on the entry's ``current`` if it is not ours."""
        conns = self.connections(scenario_connections)
        out = () if conns is None else (f"connections={json.dumps(conns)}",)
        return out if self.entry.current == COMMAND else (*out, f"report.current={self.current_ref}")


def _yaml_value(v: Any) -> str:
    """A parameter value as the text of a ``--set`` override (read back as YAML to the same value)."""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str) and yaml.safe_load(v) == v:
        return v
    return json.dumps(v)


def _from_source(connection: Any, old: str, new: str) -> Any:
    """A connection with source ``old`` made from ``new`` (``a.x -> b.y`` or ``{source, target, ...}``)."""
    if old == new:
        return connection
    if isinstance(connection, dict):
        return {**connection, "source": new} if str(connection.get("source", "")).strip() == old else connection
    if isinstance(connection, str):
        source, arrow, target = connection.partition("->")
        return f"{new} ->{target}" if arrow and source.strip() == old else connection
    return connection


@functools.lru_cache(maxsize=64)
def _variables(path: str, mtime_ns: int) -> frozenset[str] | None:
    try:
        return frozenset(read_unit(Path(path), CONTROLLER).variables)
    except Exception:  # unreadable: the engine's checks say why, at the entry's fmu key
        return None


def fmu_variables(path: Path) -> frozenset[str] | None:
    """The variable names of the FMU at ``path`` (None: no FMU there, or unreadable); cached by file and time."""
    try:
        return _variables(str(path), path.stat().st_mtime_ns)
    except OSError:
        return None


def _target_unit(connection: Any) -> str | None:
    """The unit a connection leads into (``a.x -> b.y`` or ``{source, target}``)."""
    target = connection.get("target") if isinstance(connection, dict) else (
        connection.partition("->")[2] if isinstance(connection, str) else None)
    return str(target).strip().split(".")[0] if target else None


def read_strategy_file(path: Path) -> dict[str, Strategy]:
    """The strategies of a strategy file (its ``extends`` chain merged); ScenarioError if malformed."""
    path = Path(path).resolve()
    if not path.is_file():
        raise ScenarioError(f"strategy file {path} does not exist")
    data, lines = load_tree(path)
    try:
        spec = StrategyFile.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(validation_problems(exc, lines, path, StrategyFile)) from None
    return _checked({name: Strategy(name, entry, path, lines, ("strategies", name))
                    for name, entry in spec.strategies.items()})


def _checked(strategies: dict[str, Strategy]) -> dict[str, Strategy]:
    """``strategies`` if every number of every entry's parameters is finite and no text holds a NUL, else
    ScenarioError naming each one at its key and line: a strategy a study defines but does not list is checked too."""
    problems = []

    def walk(strategy: Strategy, key: tuple[Any, ...], value: Any) -> None:
        if isinstance(value, float) and not math.isfinite(value):
            name = next(k for k in reversed(key) if isinstance(k, str))
            problems.append(strategy.problem(f"{name} must be a finite number, got {value!r} "
                                             f"(strategy {strategy.name!r})", *key))
        elif isinstance(value, str) and "\x00" in value:  # cut short on its way to the C API, or an OS error
            problems.append(strategy.problem(f"{value!r} holds a NUL character (\\0) (strategy {strategy.name!r})",
                                             *key))
        elif isinstance(value, dict):
            for k, v in value.items():
                walk(strategy, (*key, k), v)
        elif isinstance(value, list | tuple):
            for k, v in enumerate(value):
                walk(strategy, (*key, k), v)

    for strategy in strategies.values():
        walk(strategy, ("parameters",), dict(strategy.entry.parameters))
        walk(strategy, ("fmu",), strategy.entry.fmu)
    if problems:
        raise ScenarioError(problems)
    return strategies


def inline_strategies(entries: dict[str, StrategyEntry], path: Path, lines: Lines, key: str
                      ) -> dict[str, Strategy]:
    """Strategies written in a study file under ``key`` (already validated; every number finite, listed or not)."""
    return _checked({name: Strategy(name, entry, path, lines, (key, name)) for name, entry in entries.items()})


def strategy_library(files: list[Path], entries: dict[str, StrategyEntry], path: Path, lines: Lines,
                     key: str = "strategy_definitions") -> dict[str, Strategy]:
    """Every strategy a study may name: the shipped file, then ``files`` (in order), then the study's own
    ``entries`` (under ``key``); a later definition of a name replaces an earlier one."""
    library = read_strategy_file(SHIPPED)
    for file in files:
        library.update(read_strategy_file(file))
    library.update(inline_strategies(entries, path, lines, key))
    return library


def builtin_strategies() -> dict[str, Strategy]:
    """The shipped strategies (``scenarios/strategies.yaml``)."""
    return read_strategy_file(SHIPPED)


def unknown_strategies(names: list[str], known: dict[str, Strategy], lines: Lines, path: Path, key: str
                       ) -> list[Problem]:
    """A located problem for every name in ``names`` (the study's list ``key``, dotted if nested) that is not a
    known strategy."""
    problems = []
    parts = tuple(key.split("."))
    for k, name in enumerate(names):
        if name not in known:
            file, line = lines.get((*parts, k), lines.get(parts, (str(path), None)))
            problems.append(Problem(f"unknown strategy {name!r} (known: {', '.join(known)})", f"{key}.{k}",
                                    file, line))
    return problems


def recorded_flags(recorded: dict[str, dict[str, Any]], name: str) -> dict[str, Any]:
    """A strategy's flags (:meth:`Strategy.flags`) as a study folder recorded them; for a folder written before
    they were, the shipped entry's of that name (else its name only)."""
    if name in recorded:
        return recorded[name]
    shipped = builtin_strategies().get(name)
    return shipped.flags() if shipped is not None else {"label": name}


def _uncontrolled(names: list[str], library: dict[str, Strategy]) -> list[str]:
    return [n for n in names if n in library and library[n].entry.uncontrolled]


def uncontrolled_of(names: list[str], library: dict[str, Strategy]) -> str | None:
    """The one strategy of ``names`` whose entry says ``uncontrolled: true`` (None: none, or several)."""
    marked = _uncontrolled(names, library)
    return marked[0] if len(marked) == 1 else None


def uncontrolled_problems(names: list[str], library: dict[str, Strategy], lines: Lines, path: Path, key: str
                          ) -> list[Problem]:
    """A located problem unless exactly one strategy of ``names`` (the study's list ``key``) is marked uncontrolled:
    the indices and criteria of a study are over its runs."""
    marked = _uncontrolled(names, library)
    if len(marked) == 1:
        return []
    file, line = lines.get(tuple(key.split(".")), (str(path), None))
    what = (f"several are marked uncontrolled ({', '.join(marked)}): list one of them" if marked else
            "none is marked uncontrolled: list one whose entry says `uncontrolled: true` (the shipped passive-off)")
    return [Problem(f"the strategies need one uncontrolled case, the one the indices and criteria are over; {what}",
                    key, file, line)]


def check_strategy(strategy: Strategy, scenario: Path, base: tuple[str, ...], i_max: float,
                   gains: dict[str, float] | None, best: float | None) -> None:
    """The engine's checks on a record scenario run under a strategy; ScenarioError located in the strategy entry.

    The scenario tree is built with the strategy's keys carrying the strategy file's lines, so a
    missing FMU, a parameter or a connection variable the FMU lacks is reported at its line there.
    """
    data, lines = load_tree(scenario)
    data.setdefault("name", scenario.stem)
    units = data.get("units")
    names = set(units) if isinstance(units, dict) else set()
    for assignment in strategy.common(base):
        apply_override(data, lines, assignment, names)
    here: dict[tuple[Any, ...], tuple[Any, ...]] = {}  # scenario key -> the strategy entry's key
    unit = data.setdefault("units", {}).setdefault(CONTROLLER, {})
    if strategy.fmu_path is not None:
        unit["fmu"] = str(strategy.fmu_path)
        here[("units", CONTROLLER, "fmu")] = ("fmu",)
    params = unit.setdefault("parameters", {}) if isinstance(unit, dict) else {}
    for assignment in strategy.overrides(i_max, gains, best):
        key, _, text = assignment.partition("=")
        if key.startswith("units."):
            continue
        name = key.split(".", 1)[1]
        params[name] = yaml.safe_load(text)
        here[("units", CONTROLLER, "parameters", name)] = ("parameters", name) if name in strategy.entry.parameters \
            else ("gains",)
    conns = strategy.connections(list(data.get("connections") or []))
    if conns is not None and strategy.entry.connections is not None:
        old = list(data.get("connections") or [])
        kept = [k for k, c in enumerate(old) if _target_unit(c) != CONTROLLER]
        moved = {("connections", new): lines.get(("connections", k)) for new, k in enumerate(kept)}
        for key in [k for k in lines if k[:1] == ("connections",) and len(k) > 1]:
            del lines[key]
        lines.update({k: v for k, v in moved.items() if v is not None})
        for j in range(len(strategy.entry.connections or [])):
            here[("connections", len(kept) + j)] = ("connections", j)
    if conns is not None:
        data["connections"] = conns
    if strategy.entry.current != COMMAND:
        data.setdefault("report", {})["current"] = strategy.current_ref
        here[("report", "current")] = ("current",)
    for scen_key, own in here.items():
        lines[scen_key] = strategy.where(*own)
        for sub in ("source", "target"):
            lines[(*scen_key, sub)] = strategy.where(*own, sub)
    role, missing = role_problems(strategy)
    role += tunable_problems(strategy)
    try:
        resolve_scenario(validate_scenario(data, lines, scenario, REPORT.model))
    except ScenarioError as exc:  # the engine's own problems, but not again for a role variable already reported
        raise ScenarioError([*role, *(_relocated(p, here, strategy) for p in exc.problems
                                      if not any(f"{name!r}" in p.message or f"{CONTROLLER}.{name}" in p.message
                                                 for name in missing))]) from None
    if role:
        raise ScenarioError(role)


def role_problems(strategy: Strategy) -> tuple[list[Problem], set[str]]:
    """The controller role's problems of a strategy with its own FMU, at the entry's ``current`` and ``limit``
    keys, and the names they concern: the current command must be an output and the limit a parameter, both in A
    (a variable without a unit is taken as A, with a warning naming both ends). Nothing when the FMU cannot be read
    (the engine says why)."""
    path = strategy.fmu_path
    if path is None or fmu_variables(path) is None:
        return [], set()
    unit = read_unit(path, CONTROLLER)
    checks = [("current", strategy.entry.current, "output", "the current command")]
    if strategy.entry.limit is not None:
        checks.append(("limit", strategy.entry.limit, "parameter", "the current limit"))
    problems, names = [], set()
    for key, name, causality, what in checks:
        problem, warning = check_variable(unit, name, causality, "A", f"{what} of strategy {strategy.name!r}")
        if problem:
            problems.append(strategy.problem(problem, key))
            names.add(name)
        if warning and key == "limit":  # the current's own is the engine's, on its connection to the device
            warn_once(warning)
    return problems, names


NUMERIC = ("Real", "Integer")  # FMU variable types a tuner can set from a range


def tunable_problems(strategy: Strategy, unit: UnitDescription | None = None) -> list[Problem]:
    """A located problem (at ``tunable.<name>``) for each tunable parameter the controller lacks, that is no
    numeric parameter, or whose range leaves the FMU's declared min/max. ``unit``: the controller's description
    (default: the entry's FMU; nothing when there is none or it cannot be read: the engine's checks say why)."""
    if not strategy.entry.tunable:
        return []
    if unit is None:
        path = strategy.fmu_path
        if path is None or fmu_variables(path) is None:
            return []
        unit = read_unit(path, CONTROLLER)
    model = unit.model_identifier or CONTROLLER
    problems = []
    for name, rng in strategy.entry.tunable.items():
        var = unit.variables.get(name)
        if var is None or var.causality != "parameter" or var.type not in NUMERIC:
            what = "has no variable" if var is None else (
                f"has {name!r} as a {var.causality} of type {var.type}, not a numeric (Real or Integer) parameter")
            text = f"{model} {what}" + (f" {name!r}" if var is None else "")
            problems.append(strategy.problem(f"tunable parameter {name!r}: {text} (strategy {strategy.name!r})",
                                             "tunable", name))
            continue
        below = var.min_value is not None and rng.low < var.min_value
        if below or (var.max_value is not None and rng.high > var.max_value):
            problems.append(strategy.problem(
                f"tunable parameter {name!r}: the range [{rng.low:g}, {rng.high:g}] leaves {model}'s declared "
                f"[{var.min_value}, {var.max_value}] (strategy {strategy.name!r})", "tunable", name))
    return problems


def _relocated(problem: Problem, here: dict[tuple[Any, ...], tuple[Any, ...]], strategy: Strategy) -> Problem:
    """A problem of the run's scenario named by the strategy entry's key where it comes from the entry."""
    for scen_key, own in here.items():
        text = dotted(scen_key)
        if problem.key == text or problem.key.startswith(text + "."):
            key = dotted((*strategy.prefix, *own)) + problem.key[len(text):]
            return Problem(f"{problem.message} (strategy {strategy.name!r})", key, problem.file, problem.line)
    return problem


def strategy_overrides(strategy: str, i_max: float, gains: dict[str, float] | None, best: float | None
                       ) -> tuple[str, ...]:
    """Scenario overrides that make a run follow a built-in strategy's controller unit (no connections).

    ``gains``: the gain set of an SOSM strategy; ``best``: the best constant current [A].
    """
    return builtin_strategies()[strategy].overrides(i_max, gains, best)
