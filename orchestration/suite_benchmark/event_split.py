"""Which records of a suite train the tuner and which are scored: the split by event.

The unit is the suite's record (the FEMA P695 pair: both horizontal components of one station), so the two
components of a station are always on the same side. A drawn split takes ``count`` records with
``numpy.random.default_rng(seed).choice`` (no replacement) from the suite's records in their order, so it is
the same on every machine for a seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orchestration.master.errors import Problem


@dataclass(frozen=True)
class EventSplit:
    """The records (events) that train and those that are scored, in the suite's order."""

    train: list[str]
    score: list[str]
    how: str  # "listed" or "drawn: N with seed S"

    @property
    def overlap(self) -> list[str]:
        return [e for e in self.train if e in self.score]


def split_events(events: list[str], train: list[str] | int, seed: int, score: list[str] | None, overlap: bool,
                 key: str = "benchmark") -> tuple[EventSplit | None, list[Problem]]:
    """The split of ``events`` (the suite's records, in order): ``train`` as listed, or that many drawn with
    ``seed``; ``score`` as listed or every other record. Problems: an unknown record, a count that leaves no
    record to score, and training records that are scored unless ``overlap`` says so on purpose."""
    problems = []
    count = train if isinstance(train, int) else None
    for name, names in (("train", None if count is not None else train), ("score", score)):
        for k, e in enumerate(names or []):
            if e not in events:
                problems.append(Problem(f"unknown record {e!r} (the suite's: {', '.join(events)})",
                                        f"{key}.{name}.{k}"))
    if count is not None and count >= len(events):
        problems.append(Problem(f"train: {count} records leave none of the suite's {len(events)} to score",
                                f"{key}.train"))
    if problems:
        return None, problems
    if count is not None:
        drawn = set(np.random.default_rng(seed).choice(len(events), size=count, replace=False).tolist())
        chosen, how = [e for k, e in enumerate(events) if k in drawn], f"drawn: {count} with seed {seed}"
    else:
        chosen, how = [e for e in events if e in list(train)], "listed"
    scored = [e for e in events if e in score] if score is not None else [e for e in events if e not in chosen]
    split = EventSplit(chosen, scored, how)
    if split.overlap and not overlap:
        problems.append(Problem(f"records {split.overlap} are both trained on and scored: an in-sample score. "
                                "Remove them from one list, or set overlap: true to do it on purpose",
                                f"{key}.score"))
    if not scored:
        problems.append(Problem("no record is left to score", f"{key}.score"))
    return (None if problems else split), problems
