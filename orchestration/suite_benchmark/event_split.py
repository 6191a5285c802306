"""Which records of a suite train the tuner and which are scored: the split by event.

The unit is the suite's record (the FEMA P695 pair: both horizontal components of one station), so the two
components of a station are always on the same side. With ``groups`` (each record's earthquake, which the FEMA P695
far-field set names: two records each of Northridge 1994, Kobe 1995, ...), the split keeps every earthquake on one
side too: a count draws earthquakes, and a listed split that puts one earthquake on both sides is refused unless
the overlap is declared. A draw is ``numpy.random.default_rng(seed).choice`` (no replacement) over the records, or
the earthquakes, in the suite's order, so it is the same on every machine for a seed.
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
    how: str  # "listed" or "drawn: N records (or earthquakes) with seed S"

    @property
    def overlap(self) -> list[str]:
        return [e for e in self.train if e in self.score]


def split_events(events: list[str], train: list[str] | int, seed: int, score: list[str] | None, overlap: bool,
                 groups: dict[str, str] | None = None, key: str = "benchmark") -> tuple[EventSplit | None,
                                                                                          list[Problem]]:
    """The split of ``events`` (the suite's records, in order): ``train`` as listed, or that many drawn with
    ``seed`` (earthquakes, with ``groups``: record -> its earthquake); ``score`` as listed or every other record.
    Problems: an unknown record, a count that leaves no record to score, and training records that are scored
    (or, with ``groups``, an earthquake on both sides) unless ``overlap`` says so on purpose."""
    problems = []
    count = train if isinstance(train, int) else None
    for name, names in (("train", None if count is not None else train), ("score", score)):
        for k, e in enumerate(names or []):
            if e not in events:
                problems.append(Problem(f"unknown record {e!r} (the suite's: {', '.join(events)})",
                                        f"{key}.{name}.{k}"))
    units = list(dict.fromkeys(groups[e] for e in events)) if groups is not None else events
    what = "earthquakes" if groups is not None else "records"
    if count is not None and count >= len(units):
        problems.append(Problem(f"train: {count} {what} leave none of the suite's {len(units)} to score",
                                f"{key}.train"))
    if problems:
        return None, problems
    if count is not None:
        drawn = {units[k] for k in np.random.default_rng(seed).choice(len(units), size=count, replace=False)}
        chosen = [e for e in events if (groups[e] if groups is not None else e) in drawn]
        how = f"drawn: {count} {what} with seed {seed}"
    else:
        chosen, how = [e for e in events if e in list(train)], "listed"
    scored = [e for e in events if e in score] if score is not None else [e for e in events if e not in chosen]
    split = EventSplit(chosen, scored, how)
    if split.overlap and not overlap:
        problems.append(Problem(f"records {split.overlap} are both trained on and scored: an in-sample score. "
                                "Remove them from one list, or set overlap: true to do it on purpose",
                                f"{key}.score"))
    elif groups is not None and not overlap:
        shared = [g for g in units if any(groups[e] == g for e in chosen) and any(groups[e] == g for e in scored)]
        if shared:
            problems.append(Problem(f"earthquakes {shared} have records both trained on and scored "
                                    f"(split_by: earthquake). Move their records to one side, or set overlap: true "
                                    "to do it on purpose", f"{key}.score"))
    if not scored:
        problems.append(Problem("no record is left to score", f"{key}.score"))
    return (None if problems else split), problems
