"""The generic co-simulation engine: scenarios, FMU units, coupling algorithm, execution, recording, run folder.

It knows FMUs only through their model descriptions and recorded variables only by name, and
imports nothing from ``components`` or from the applications (``orchestration.case_study``,
``orchestration.ida_study``, ``orchestration.interop``, the CLIs). What an application adds
(building FMUs, checking data files, a report section with its summary entries and figures)
it gives through :class:`~orchestration.master.resolve.ResolveHooks`.
"""
