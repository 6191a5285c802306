"""This project's wiring of the generic master: its FMUs built on demand, its records found and checked.

The engine (:mod:`orchestration.master`) knows FMUs only through their model descriptions;
the applications (command-line tools, studies, the Python API) give it these hooks:

* an FMU path in the project's ``fmus/`` folder is built from ``components/`` when it is
  missing or older than its sources (:func:`components.build.project_fmus.ensure_fmu`); when
  that folder is not writable (an installed package) the FMU is built and read in the per-user
  cache folder instead (:func:`mre_common.project_paths.build_location`);
* a bare scenario name (``kobe``) is the shipped scenario of that name (``scenarios/kobe.yaml``,
  in the checkout or where ``pip install .`` put it: :data:`mre_common.project_paths.SCENARIOS_DIR`);
* a ``!record`` file (and a ``!data`` file given as the ground motion's ``record``) is read
  once before the run (a file that is not a record is a scenario error, not a failure at t = 0);
* the records the project ships (``scenarios/records/``) are on the data search path,
  after ``--data-dir`` and ``MRE_COSIM_DATA``;
* a scenario's ``report`` section may name the isolated building's roles and limits, which
  give the summary's peaks and the run's figures (:mod:`orchestration.building_report`);
* a project unit's parameter values outside its domain (each rule in its physics core) are
  scenario errors before any run, not failures at initialization (:mod:`orchestration.parameter_domains`).
"""

from __future__ import annotations

import os
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

from components.build.project_fmus import ensure_fmu
from components.physics.ground_motion_core import RecordError, read_record
from mre_common.project_paths import PROJECT_DIR as PROJECT_DIR  # re-exported: the applications import it here
from mre_common.project_paths import RECORDS_DIR, build_location, shipped_scenario
from mre_common.project_paths import SCENARIOS_DIR as SCENARIOS_DIR
from orchestration.building_report import REPORT
from orchestration.master.errors import Problem, ScenarioError
from orchestration.master.execution import StopRequest
from orchestration.master.resolve import ResolveHooks, SystemPlan, check_environment, resolve
from orchestration.master.scenario import LoadedScenario, load_scenario
from orchestration.master.session import RunOutcome, run_plan
from orchestration.master.unit import UnitDescription
from orchestration.master.yaml_source import load_tree
from orchestration.parameter_domains import parameter_problems
from orchestration.provenance import provenance


def check_record(path: Path) -> str | None:
    """Problem text if ``path`` is not a readable ground-motion record, else None (each file parsed once per
    process while its size and modification time stay the same: a study plans every record many times)."""
    try:
        st = os.stat(path)
    except OSError:
        return _check_record.__wrapped__(str(path), -1, -1)  # no file: not cached
    return _check_record(str(path), st.st_size, st.st_mtime_ns)


@lru_cache(maxsize=1024)
def _check_record(path: str, size: int, mtime_ns: int) -> str | None:
    try:
        read_record(path)
    except RecordError as exc:
        return f"unreadable record: {exc}"
    return None


def data_kind(description: UnitDescription, variable: str) -> str | None:
    """``record`` for the ground-motion source's ``record`` parameter (a file tagged ``!data`` is checked as a
    record too), else None."""
    if description.model_identifier == "GroundMotionSource" and variable == "record":
        return "record"
    return None


HOOKS = ResolveHooks(prepare_fmu=ensure_fmu, data_checks={"record": check_record}, default_data_dirs=(RECORDS_DIR,),
                     provenance=provenance, report=REPORT, data_kind=data_kind, parameter_check=parameter_problems)
CHECK_ONLY = replace(HOOKS, prepare_fmu=None)  # the same checks, no FMU is built


# Top-level keys that only one kind of file has, and the tool that reads it.
FILE_KINDS = {
    "scenario": ({"units", "connections"}, "python orchestration/run.py"),
    "study": ({"records", "strategies"}, "python orchestration/study.py"),
    "identification": ({"identifiers", "ffoa", "fit"}, "python orchestration/identify.py"),
}


