"""What made a result: this package's version and the source revision it ran from.

Written into every run's ``manifest.json`` (through the resolve hooks of
:mod:`orchestration.engine_hooks`) and into a study's ``study.json``.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from mre_common.project_paths import DISTRIBUTION as PACKAGE
from mre_common.project_paths import PROJECT_DIR as PROJECT_DIR  # re-exported (the checkout or site-packages)
from mre_common.project_paths import git as git  # the one git reader: `git(*args)` in the checkout, or None
from mre_common.project_paths import package_version as package_version  # re-exported: mre-cosim --version


@lru_cache(maxsize=1)
def provenance() -> dict[str, Any]:
    """Package name and version, git commit of the source and whether its code differs from that commit.

    ``version`` is the installed distribution's (``importlib.metadata``; ``unknown`` when the code runs
    from a checkout that was never installed). ``commit`` is None outside a git checkout (an unpacked
    archive, an installed package); ``dirty`` is None then. Only ``components/``, ``orchestration/``,
    ``mre_common/``, ``scenarios/`` and ``pyproject.toml`` count for ``dirty``: run folders and notes in
    the checkout do not change a result.
    """
    commit = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--", "components", "orchestration", "mre_common", "scenarios",
                  "pyproject.toml")
    return {"package": PACKAGE, "version": package_version(), "commit": commit,
            "dirty": None if commit is None or status is None else bool(status)}
