"""Run summary and figures, generic: every recorded variable's peak, plus what the application's hook adds.

The engine knows variables only. A scenario's ``report`` section names the run for a reader
(``caption``, filled from the run's parameter values, and ``labels``);
the application may add keys of its own to that section and a :class:`ReportHook` that turns
them into entries of ``summary.json`` and into figures (drawn with :class:`Figures`, which
titles each with the caption and keeps every peak of a decimated line).
"""

from __future__ import annotations

import json
import logging
import os
import re
import signal
import sys
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.recorder import Recorder
from orchestration.master.scenario import ReportSpec
from orchestration.master.yaml_source import DataFile

PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_.\[\]]*)\}")
_MAX_POINTS = 4000  # per plotted line: a figure is ~1000 px wide; min/max pairs keep every peak


def peak(x: np.ndarray) -> float | None:
    """Largest absolute value, or None for an empty series."""
    return float(np.max(np.abs(x))) if len(x) else None


def summarize(rec: Recorder) -> dict[str, Any]:
    """The engine's own summary: every recorded numeric variable's peak, minimum and maximum (SI units)."""
    numeric = [k for k, kind in enumerate(rec.kinds) if kind != "string"]
    if not rec.count or not numeric:
        return {"variables": {rec.names[k]: {"max_abs": None, "min": None, "max": None} for k in numeric}}
    block = rec.data[: rec.count]
    if len(numeric) != block.shape[1]:
        block = block[:, numeric]
    top, low, high = np.max(np.abs(block), axis=0), np.min(block, axis=0), np.max(block, axis=0)  # all columns at once
    return {"variables": {
        rec.names[k]: {"max_abs": float(top[j]), "min": float(low[j]), "max": float(high[j])}
        for j, k in enumerate(numeric)
    }}


def sample_interval(rec: Recorder) -> float:
    """The recorded time step [s] (0 with fewer than two samples)."""
    t = rec.times
    return float(t[1] - t[0]) if len(t) > 1 else 0.0


@dataclass(frozen=True)
class RunDescription:
    """What a reader needs to name a run: parameter values (set or declared) and readable labels."""

    values: dict[str, dict[str, Any]]  # unit -> parameter -> value used in the run
    model_names: dict[str, str]  # unit -> the FMU's model name
    labels: dict[str, str] = field(default_factory=dict)
    held: frozenset[str] = frozenset()  # "unit.var" Real outputs held on the base grid (discrete, or a unit's own step)

    def value(self, unit: str, name: str) -> Any:
        """A parameter's value as the run used it, or None if the unit has no such parameter."""
        return self.values.get(unit, {}).get(name)

    def render(self, template: str, depth: int = 0) -> str:
        """Fill ``{unit.param}`` with the run's values; a value with a label ``unit.param=value`` shows the label.

        A placeholder naming a parameter the unit does not have (a unit swapped for another
        FMU) shows that unit's model name, so a caption stays true for any swap.
        """

        def fill(m: re.Match[str]) -> str:
            unit, name = m.group(1), m.group(2)
            value = self.value(unit, name)
            if value is None:
                return self.model_names.get(unit, f"{unit}.{name}")
            text = _plain(value)
            label = self.labels.get(f"{unit}.{name}={text}")
            if label is not None and depth < 2:
                return self.render(label, depth + 1)
            return text

        return PLACEHOLDER.sub(fill, template)

    def label(self, ref: str) -> str:
        """A variable's readable name (``labels`` in the scenario), or ``unit.variable``."""
        text = self.labels.get(ref)
        return self.render(text) if text is not None else ref


def _plain(value: Any) -> str:
    if isinstance(value, DataFile):
        return Path(str(value)).name
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    return Path(value).name if isinstance(value, str) and "/" in value else str(value)


def caption(spec: ReportSpec, run: RunDescription, name: str) -> str:
    """One line saying what was run (record, scale, strategy, ...), or the scenario's name."""
    return run.render(spec.caption) if spec.caption else name


