"""A run's report, generic: how a run is named (caption, labels), its figures, and the application's hook.

The engine knows variables only. A scenario's ``report`` section names the run for a reader
(``caption``, filled from the run's parameter values, and ``labels``);
the application may add keys of its own to that section and a :class:`ReportHook` that turns
them into entries of ``summary.json`` and into figures (drawn with :class:`Figures`, which
titles each with the caption and keeps every peak of a decimated line). The summary's entries are
made in :mod:`orchestration.master.summary`; the figures are drawn by forked processes
(:class:`PlotProcess`, on :mod:`orchestration.master.child_process`), or in the run's process.
"""

from __future__ import annotations

import functools
import logging
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from orchestration.master.child_process import Child, exit_text, fork_safe, read_all, spare_processes
from orchestration.master.figure_files import PNG_ONLY, RUN_DPI, FigureFiles, save_figure
from orchestration.master.recorder import Recorder
from orchestration.master.scenario import ReportSpec
from orchestration.master.summary import non_finite, peak, sample_interval, summarize
from orchestration.master.yaml_source import DataFile

__all__ = ["PLACEHOLDER", "RUN_DPI", "FigureFiles", "Figures", "PlotFailed", "PlotProcess", "ReportHook",
           "RunDescription", "caption", "decimate", "non_finite", "peak", "plot", "prepare_plotting", "report_summary",
           "sample_interval", "summarize"]
# non_finite, peak, report_summary, sample_interval, summarize: the summary's part (orchestration.master.summary),
# importable from here as before

PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_.\[\]]*)\}")
_MAX_POINTS = 4000  # per plotted line: a figure is ~1000 px wide; min/max pairs keep every peak


@dataclass(frozen=True)
class RunDescription:
    """What a reader needs to name a run: parameter values (set or declared) and readable labels."""

    values: dict[str, dict[str, Any]]  # unit -> parameter -> value used in the run
    model_names: dict[str, str]  # unit -> the FMU's model name
    labels: dict[str, str] = field(default_factory=dict)
    held: frozenset[str] = frozenset()  # "unit.var" Real outputs held on the base grid (discrete, or a unit's own step)
    set_values: dict[str, dict[str, Any]] = field(default_factory=dict)  # unit -> parameter -> value the scenario set

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
    """Figures of one run, saved into its folder: titled with the run's caption, lines decimated.

    Each is a PNG at ``files.dpi`` (default :data:`RUN_DPI`), with ``files.formats`` (SVG, PDF) beside it.

    ``time_figure`` draws time histories; with a ``window`` (a time span [s] the application
    picks) the window is drawn large and the whole run below it, the window shaded.
    """

    def __init__(self, folder: Path, head: str, share: tuple[int, int] = (0, 1),
                 files: FigureFiles = PNG_ONLY) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self.plt = plt
        self.folder = Path(folder)
        self.head = head  # the caption, first line of every title
        self.made: list[Path] = []
        self.share = share  # (k, n): this process writes the k-th, (k+n)-th, ... figure (see PlotProcess)
        self.files = files
        self._turns = 0

    def _my_turn(self) -> bool:
        """Whether the next figure is this process's to write (figures take turns in the order the hook makes
        them with :meth:`time_figure`, or saves them when it made them itself)."""
        k, n = self.share
        turn, self._turns = self._turns, self._turns + 1
        return turn % n == k

    def save(self, fig: Any, file: str) -> None:
        """Write ``fig`` as ``file`` (a ``.png``) in the run folder, and in each vector format asked for (each
        through a temporary name), and close it.

        With a ``share`` (k, n), only every n-th figure from the k-th is written (other
        processes write the others); the rest are closed unrendered.
        """
        mine = getattr(fig, "_mre_cosim_mine", None)
        if not (self._my_turn() if mine is None else mine):
            self.plt.close(fig)
            return
        try:
            save_figure(fig, self.folder / file, self.files, RUN_DPI, made=self.made)
        finally:
            self.plt.close(fig)

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
            mask: slice | np.ndarray = slice(None)
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


