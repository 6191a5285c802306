"""Exit codes, one-line errors and crash logs shared by every command-line tool of the project.

Every tool's ``main(argv)`` runs its work through :func:`guarded`:

* a problem the user can cause and fix (the tool's own error types, given by the tool)
  is one line on stderr (a ``ScenarioError`` its list of problems) and exit code 2;
* Ctrl-C or SIGTERM before the tool has anything to save (start-up imports, checking a
  scenario, building FMUs) is ``interrupted; nothing written`` and exit code 130;
* anything else is a bug: its traceback goes to a log file in the temporary folder, one
  line names the exception and that file, and the exit code is 3.

Only the standard library is imported here. A tool run as a script calls
:func:`quiet_interrupts` right after importing this module, so that Ctrl-C or SIGTERM
during its start-up imports ends it with the same line and code 130 instead of a
traceback; :func:`guarded` then restores the usual KeyboardInterrupt. The module lives
in :mod:`mre_common` so that both layers may use it (``python -m components.build`` too);
:mod:`orchestration.cli` adds the engine's error types.
"""

from __future__ import annotations

import os
import sys

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing: a tool imports this module first,
if TYPE_CHECKING:  # before its Ctrl-C handler is set, so it imports nothing that is not loaded at start-up
    import signal  # the type checker reads signal's stubs; _signal (its C core) has none
    from collections.abc import Callable, Sequence
else:  # signal.py's C core: signal.py imports enum and builds its enums, and this module is imported
    import _signal as signal  # before the Ctrl-C handler exists (quiet_interrupts)

# The exit codes of every command-line tool (the one table: orchestration.console and orchestration.cli import it)
EXIT_OK = 0  # done: the run (or the tool's work) is complete
EXIT_FAILED = 1  # the work ran and failed (a unit's error, a write failure): partial results are kept
EXIT_USAGE = 2  # a problem the user can fix (arguments, scenario, configuration): nothing written
EXIT_BUG = 3  # an internal error: one line names the log file with the traceback
EXIT_INTERRUPTED = 130  # Ctrl-C or SIGTERM before anything was written

EPILOG_COMMON = ("3 internal error, a bug (one line names the log file with the traceback); 130 interrupted "
                 "before anything was written")
"""The end of every tool's exit-code epilog."""

CRASH_DIR_ENV = "MRE_COSIM_CRASH_DIR"
"""Folder for crash logs (default: the temporary folder)."""


class UsageError(Exception):
    """A problem the user can fix, reported as ``error: <message>`` with exit code 2 (nothing written)."""


ErrorTypes = tuple[type[BaseException], ...]


_invoked_as: str | None = None


def set_invoked_as(name: str | None) -> None:
    """The command a user typed for the tool about to run (``mre-cosim run``), shown in its usage lines."""
    global _invoked_as
    _invoked_as = name


def invoked_as(script: str) -> str:
    """A tool's program name for argparse: ``mre-cosim TOOL`` when the console command runs it, else ``script``."""
    return _invoked_as or script


def _stdout_closed() -> bool:
    """True if standard output's reader has gone (its pipe is broken); stdout then points at /dev/null, so that
    the interpreter's own flush at exit prints nothing either."""
    import select  # built in

    try:
        fd = sys.stdout.fileno()
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        if not any(event & select.POLLERR for _, event in poller.poll(0)):  # a pipe without reader: POLLERR
            return False
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
        return True
    except (OSError, ValueError, AttributeError):
        return False


def crash_log(prog: str, exc: BaseException, argv: Sequence[str] | None) -> str | None:
    """Write the traceback of an unexpected error to a new log file; its path, or None if none could be written."""
    import platform
    import tempfile
    import time
    import traceback

    folder = os.environ.get(CRASH_DIR_ENV) or tempfile.gettempdir()
    stamp = time.strftime("%Y%m%dT%H%M%S")
    name = os.path.splitext(os.path.basename(prog))[0].replace(" ", "_")
    try:
        fd, path = tempfile.mkstemp(prefix=f"mre-cosim-{name}-crash-{stamp}-", suffix=".log", dir=folder)
        with os.fdopen(fd, "w", errors="replace") as f:
            f.write(f"{prog}: internal error (a bug)\n")
            f.write(f"command: {[sys.executable, *sys.argv] if argv is None else [prog, *argv]}\n")
            f.write(f"working folder: {os.getcwd()}\n")
            f.write(f"python {platform.python_version()} on {platform.platform()}\n\n")
            f.write("".join(traceback.format_exception(exc)))
    except (OSError, ValueError):
        return None
    return path


