"""The batch layer: jobs fanned out on a Dask cluster (local or remote), knowing no study.

:class:`BatchPool` (pool.py) runs module-level functions on payloads, each optionally in a
forked child of a worker (child.py, forkserver_preload.py); portable.py sends checked plans and
their files to workers without a shared file system and names jobs by content; store.py keeps
finished jobs for ``--resume``; jobs.py runs a plan on a worker and sends its run folder back.
Imports only the engine (``orchestration.master``) and ``mre_common``; the studies import it.
"""

from orchestration.batch.pool import BatchPool, BatchUnavailable, default_workers, map_values

__all__ = ["BatchPool", "BatchUnavailable", "default_workers", "map_values"]
