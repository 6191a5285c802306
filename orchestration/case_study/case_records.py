"""Typed records between the case study's run and its report: what ``study.json`` holds.

:class:`CaseStudyRecord` is the whole study (settings, per-record facts, every job's outcome,
provenance); :class:`RecordInfo` one record's facts as planned; :class:`RunEntry` one
record x strategy co-simulation; :class:`SweepOutcome` and :class:`ReferenceOutcome` the
in-process jobs. Each converts to and from the JSON of ``study.json`` (``to_json`` /
``from_json``), which ``--report`` and ``--resume`` read back; folders written before these
records existed still read. ``config`` and the gain-set documents stay the JSON they are
(the study's StudySpec dump, the gains files' documents).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any


def utc_now() -> str:
    """The time now, ISO 8601 in UTC (``2026-12-02T05:30:00Z``)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


@dataclass(frozen=True)
class RecordInfo:
    """One record of the study as planned."""

    scenario: str  # its scenario file
    stop_time_s: float  # [s]
    masses_kg: list[float]  # [kg] base first
    record_file: str
    scale: float | None  # amplitude scale of the ground motion
    time_scale: float  # time scale of the ground motion (1: as recorded)
    n_isolators: int | None
    name: str | None = None  # the record's name for a reader (the scenario's label of ground.record), or None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RecordInfo:
        return cls(scenario=d.get("scenario", ""), stop_time_s=d["stop_time_s"], masses_kg=list(d["masses_kg"]),
                   record_file=d.get("record_file", ""), scale=d.get("scale"), time_scale=d.get("time_scale", 1.0),
                   n_isolators=d.get("n_isolators"), name=d.get("name"))


@dataclass
class RunEntry:
    """One record x strategy co-simulation: planned, then filled in as its job ends."""

    key: str  # record/strategy
    record: str
    strategy: str
    folder: str  # its run folder, relative to the study folder
    ok: bool = False
    error: str | None = None
    current_A: float | None = None  # [A] the constant current of a passive strategy
    overrides: list[str] | None = None  # the strategy's scenario overrides (None: not planned)
    status: str | None = None  # how the run ended (None: it did not end)
    wall_time_s: float | None = None
    unit_warnings: dict[str, Any] | None = None
    variant: str | None = None  # the robustness variant it runs (None: the study's own, nominal run)
    # numerical validity, from the run's summary.json (None: not read, a run without one)
    valid: bool | None = None
    invalid_reasons: list[str] = field(default_factory=list)
    energy: dict[str, Any] | None = None  # the summary's energy section (J9 comes from it)
    step_change: dict[str, float] | None = None  # --verify-step: criterion -> relative change at half the step

    def to_json(self) -> dict[str, Any]:
        out = {"key": self.key, "record": self.record, "strategy": self.strategy, "folder": self.folder,
               "ok": self.ok, "error": self.error}
        if self.variant is not None:
            out["variant"] = self.variant
        if self.valid is not None:
            out.update(valid=self.valid, invalid_reasons=self.invalid_reasons, energy=self.energy)
        if self.step_change is not None:
            out["step_change"] = self.step_change
        if self.overrides is not None:
            out.update(current_A=self.current_A, overrides=self.overrides)
        if self.status is not None:
            out.update(status=self.status, wall_time_s=self.wall_time_s, unit_warnings=self.unit_warnings)
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RunEntry:
        return cls(key=d["key"], record=d["record"], strategy=d["strategy"], folder=d["folder"], ok=bool(d.get("ok")),
                   error=d.get("error"), current_A=d.get("current_A"), overrides=d.get("overrides"),
                   status=d.get("status"), wall_time_s=d.get("wall_time_s"), unit_warnings=d.get("unit_warnings"),
                   variant=d.get("variant"), valid=d.get("valid"), invalid_reasons=list(d.get("invalid_reasons") or []),
                   energy=d.get("energy"), step_change=d.get("step_change"))


@dataclass(frozen=True)
class SweepOutcome:
    """The constant-current sweep of one record: every current's objective, the best current."""

    ok: bool
    error: str | None = None
    rows: list[dict[str, Any]] = field(default_factory=list)  # current_A, x0, d, a3, J per current
    best_current_A: float | None = None  # [A]
    best_J: float | None = None

    def to_json(self) -> dict[str, Any]:
        out = {"ok": self.ok, "error": self.error}
        return out if not self.ok else {**out, "rows": self.rows, "best_current_A": self.best_current_A,
                                         "best_J": self.best_J}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SweepOutcome:
        return cls(ok=bool(d.get("ok")), error=d.get("error"), rows=d.get("rows") or [],
                   best_current_A=d.get("best_current_A"), best_J=d.get("best_J"))


@dataclass(frozen=True)
class ReferenceOutcome:
    """The monolithic Radau reference of one passive run: its peaks (units of peaks.csv) if ok."""

    ok: bool
    error: str | None = None
    value: dict[str, float] | None = None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> ReferenceOutcome:
        return cls(ok=bool(d.get("ok")), error=d.get("error"), value=d.get("value"))


@dataclass(frozen=True)
class PreparedStudy:
    """A study checked before anything is written: its records, gain sets, coupling algorithms and step."""

    records: dict[str, RecordInfo]
    gain_sets: dict[str, dict[str, Any]]  # SOSM gain set (sosm, sosm-fig15) -> its gains file's document
    algorithms: dict[str, str]  # record -> coupling algorithm
    step: float | None  # [s] communication step

    @property
    def gains(self) -> dict[str, Any] | None:
        """The document of the ``sosm`` gains file, if the study has that strategy."""
        return self.gain_sets.get("sosm")