def one_line(exc: BaseException) -> str:
    """The message of a user-reachable error: ``exc.report()`` when it has one, else ``error: <exc>``."""
    report = getattr(exc, "report", None)
    if callable(report):
        return str(report())
    if isinstance(exc, OSError) and exc.strerror:
        where = f"{exc.filename}: " if exc.filename else ""
        return f"error: {where}{exc.strerror}"
    text = str(exc).strip() or type(exc).__name__
    return f"error: {text}"


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _exit_at_startup(signum: int, frame: object) -> None:
    _print(f"{os.path.basename(sys.argv[0]) or 'mre-cosim'}: interrupted while starting; nothing written")
    os._exit(EXIT_INTERRUPTED)  # nothing to clean up yet; unwinding half-done imports could print tracebacks


def quiet_interrupts() -> None:
    """Until :func:`guarded` starts, end the process on Ctrl-C or SIGTERM with one line and code 130."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            if signal.getsignal(sig) is not signal.SIG_IGN:  # an ignored signal (nohup, `&`) stays ignored
                signal.signal(sig, _exit_at_startup)
        except ValueError:  # not the main thread
            return


def guarded(
    work: Callable[[list[str] | None], int],
    argv: list[str] | None,
    prog: str,
    user_errors: Callable[[], ErrorTypes] | ErrorTypes = (),
) -> int:
    """Run a tool's ``work(argv)`` and map every way it can end to the documented exit code.

    ``user_errors``: the exception types the user can cause (or a function returning them,
    so that they are imported only when needed); :class:`UsageError` always is one.
    SIGTERM raises KeyboardInterrupt while ``work`` runs, unless ``work`` installs its own
    handler (a run does, to stop at a step boundary and keep partial results); the
    previous handler is restored afterwards.
    """
    previous = None
    try:
        if signal.getsignal(signal.SIGINT) is _exit_at_startup:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        current = signal.getsignal(signal.SIGTERM)
        if current is not signal.SIG_IGN:
            signal.signal(signal.SIGTERM, _interrupt)
            previous = signal.SIG_DFL if current is _exit_at_startup else current
    except ValueError:  # not the main thread: leave signals alone
        previous = None
    try:
        return work(argv)
    except SystemExit:
        raise  # argparse: --help (0) and usage errors (2)
    except KeyboardInterrupt:
        _print(f"{prog}: interrupted; nothing written")
        return EXIT_INTERRUPTED
    except BaseException as exc:
        try:
            types = user_errors() if callable(user_errors) else user_errors
        except Exception:
            types = ()
        if isinstance(exc, (UsageError, *types)):
            _print(one_line(exc))
            return EXIT_USAGE
        if not isinstance(exc, Exception):
            raise  # GeneratorExit and other interpreter-level signals
        import errno  # built in, like _signal

        if isinstance(exc, BrokenPipeError) and _stdout_closed():  # `tool --help | head`: the reader left
            return EXIT_FAILED
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):  # the disk, not a bug
            where = f" {exc.filename}" if exc.filename else " its output"
            _print(f"{prog}: could not write{where}: {exc.strerror or exc}; the output is incomplete (every file "
                   "written before is whole and kept, the one being written is not; free space and run again)")
            return EXIT_FAILED
        log = crash_log(prog, exc, argv)
        if log is not None:
            where = f"traceback in {log}"
        else:
            import traceback

            where = "no log file could be written:\n" + "".join(traceback.format_exception(exc))
        _print(f"{prog}: internal error (this is a bug, please report it): {type(exc).__name__}: "
               f"{_first_line(exc)}; {where}")
        return EXIT_BUG
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0][:300] if text else "(no message)"


def _print(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass  # stderr closed: the exit code still tells