def plot(rec: Recorder, spec: ReportSpec, hook: ReportHook | None, folder: Path, name: str,
         run: RunDescription, share: tuple[int, int] = (0, 1), files: FigureFiles = PNG_ONLY) -> list[Path]:
    """The application's figures of a run (none without a hook that draws): the files written, PNG and the
    ``files.formats`` (with a ``share`` (k, n), those of the k-th of n processes drawing them: :class:`Figures`)."""
    if hook is None or hook.plot is None:
        return []
    figures = Figures(folder, caption(spec, run, name), share, files)
    hook.plot(spec, rec, run, figures)
    return figures.made


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
    """A run's figures drawn by forked processes (:class:`~orchestration.master.child_process.Child`), beside the
    run's other writing.

    :meth:`start` forks before the run: each child imports matplotlib while the units step,
    then waits. :meth:`draw` tells them how many rows were recorded (the rows themselves are
    in storage all processes share, :class:`~orchestration.master.recorder.RowStorage`); they
    draw while the caller writes ``timeseries.csv``, each every n-th figure (``draw(rows,
    (k, n))``). :meth:`wait` returns the PNG files, or raises :class:`PlotFailed` (also when a
    child died). The children ignore SIGINT and SIGTERM (the run decides when to stop) and
    exit when the caller closes its end without a count (:meth:`cancel`, or the caller's death).
    """

    def __init__(self, children: list[Child]) -> None:
        self._procs = children

    @property
    def _children(self) -> list[tuple[int, int, int]]:
        """(pid, go pipe, result pipe) per child (0 and -1 once reaped and closed)."""
        return [(c.pid, c.go, c.result) for c in self._procs]

    @staticmethod
    def available() -> bool:
        """Forking is safe here (:func:`~orchestration.master.child_process.fork_safe`)."""
        return fork_safe()

    @classmethod
    def start(cls, draw: Callable[[int, tuple[int, int]], list[Path]],
              processes: int | None = None) -> PlotProcess | None:
        """Fork ``processes`` children (default: 2, or 1 on one CPU), the k-th of which will call
        ``draw(rows, (k, processes))``; None where forking is not available."""
        if not cls.available():
            return None
        n = processes or spare_processes(2)
        children: list[Child] = []
        for k in range(n):
            earlier = [fd for c in children for fd in (c.go, c.result)]
            children.append(Child.fork(functools.partial(_plot_child, draw, (k, n)),
                                       "the figures could not be drawn", earlier))
        return cls(children)

    def draw(self, rows: int) -> None:
        """Draw the figures of the first ``rows`` rows (the children start at once; a child that died: :meth:`wait`
        says so)."""
        for child in self._procs:
            child.send(str(rows))
        self._close_go()

    def cancel(self) -> None:
        """No figures: the children exit."""
        self._close_go()
        for child in self._procs:
            child.reap()

    def wait(self) -> list[Path]:
        """The PNG files written, once every child is done; :class:`PlotFailed` if any could not draw its figures."""
        self._close_go()
        answers = [child.answer() for child in self._procs]
        statuses = [child.reap() for child in self._procs]
        files, errors = [], []
        for answer, status in zip(answers, statuses, strict=True):
            if not isinstance(answer, dict):
                errors.append(f"a plot process ended without an answer ({exit_text(status)})")
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
        except (OSError, AttributeError):
            pass

    def parent_fds(self) -> list[int]:
        """This process's ends of the children's pipes (a process forked later must close them: a child sees the
        run close its pipe only when no other process holds it open)."""
        return [fd for c in self._procs for fd in (c.go, c.result) if fd >= 0]

    def _close_go(self) -> None:
        for child in self._procs:
            child.close_go()


def _plot_child(draw: Callable[[int, tuple[int, int]], list[Path]], share: tuple[int, int],
                go: int) -> dict[str, Any] | None:
    """The plot process: import, wait for the row count, draw; answers ``{"files": [...]}`` (an error is answered
    by :class:`~orchestration.master.child_process.Child`), nothing when cancelled."""
    try:
        prepare_plotting()
    except Exception:  # drawing reports it
        pass
    rows = read_all(go)
    if not rows:
        return None  # cancelled
    return {"files": [str(p) for p in draw(int(rows), share)]}