@dataclass
class CaseStudyRecord:
    """A case study from its start to its report (``study.json``)."""

    name: str
    description: str
    study_file: str
    started: str
    config: dict[str, Any]  # the StudySpec dump and the swept currents (``sweep_currents``)
    strategies: list[str]
    records: dict[str, RecordInfo]
    run_overrides: list[str]
    gains: dict[str, Any] | None  # the sosm gains document (also in gain_sets)
    gains_file: str | None
    gain_sets: dict[str, dict[str, Any]]
    gains_files: dict[str, str]
    provenance: dict[str, Any]
    batch: dict[str, Any] = field(default_factory=dict)  # where the jobs ran: scheduler, workers
    finished: str | None = None
    best_current: dict[str, float] = field(default_factory=dict)  # record -> best constant current [A]
    sweep: dict[str, SweepOutcome] = field(default_factory=dict)  # record -> its sweep
    reference: dict[str, ReferenceOutcome] = field(default_factory=dict)  # record/strategy -> its reference
    runs: list[RunEntry] = field(default_factory=list)
    indices: dict[str, dict[str, float]] = field(default_factory=dict)  # record/strategy -> evaluation indices
    jobs_computed: int = 0  # jobs sent to the pool (the others' results were stored already)
    resumed: list[str] | None = None
    interrupted: bool | None = None
    metrics: dict[str, dict[str, float]] | None = None  # record/strategy -> metrics (written by the report)
    variant_runs: list[RunEntry] = field(default_factory=list)  # robustness variants: record/strategy/variant
    half_step_runs: list[RunEntry] = field(default_factory=list)  # --verify-step: record/strategy/half-step
    strategy_flags: dict[str, dict[str, Any]] = field(default_factory=dict)  # strategy -> its entry's flags

    def flags(self, strategy: str) -> dict[str, Any]:
        """What the report needs of a strategy's entry (:meth:`Strategy.flags`); for a study.json written before
        runs recorded them, the shipped entry's of that name (else none)."""
        from orchestration.building_studies.strategies import recorded_flags

        return recorded_flags(self.strategy_flags, strategy)

    @property
    def uncontrolled(self) -> str:
        """The study's uncontrolled strategy (its entry says ``uncontrolled: true``)."""
        marked = [s for s in self.strategies if self.flags(s).get("uncontrolled")]
        if len(marked) != 1:
            raise ValueError(f"study.json: {len(marked)} strategies are marked uncontrolled, not one")
        return marked[0]

    def paper(self, part: str) -> list[str]:
        """The study's strategies with that part in the paper's figures (``controlled`` or ``passive``), in order."""
        return [s for s in self.strategies if self.flags(s).get("paper_figures") == part]

    def run(self, key: str) -> RunEntry:
        """The run entry of ``record/strategy`` (or of a robustness variant, ``record/strategy/variant``, or of
        a run at half the plant's step, ``record/strategy/half-step``)."""
        return next(e for e in (*self.runs, *self.variant_runs, *self.half_step_runs) if e.key == key)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.name, "description": self.description, "study_file": self.study_file,
            "started": self.started, "finished": self.finished, "config": self.config,
            "strategies": self.strategies, "records": {r: i.to_json() for r, i in self.records.items()},
            "run_overrides": self.run_overrides, "gains": self.gains, "gains_file": self.gains_file,
            "gain_sets": self.gain_sets, "gains_files": self.gains_files, "best_current": self.best_current,
            "sweep": {r: s.to_json() for r, s in self.sweep.items()},
            "reference": {k: v.to_json() for k, v in self.reference.items()},
            "runs": [e.to_json() for e in self.runs], "indices": self.indices, "provenance": self.provenance,
            "batch": self.batch, "jobs_computed": self.jobs_computed}
        if self.resumed is not None:
            out["resumed"] = self.resumed
        if self.interrupted is not None:
            out["interrupted"] = self.interrupted
        if self.metrics is not None:
            out["metrics"] = self.metrics
        if self.variant_runs:
            out["variant_runs"] = [e.to_json() for e in self.variant_runs]
        if self.half_step_runs:
            out["half_step_runs"] = [e.to_json() for e in self.half_step_runs]
        if self.strategy_flags:
            out["strategy_flags"] = self.strategy_flags
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> CaseStudyRecord:
        return cls(
            name=d["name"], description=d.get("description", ""), study_file=d["study_file"], started=d["started"],
            config=d["config"], strategies=list(d["strategies"]),
            records={r: RecordInfo.from_json(i) for r, i in d["records"].items()},
            run_overrides=list(d.get("run_overrides", [])), gains=d.get("gains"), gains_file=d.get("gains_file"),
            gain_sets=d.get("gain_sets") or ({"sosm": d["gains"]} if d.get("gains") else {}),
            gains_files=d.get("gains_files") or ({"sosm": d["gains_file"]} if d.get("gains_file") else {}),
            provenance=d.get("provenance", {}), batch=d.get("batch", d.get("engine", {})), finished=d.get("finished"),
            best_current=d.get("best_current", {}),
            sweep={r: SweepOutcome.from_json(s) for r, s in (d.get("sweep") or {}).items()},
            reference={k: ReferenceOutcome.from_json(v) for k, v in (d.get("reference") or {}).items()},
            runs=[RunEntry.from_json(e) for e in d.get("runs", [])], indices=d.get("indices") or {},
            jobs_computed=d.get("jobs_computed", 0), resumed=d.get("resumed"), interrupted=d.get("interrupted"),
            metrics=d.get("metrics"), variant_runs=[RunEntry.from_json(e) for e in d.get("variant_runs", [])],
            half_step_runs=[RunEntry.from_json(e) for e in d.get("half_step_runs", [])],
            strategy_flags=d.get("strategy_flags") or {})
