"""The tool's exceptions: configuration problems and simulation failures are kept apart."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    """One configuration problem: where it is (file, line, key path) and what is wrong."""

    message: str
    key: str = ""
    file: str = ""
    line: int | None = None

    def __str__(self) -> str:
        where = self.file
        if self.line is not None:
            where = f"{where}:{self.line}" if where else f"line {self.line}"
        parts = [p for p in (where, self.key) if p]
        return f"{': '.join(parts)}: {self.message}" if parts else self.message


class ScenarioError(Exception):
    """A scenario (or its data) cannot be run; carries every problem found, not only the first."""

    def __init__(self, problems: list[Problem] | Problem | str) -> None:
        if isinstance(problems, str):
            problems = [Problem(problems)]
        elif isinstance(problems, Problem):
            problems = [problems]
        self.problems = list(problems)
        super().__init__(self.report())

    def report(self) -> str:
        n = len(self.problems)
        head = f"scenario error ({n} problem{'s' if n != 1 else ''}):"
        return "\n".join([head, *(f"  - {p}" for p in self.problems)])


class SimulationError(Exception):
    """A run failed after it started: names the unit, the variable if known, and the time."""

    def __init__(
        self,
        message: str,
        unit: str | None = None,
        variable: str | None = None,
        time: float | None = None,
        details: tuple[str, ...] = (),
    ) -> None:
        self.unit = unit
        self.variable = variable
        self.time = time
        self.details = details
        self.reason = message
        where = []
        if unit:
            where.append(f"unit '{unit}'")
        if variable:
            where.append(f"variable '{variable}'")
        if time is not None:
            where.append(f"t = {time:.6g} s")
        text = f"{', '.join(where)}: {message}" if where else message
        if details:
            text += "\n" + "\n".join(f"    {d}" for d in details)
        super().__init__(text)


class UnitCallError(SimulationError):
    """An FMI call returned discard, error or fatal (translated in one place: fmi_status.check_status)."""

    def __init__(self, unit: str, function: str, status: str, time: float | None, log: tuple[str, ...]) -> None:
        self.function = function
        self.status = status
        super().__init__(f"{function} returned {status}", unit=unit, time=time, details=log)
