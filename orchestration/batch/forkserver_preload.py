"""Imported once by each worker's forkserver (:mod:`orchestration.batch.child`): everything a run needs, warm.

Importing this module loads numpy, scipy, fmpy, pythonfmu, the master and the batch
layer's job plumbing (the studies' own job modules are imported just before it, see
``BatchPool(preload=...)``), reads the package versions a run folder's manifest names and loads the
native kernel, so that each forked child starts with all of it in memory, and freezes it
out of the garbage collector's reach (``gc.freeze``). No FMU is loaded here: that is what
each child does on its own.
"""

from __future__ import annotations

import contextlib
import gc
import os

import fmpy.fmi2  # noqa: F401
import numpy as np
import pythonfmu.fmi2slave  # noqa: F401
import scipy.linalg

import orchestration.batch.jobs
import orchestration.master.resolve
import orchestration.master.session  # noqa: F401
from orchestration.master import native_stepper
from orchestration.master.runfolder import package_versions

main = os.environ.get("MRE_COSIM_FORKSERVER_MAIN")  # orchestration.batch.child.MAIN_ENV
if main:  # the parent's main script, once here rather than in every child (multiprocessing would)
    from multiprocessing import process, spawn

    process.current_process()._inheriting = True
    try:
        spawn.import_main_path(main)
    except Exception:  # a child would then import it itself, as multiprocessing does
        pass
    finally:
        del process.current_process()._inheriting
package_versions()
with contextlib.suppress(Exception):  # no compiler: the runs fall back to the Python executor
    native_stepper.kernel_library()
scipy.linalg.expm(np.eye(2))  # the building discretizes with expm
# Keep the garbage collector away from everything loaded so far: a forked child that ran a
# full collection over it would touch (and so copy) every page of it, about 0.8 s a run.
gc.freeze()