def decimate(t: np.ndarray, y: np.ndarray, max_points: int = _MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """At most ``max_points`` points that keep every bucket's minimum and maximum (so every peak shows).

    The buckets are ``max_points // 2`` near-equal runs of samples; within each, the first
    minimum and the first maximum are kept (the first NaN, if there is one, as numpy's argmin and
    argmax take it), all buckets at once.
    """
    n = len(t)
    if n <= max_points:
        return t, y
    buckets = max_points // 2
    edges = np.linspace(0, n, buckets + 1).astype(np.intp)
    lo, hi = edges[:-1], edges[1:]
    lo, hi = lo[hi > lo], hi[hi > lo]
    if not len(lo):
        return t[:0], y[:0]
    index = lo[:, None] + np.arange(int(np.max(hi - lo)))
    outside = index >= hi[:, None]  # the padding of the shorter buckets, at their ends
    values = np.asarray(y)[np.minimum(index, n - 1)]
    first_min = np.argmin(np.where(outside, np.inf, values), axis=1)
    first_max = np.argmax(np.where(outside, -np.inf, values), axis=1)
    idx = np.unique(np.concatenate([lo + first_min, lo + first_max]))
    return t[idx], y[idx]


class Figures:
    """Figures of one run, saved as PNG into its folder: titled with the run's caption, lines decimated.

    ``time_figure`` draws time histories; with a ``window`` (a time span [s] the application
    picks) the window is drawn large and the whole run below it, the window shaded.
    """

    def __init__(self, folder: Path, head: str, share: tuple[int, int] = (0, 1)) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.plt = plt
        self.folder = Path(folder)
        self.head = head  # the caption, first line of every title
        self.made: list[Path] = []
        self.share = share  # (k, n): this process writes the k-th, (k+n)-th, ... figure (see PlotProcess)
        self._turns = 0

    def _my_turn(self) -> bool:
        """Whether the next figure is this process's to write (figures take turns in the order the hook makes
        them with :meth:`time_figure`, or saves them when it made them itself)."""
        k, n = self.share
        turn, self._turns = self._turns, self._turns + 1
        return turn % n == k

    def save(self, fig: Any, file: str) -> None:
        """Write ``fig`` as ``file`` in the run folder (through a temporary name) and close it.

        With a ``share`` (k, n), only every n-th figure from the k-th is written (other
        processes write the others); the rest are closed unrendered.
        """
        mine = getattr(fig, "_mre_cosim_mine", None)
        if not (self._my_turn() if mine is None else mine):
            self.plt.close(fig)
            return
        path = self.folder / file
        tmp = self.folder / f".{file}.tmp.png"
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
        self.plt.close(fig)
        tmp.replace(path)
        self.made.append(path)

    def time_figure(self, t: np.ndarray, title: str, ylabel: str,
                    lines: list[tuple[np.ndarray, str, dict[str, Any]]],
                    window: tuple[float, float] | None = None, window_note: str = "") -> Any:
        """A figure of time histories ``(values, label, plot style)`` over ``t`` [s].

        A figure another process writes (``share``) comes back with its axes but nothing drawn on them.
        """
        plt = self.plt
        if window is None:
            fig, ax = plt.subplots(figsize=(9, 3.4))
            axes = [ax]
        else:
            fig, axes = plt.subplots(2, 1, figsize=(9, 4.6), gridspec_kw={"height_ratios": [3, 1]})
        fig._mre_cosim_mine = self._my_turn()
        if not fig._mre_cosim_mine:
            return fig
        for k, ax in enumerate(axes):
            mask = slice(None)
            if window is not None and k == 0:
                mask = (t >= window[0]) & (t <= window[1])
            for y, label, style in lines:
                ax.plot(*decimate(t[mask], y[mask]), label=label, **({"lw": 0.7} | style))
            ax.grid(alpha=0.3)
        axes[0].set(ylabel=ylabel, title=f"{self.head}\n{title}")
        axes[-1].set(xlabel="time [s]")
        if window is not None:
            axes[0].set_xlim(*window)
            if window_note:
                axes[0].text(0.995, 0.02, window_note, transform=axes[0].transAxes, ha="right", va="bottom",
                             fontsize=7, color="0.35")
            axes[1].axvspan(*window, color="0.85", zorder=0)
            axes[1].set_xlim(t[0], t[-1])
            axes[1].set_title("whole record (shaded: window above)", fontsize=8, loc="left")
        if len(lines) > 1:
            axes[0].legend(fontsize=7, loc="upper right")
        fig.tight_layout()
        return fig


@dataclass(frozen=True)
class ReportHook:
    """An application's part of the report: the keys it reads in ``report:``, what it adds to the summary, figures.

    ``model``: the ``report`` section's model, a subclass of
    :class:`~orchestration.master.scenario.ReportSpec` (its unknown keys are refused with file and
    line; every :class:`~orchestration.master.scenario.VariableRef` field is checked as an output
    and recorded). ``summarize(spec, recorder, run)`` returns entries for ``summary.json``
    (placed after the engine's run status and before its ``variables`` table; they may not
    replace the engine's keys). ``plot(spec, recorder, run, figures)`` draws figures with
    :class:`Figures` (``figures.save(fig, "name.png")``). ``spec`` is the section as ``model``
    read it, ``run`` the :class:`RunDescription`.
    """

    model: type[ReportSpec] = ReportSpec
    summarize: Callable[[Any, Recorder, RunDescription], dict[str, Any]] | None = None
    plot: Callable[[Any, Recorder, RunDescription, Figures], None] | None = None


def plot(rec: Recorder, spec: ReportSpec, hook: ReportHook | None, folder: Path, name: str,
         run: RunDescription, share: tuple[int, int] = (0, 1)) -> list[Path]:
    """The application's figures of a run (none without a hook that draws): the PNG files written (with a
    ``share`` (k, n), those of the k-th of n processes drawing them: :class:`Figures`)."""
    if hook is None or hook.plot is None:
        return []
    figures = Figures(folder, caption(spec, run, name), share)
    hook.plot(spec, rec, run, figures)
    return figures.made


def non_finite(rec: Recorder) -> list[str]:
    """One line per recorded numeric variable that took a non-finite value (NaN, +-inf), with when it first did."""
    numeric = [k for k, kind in enumerate(rec.kinds) if kind != "string"]
    if not rec.count or not numeric:
        return []
    block = rec.data[: rec.count]
    bad = ~np.isfinite(block[:, numeric] if len(numeric) != block.shape[1] else block)
    out = []
    for j in np.flatnonzero(bad.any(axis=0)):
        row, col = int(np.argmax(bad[:, j])), numeric[j]
        out.append(f"non-finite value: {rec.names[col]} = {block[row, col]} at t = {rec.times[row]:.6g} s")
    return out


def report_summary(rec: Recorder, spec: ReportSpec, hook: ReportHook | None, run: RunDescription,
                   reserved: set[str] | frozenset[str] = frozenset()) -> dict[str, Any]:
    """Numerical validity, the application's summary entries (without ``reserved`` keys), the ``variables`` table.

    ``valid`` is false when any reason is found: a recorded value that is not finite (the engine's), or one
    of the application's ``invalid_reasons`` (its hook returns them under that key: e.g. an energy balance
    that does not close). A physical result (a limit exceeded) is not such a reason.
    """
    added = hook.summarize(spec, rec, run) if hook is not None and hook.summarize is not None else {}
    generic = summarize(rec)
    reasons = non_finite(rec) + [str(r) for r in added.pop("invalid_reasons", None) or []]
    validity = {"valid": not reasons, "invalid_reasons": reasons}
    return validity | {k: v for k, v in added.items() if k not in reserved and k not in generic
                       and k not in validity} | generic


class PlotFailed(OSError):
    """The plot process could not draw the figures (an :class:`OSError`: the run reports it as a file it could not
    write, and keeps its other results)."""


def prepare_plotting() -> None:
    """Import what :class:`Figures` needs (matplotlib with the Agg backend, pyplot, PIL's image plugins), ahead of
    drawing."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot
    from PIL import Image

    Image.preinit()  # savefig's PNG writer would load PIL's plugins on the first figure


class PlotProcess:
    """A run's figures drawn by forked processes, beside the run's other writing.

    :meth:`start` forks before the run: each child imports matplotlib while the units step,
    then waits. :meth:`draw` tells them how many rows were recorded (the rows themselves are
    in storage all processes share, :class:`~orchestration.master.recorder.RowStorage`); they
    draw while the caller writes ``timeseries.csv``, each every n-th figure (``draw(rows,
    (k, n))``). :meth:`wait` returns the PNG files, or raises :class:`PlotFailed` (also when a
    child died). The children ignore SIGINT and SIGTERM (the run decides when to stop) and
    exit when the caller closes its end without a count (:meth:`cancel`, or the caller's death).
    """

    def __init__(self, children: list[tuple[int, int, int]]) -> None:
        self._children = children  # (pid, go pipe, result pipe) per child

    @staticmethod
    def available() -> bool:
        """Forking is safe here: Linux and one thread (a fork copies no other thread, nor locks it might hold)."""
        return sys.platform.startswith("linux") and threading.active_count() == 1

    @classmethod
    def start(cls, draw: Callable[[int, tuple[int, int]], list[Path]],
              processes: int | None = None) -> PlotProcess | None:
        """Fork ``processes`` children (default: 2, or 1 on one CPU), the k-th of which will call
        ``draw(rows, (k, processes))``; None where forking is not available."""
        if not cls.available():
            return None
        processes = processes or max(1, min(2, os.cpu_count() or 1))
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()  # nothing buffered before the fork is written twice
            except (AttributeError, OSError, ValueError):
                pass
        children = []
        for k in range(processes):
            go_read, go_write = os.pipe()
            result_read, result_write = os.pipe()
            pid = os.fork()
            if pid == 0:  # a child: never returns into the caller's code
                code = 1
                try:
                    for _, go, result in children:  # the earlier children's pipes
                        os.close(go)
                        os.close(result)
                    os.close(go_write)
                    os.close(result_read)
                    code = _plot_child(lambda rows, k=k: draw(rows, (k, processes)), go_read, result_write)
                finally:
                    os._exit(code)
            os.close(go_read)
            os.close(result_write)
            children.append((pid, go_write, result_read))
        return cls(children)

    def draw(self, rows: int) -> None:
        """Draw the figures of the first ``rows`` rows (the children start at once)."""
        for _, go, _ in self._children:
            if go >= 0:
                try:
                    os.write(go, str(rows).encode())
                except OSError:
                    pass  # a child that died: wait() says so
        self._close_go()

    def cancel(self) -> None:
        """No figures: the children exit."""
        self._close_go()
        self._reap()

    def wait(self) -> list[Path]:
        """The PNG files written, once every child is done; :class:`PlotFailed` if any could not draw its figures."""
        self._close_go()
        answers = []
        for _, _, result in self._children:
            chunks = []
            while chunk := os.read(result, 65536):
                chunks.append(chunk)
            try:
                answers.append(json.loads(b"".join(chunks) or b"null"))
            except ValueError:
                answers.append(None)
        statuses = self._reap()
        files, errors = [], []
        for answer, status in zip(answers, statuses, strict=True):
            if not isinstance(answer, dict):
                errors.append(f"a plot process ended without an answer ({_exit_text(status)})")
            elif "error" in answer:
                if answer.get("traceback"):
                    logging.getLogger("mre_cosim.report").debug("a plot process: %s", answer["traceback"])
                errors.append(answer["error"])
            else:
                files += answer["files"]
        if errors:
            raise PlotFailed("; ".join(dict.fromkeys(errors)))
        return [Path(p) for p in files]

    def __del__(self) -> None:  # dropped without draw, cancel or wait (an exception in the run): the children exit
        try:
            self.cancel()
        except OSError:
            pass

    def parent_fds(self) -> list[int]:
        """This process's ends of the children's pipes (a process forked later must close them: a child sees the
        run close its pipe only when no other process holds it open)."""
        return [fd for _, go, result in self._children for fd in (go, result) if fd >= 0]

    def _close_go(self) -> None:
        for _, go, _ in self._children:
            if go >= 0:
                os.close(go)
        self._children = [(pid, -1, result) for pid, _, result in self._children]

    def _reap(self) -> list[int]:
        statuses = []
        for pid, _, result in self._children:
            if result >= 0:
                os.close(result)
            statuses.append(os.waitpid(pid, 0)[1] if pid > 0 else 0)
        self._children = [(0, -1, -1) for _ in self._children]
        return statuses


def _exit_text(status: int) -> str:
    if os.WIFSIGNALED(status):
        return f"killed by {signal.Signals(os.WTERMSIG(status)).name}"
    return f"exit code {os.WEXITSTATUS(status)}"


def _plot_child(draw: Callable[[int], list[Path]], go: int, result: int) -> int:
    """The plot process: import, wait for the row count, draw, answer ``{"files": [...]}`` or ``{"error": text}``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        prepare_plotting()
    except Exception:  # drawing reports it
        pass
    chunks = []
    while chunk := os.read(go, 64):
        chunks.append(chunk)
    if not chunks:
        return 0  # cancelled
    try:
        answer: dict[str, Any] = {"files": [str(p) for p in draw(int(b"".join(chunks)))]}
    except OSError as exc:
        answer = {"error": exc.strerror or str(exc)}
    except BaseException as exc:  # reported to the run, which keeps its other results
        last = traceback.format_exception_only(exc)[-1].strip()
        answer = {"error": f"the figures could not be drawn ({last})", "traceback": traceback.format_exc()}
    data = json.dumps(answer).encode()
    while data:
        data = data[os.write(result, data):]
    return 0