def file_kind(path: Path | str) -> str | None:
    """'scenario', 'study' or 'identification' from a YAML file's top-level keys; None if unknown or unreadable."""
    try:
        data, _ = load_tree(Path(path))
    except (ScenarioError, OSError, RecursionError):
        return None
    keys = set(data) if isinstance(data, dict) else set()
    kinds = [kind for kind, (marks, _) in FILE_KINDS.items() if keys & marks]
    return kinds[0] if len(kinds) == 1 else None


def require_kind(path: Path | str, expected: str) -> None:
    """ScenarioError naming the right tool if a YAML file is plainly another kind of file."""
    kind = file_kind(path)
    if kind is not None and kind != expected:
        raise ScenarioError(Problem(f"this is {'an' if kind[0] in 'aeiou' else 'a'} {kind} file, not a {expected} "
                                    f"file: use {FILE_KINDS[kind][1]} {path}", "", str(path)))


def resolve_scenario(loaded: LoadedScenario, data_dirs: tuple[Path, ...] = (), build: bool = True) -> SystemPlan:
    """Check a loaded scenario (YAML or SSP) with the project's hooks; raises ScenarioError.

    ``build=False`` builds no FMU (a missing one is a problem like any other).
    """
    fmus_where_built(loaded)
    return scripts_as_data_files(resolve(loaded, data_dirs, HOOKS if build else CHECK_ONLY))


def fmus_where_built(loaded: LoadedScenario) -> None:
    """Each unit's FMU in the project's ``fmus/`` folder named by its build location
    (:func:`mre_common.project_paths.build_location`: the same file in a writable checkout; the per-user
    cache folder when installed), so that it is built, checked and run there."""
    for name, spec in list(loaded.scenario.units.items()):
        path = loaded.fmu_path(name)
        target = build_location(path)
        if target != path:
            loaded.scenario.units[name] = spec.model_copy(update={"fmu": str(target)})


def scripts_as_data_files(plan: SystemPlan) -> SystemPlan:
    """A unit's script given as a plain path (not ``!data``) made one of the plan's data files: its absolute
    path in the parameters (no later ``os.chdir`` moves it), its SHA-256 in the run's manifest, its bytes sent
    to a study's workers like any data file (:data:`orchestration.parameter_domains.SCRIPT_PARAMETERS`)."""
    from orchestration.master.runfolder import sha256
    from orchestration.parameter_domains import script_parameters

    for unit, desc in plan.descriptions.items():
        for name in script_parameters(desc.model_identifier):
            value = plan.parameters.get(unit, {}).get(name)
            key = f"{unit}.{name}"
            if not isinstance(value, str) or not value or key in plan.data_files:
                continue
            path = Path(os.path.abspath(value))
            plan.parameters[unit][name] = str(path)
            plan.data_files[key] = path
            try:
                plan.input_hashes[str(path)] = sha256(path)
            except OSError:
                plan.input_hashes[str(path)] = None
    return plan


def plan_scenario(path: Path | str, overrides: tuple[str, ...] = (), data_dirs: tuple[Path, ...] = ()) -> SystemPlan:
    """Load and check a scenario file or SSP package (builds project FMUs if needed); raises ScenarioError."""
    check_environment()  # MRE_COSIM_* values that mean nothing: refused before any file is read
    path = shipped_scenario(str(path)) or path  # `mre-cosim run kobe`: the shipped scenarios/kobe.yaml
    if Path(path).suffix.lower() == ".ssp":
        from orchestration.interop.ssp_package import load_ssp

        return resolve_scenario(load_ssp(path, overrides), data_dirs)
    try:
        loaded = load_scenario(path, overrides, REPORT.model)
    except ScenarioError:
        require_kind(path, "scenario")  # a study or identification file: name the right tool instead
        raise
    return resolve_scenario(loaded, data_dirs)


def run_scenario(
    path: Path | str,
    overrides: tuple[str, ...] = (),
    out: Path | None = None,
    data_dirs: tuple[Path, ...] = (),
    plots: bool = True,
    progress: bool = False,
    stop: StopRequest | None = None,
) -> RunOutcome:
    """Load, check and run a scenario file; ScenarioError before anything is written."""
    plan = plan_scenario(path, overrides, data_dirs)
    return run_plan(plan, out, plots, progress, stop)
