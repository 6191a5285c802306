"""Shell glue of the FMUs that carry a module other FMUs carry too: refuse another FMU's copy with other code.

pythonfmu FMUs share the host's interpreter, which imports a module once under its bare name: the copy the
first FMU loaded serves every FMU that imports that name (``mre_isolator_core``, the isolator law, travels in
the isolator, SOSM and model-based controller FMUs; ``dyke_building``, the building table, in those and the
building FMU). A shared module records its source when it is loaded (``LOADED_SOURCE``: the folder it came from
may be gone by the time another FMU asks), and :func:`copy_problem` compares it with the calling FMU's own copy
in its resources folder, before the unit runs.

Not an FMU itself (no ``_fmu.py``): listed in ``FMU_CORE_MODULES`` of every shell that imports it, and imported
by bare name. No state.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType

with open(__file__, "rb") as _source:
    LOADED_SOURCE = _source.read()


def copy_problem(modules: Iterable[ModuleType], resources: str | None) -> str:
    """A text if one of ``modules`` (or this one) was loaded from another FMU with other code than the calling
    FMU's own copy in ``resources`` (its folder), else "". Each module has ``LOADED_SOURCE`` (bytes)."""
    if not resources:
        return ""
    for module in (*modules, sys.modules[__name__]):
        loaded = Path(module.__file__)
        own = Path(resources) / loaded.name
        if own.is_file() and own.resolve() != loaded.resolve() and own.read_bytes() != module.LOADED_SOURCE:
            return (f"another FMU in this process loaded a different version of the module {loaded.stem} "
                    f"(from {loaded.parent}); use FMUs built from the same project version")
    return ""
