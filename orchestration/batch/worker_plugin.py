"""A Dask worker plugin for the local cluster: workers leave Ctrl-C to the study.

A terminal's Ctrl-C goes to the whole process group: the study's client and the workers
of its embedded cluster. The client cancels what is pending and writes its report, then
closes the cluster; a worker that took the SIGINT itself would only die noisily first.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin


class IgnoreInterrupt(WorkerPlugin):
    """On every worker (also one restarted by its nanny): SIGINT ignored."""

    name = "mre-cosim-ignore-sigint"

    def setup(self, worker: Any) -> None:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
