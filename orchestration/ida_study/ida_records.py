"""Typed records between an IDA's run and its report: what ``ida.json`` and ``jobs/`` hold.

:class:`IdaInfo` is the study's description (written to ``ida.json``, read back by
``--report`` and ``--resume``); :class:`ComponentInfo` one record component as played;
:class:`RunOutcome` one finished run as the result store keeps it. Each converts to and
from the JSON it is stored as (``to_json`` / ``from_json``), so folders written before these
records existed still read.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any

from orchestration.ida_study.ida_jobs import IdaRunResult


def utc_now() -> str:
    """The time now, ISO 8601 in UTC (``2026-12-02T05:30:00Z``)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


@dataclass(frozen=True)
class ComponentInfo:
    """One record component as the study played it."""

    id: str
    record: str
    component: str
    source: str
    window_s: tuple[float, float]  # [s] start and end of the window in record time
    stop_time_s: float  # [s] simulated time of each run
    im: float  # [g] intensity of the windowed component at scale 1
    pga_g: float  # [g] peak ground acceleration of the whole component

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "window_s": list(self.window_s)}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> ComponentInfo:
        return cls(id=d["id"], record=d["record"], component=d["component"], source=d["source"],
                   window_s=(d["window_s"][0], d["window_s"][1]), stop_time_s=d["stop_time_s"], im=d["im"],
                   pga_g=d["pga_g"])


@dataclass(frozen=True)
class RunOutcome:
    """One finished run as stored under its content key: ``value`` is the job's (ida_jobs.ida_job) if ``ok``."""

    label: str  # record_id/level/strategy
    ok: bool
    status: str
    value: dict[str, Any] | None = None
    error: str | None = None
    wall_time_s: float | None = None
    worker: str | None = None

    @property
    def result(self) -> IdaRunResult | None:
        """The job's value as its record (None unless ``ok``)."""
        return IdaRunResult.from_json(self.value) if self.ok and self.value else None

    @property
    def run_status(self) -> str:
        """How the run ended: the job's own status (ok, diverged, ...) if it returned, else the batch's."""
        return self.value["status"] if self.ok and self.value else self.status

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RunOutcome:
        return cls(label=d.get("label", d.get("key", "")), ok=bool(d["ok"]), status=d["status"], value=d.get("value"),
                   error=d.get("error"), wall_time_s=d.get("wall_time_s"), worker=d.get("worker"))


@dataclass
class IdaInfo:
    """An IDA study's settings, components and provenance; the end of the run fills the last fields."""

    name: str
    description: str
    study_file: str
    started: str
    config: dict[str, Any]  # the IdaSpec as JSON
    measure: str  # intensity measure: pga or sa
    measure_label: str
    period_s: float | None  # [s] the isolated period of Sa
    strategies: dict[str, list[str]]  # strategy -> its scenario overrides
    masses_kg: list[float]
    gains: dict[str, Any] | None  # the SOSM gains file's document
    planning_s: float  # [s] checking and planning every run
    components: list[ComponentInfo]
    batch: dict[str, Any]  # where the runs ran: scheduler, workers, dashboard
    provenance: dict[str, Any]
    finished: str | None = None
    resumed: list[str] | None = None
    interrupted: bool | None = None
    wall_time_s: float | None = None  # [s] the runs' phase
    runs_computed: int | None = None
    strategy_flags: dict[str, dict[str, Any]] = field(default_factory=dict)  # strategy -> its entry's flags
    extra: dict[str, Any] = field(default_factory=dict)  # keys this version does not know (kept as read)

    _ORDER = ("name", "description", "study_file", "started", "finished", "config", "measure", "measure_label",
              "period_s", "strategies", "masses_kg", "gains", "planning_s", "components", "batch", "provenance",
              "resumed", "interrupted", "wall_time_s", "runs_computed", "strategy_flags")

    def flags(self, strategy: str) -> dict[str, Any]:
        """A strategy's flags (its entry's: uncontrolled, style, ...; a ``{name, overrides}`` strategy has none)."""
        from orchestration.building_studies.strategies import recorded_flags

        return recorded_flags(self.strategy_flags, strategy)

    @property
    def uncontrolled(self) -> str | None:
        """The study's uncontrolled strategy (its entry says ``uncontrolled: true``); None if it lists none: its
        rows then have no indices."""
        marked = [s for s in self.strategies if self.flags(s).get("uncontrolled")]
        return marked[0] if len(marked) == 1 else None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key in self._ORDER:
            value = getattr(self, key)
            if key in ("resumed", "interrupted", "wall_time_s", "runs_computed") and value is None:
                continue
            if key == "strategy_flags" and not value:
                continue
            out[key] = [c.to_json() for c in value] if key == "components" else value
        return {**out, **self.extra}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> IdaInfo:
        known = {k: d[k] for k in cls._ORDER if k in d}
        known["components"] = [ComponentInfo.from_json(c) for c in d.get("components", [])]
        known.setdefault("batch", d.get("engine", {}))  # folders written before the batch layer had its name
        known.setdefault("description", "")
        extra = {k: v for k, v in d.items() if k not in cls._ORDER and k != "engine"}
        return cls(**known, extra=extra)
