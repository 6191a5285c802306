"""The generic co-simulation engine: scenarios, FMU units, coupling algorithm, execution, recording.

It knows FMUs only through their model descriptions and imports nothing from ``components``
or from the applications (``orchestration.studies``, ``orchestration.interop``, the CLIs).
"""
