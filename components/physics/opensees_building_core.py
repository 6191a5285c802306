"""A building modelled in OpenSees (McKenna et al., OpenSees, PEER/UC Berkeley; its Python
interpreter OpenSeesPy, Zhu et al. 2018, SoftwareX 7:6-11), stepped from a co-simulation.

The user's **model script** is a Python file that builds an OpenSeesPy model and declares
where the building is. Convention (checked when the model is built; a violation is a
:class:`ModelScriptError` naming the script):

- The script builds the model with OpenSeesPy commands, either through the name ``ops``
  (the unit puts ``openseespy.opensees`` there) or after ``import openseespy.opensees as ops``
  (works too: the unit imports it first). The model is wiped before the script runs.
- ``BASE_NODE = <tag>``: the base floor. The isolator force acts on it; it must be free in
  DOF 1 and carry mass.
- ``FLOOR_NODES = [<tag>, ...]``: floors 1..n, bottom to top (n must equal the unit's
  number of storeys).
- Masses with ``ops.mass(node, m, ...)`` on the base and floor nodes [kg]; DOF 1 is the
  horizontal direction of the excitation. Other nodes may carry mass (the ground motion
  loads them), but the storey shears are computed from the floor masses (below).
- ``LINEAR = True`` (optional): the model is linear; each sub-step is one linear solve
  (OpenSees ``algorithm Linear``) instead of Newton iterations.
- The script builds the model only: no load patterns, no analysis. Time series and
  pattern tags 900001-900002 and parameter tags 900001-900002 are the unit's.
- Units: SI (m, kg, s, N), like every boundary of the toolkit.

Loads and stepping. Coordinates are relative to the ground. The ground acceleration ag
[m/s^2] is a ``UniformExcitation`` pattern in DOF 1 (OpenSees applies -M 1 ag) whose
``Constant`` acceleration series has its factor set to ag before each step (``parameter`` /
``updateParameter``); the isolator force F [N] is a nodal load -F on the base node in a
``Plain`` pattern, its value set the same way. This is the shear building's equation,
M x'' + C x' + f_s(x) = -e_0 F - M 1 ag (:mod:`shear_building_core`), with OpenSees'
restoring forces. Inputs are held over the communication step, as by the shear building.

Each communication step h is ``substeps`` steps of OpenSees' transient analysis with
Newmark's average-acceleration integrator (Newmark 1959, J. Eng. Mech. Div. ASCE 85(EM3); gamma = 1/2,
beta = 1/4: unconditionally stable,
no numerical damping, period error about (omega dt)^2 / 12) and Newton iterations
(``NormDispIncr`` 1e-10 m, 25 iterations), or the Linear algorithm for ``LINEAR`` models.
Newmark interpolates the load linearly between the previous and the present step's end,
so an input that jumps at a communication point is seen as a ramp over the first
sub-step; ``zoh = True`` (the default) makes that first sub-step ``h * ZOH_FRACTION`` long,
so the load is held over the whole step as the shear building's exact ZOH does. A
sub-step that fails to converge is retried as ``RETRY_REFINEMENT`` shorter steps; if that
fails too, :class:`StepFailure` names the time and OpenSees' message.

Outputs (:meth:`OpenSeesBuilding.output_vector`, in the order of the shear building's):
per level (base, floors) x [m], v [m/s] relative to the ground, absolute acceleration a
[m/s^2] and relative acceleration arel [m/s^2]; per storey j >= 1 drift x_j - x_{j-1} [m]
and shear [N], shear_j = -sum_{i >= j} m_i a_i (the inertia of the floors above: the
storey's spring-plus-dashpot force in a shear building whose masses are at its floors).
Accelerations depend directly on the inputs: OpenSees' accelerations after a step hold for
the inputs of that step; for new inputs the lumped floor masses give arel_i - (ag - ag_s)
- e_0 (F - F_s) / m_0.

OpenSees keeps one model per process, so one :class:`OpenSeesBuilding` may live per
process; a second one is refused (:class:`ProcessBusy`) until the first is closed.

Some openseespy Linux wheels (openseespylinux 3.7) bundle liblapack without a run path to
the libblas beside it, so ``import openseespy.opensees`` fails; :func:`import_opensees`
then preloads the bundled libraries (``ctypes.CDLL(..., RTLD_GLOBAL)``) and imports again.
"""

from __future__ import annotations

import atexit
import ctypes
import gc
import importlib
import importlib.util
import math
import os
import sys
import tempfile
import traceback
import weakref
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

PATTERN_GROUND = 900001  # also its time series and parameter tag
PATTERN_FORCE = 900002
ZOH_FRACTION = 1e-3  # length of the load-jump sub-step relative to the communication step
RETRY_REFINEMENT = 10  # a failed sub-step is retried as this many shorter ones
NEWTON_TOLERANCE = 1e-10  # [m] norm of the displacement increment (0.1 nm)
NEWTON_ITERATIONS = 25
MAX_SCRIPT_BYTES = 4 * 1024 * 1024  # a model script is source code; a larger file is a mistake
INSTALL_HINT = "install it with: pip install -e \".[opensees]\" (or pip install openseespy)"
# Bundled native libraries, loaded in this order when the first import fails (dependencies first).
_BUNDLED_LIBRARY_PREFIXES = ("libquadmath", "libgfortran", "libgomp", "libopenblas", "libblas", "liblapack")


class OpenSeesUnavailable(ImportError):
    """openseespy is missing or cannot be imported on this machine."""


class ModelScriptError(ValueError):
    """The model script raised, or does not follow the convention (message names the script and line)."""


class StepFailure(RuntimeError):
    """OpenSees' transient analysis did not converge (message names the time and OpenSees' words)."""


class ProcessBusy(RuntimeError):
    """Another OpenSees building lives in this process (OpenSees keeps one model per process)."""


def _bundled_library_folders() -> list[Path]:
    """Folders of native libraries shipped inside the openseespy wheels (found without importing them)."""
    folders = []
    for name in ("openseespylinux", "openseespy"):
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
        if spec is None or not spec.submodule_search_locations:
            continue
        for location in spec.submodule_search_locations:
            package = Path(location)
            folders += [package / "lib", package / ".libs", package.parent / f"{name}.libs"]
    return [f for f in folders if f.is_dir()]


def preload_bundled_libraries() -> list[str]:
    """Load the BLAS/LAPACK (and Fortran runtime) libraries bundled with openseespy, globally.

    Returns the files loaded. Best effort: a library that does not load is skipped.
    """
    loaded = []
    for folder in _bundled_library_folders():
        files = sorted(p for p in folder.iterdir() if ".so" in p.name)
        for prefix in _BUNDLED_LIBRARY_PREFIXES:
            for path in files:
                if path.name.startswith(prefix):
                    try:
                        ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
                        loaded.append(str(path))
                    except OSError:
                        pass
    return loaded


def import_opensees() -> Any:
    """``openseespy.opensees``, preloading its bundled BLAS if the plain import fails.

    Raises :class:`OpenSeesUnavailable` with the reason and the way to install it.
    """
    try:
        return importlib.import_module("openseespy.opensees")
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0].startswith("openseespy"):
            raise OpenSeesUnavailable(f"the OpenSees building unit needs openseespy in the Python of "
                                      f"{sys.executable}; {INSTALL_HINT}") from None
        first: BaseException = exc
    except (ImportError, RuntimeError, OSError) as exc:
        first = exc
    loaded = preload_bundled_libraries()
    for name in [m for m in sys.modules if m.startswith("openseespy")]:
        if name != "openseespy":
            sys.modules.pop(name, None)
    try:
        return importlib.import_module("openseespy.opensees")
    except (ImportError, RuntimeError, OSError) as exc:
        cause = exc.__context__ or first.__context__ or exc
        raise OpenSeesUnavailable(
            f"openseespy is installed but does not import ({cause}); preloaded {len(loaded)} bundled "
            f"libraries without success. Reinstall it for this Python ({sys.version.split()[0]}): {INSTALL_HINT}"
        ) from None


# -- one model per process ------------------------------------------------------------------------------
# The owner lives on the openseespy.opensees module itself: the core may be imported twice in one
# process (as components.physics.opensees_building_core and, inside an FMU, by its bare name),
# but there is one OpenSees model.
_OWNER_ATTRIBUTE = "_mre_cosim_opensees_building"


def _owner() -> OpenSeesBuilding | None:
    """The OpenSees building living in this process, if any."""
    ops = sys.modules.get("openseespy.opensees")
    ref = getattr(ops, _OWNER_ATTRIBUTE, None) if ops is not None else None
    owner = ref() if ref is not None else None
    return owner if owner is not None and not owner.closed else None


def busy_reason() -> str | None:
    """Why a new OpenSees building cannot be created in this process now, or None if it can."""
    if _owner() is not None:
        gc.collect()  # an owner freed by its host may only wait for the cycle collector
    owner = _owner()
    if owner is None:
        return None
    return (f"an OpenSees building ({owner.script}) already runs in this process, and OpenSees keeps one "
            f"model per process: run one OpenSeesBuilding per process (studies run each simulation in its own)")


SCRIPT_CHECK_TIMEOUT_S = 60.0
"""Longest a model script may take to build its model in the check before a run [s]."""
SCRIPT_CHECK_ENV = "MRE_COSIM_SCRIPT_CHECK_TIMEOUT_S"
"""Environment variable that sets another bound [s] (a positive number)."""
_CHECK_FLAG = "--check-model-script"


def check_timeout() -> float:
    """The bound of a script check [s]: ``$MRE_COSIM_SCRIPT_CHECK_TIMEOUT_S`` if a positive number, else the default."""
    try:
        value = float(os.environ.get(SCRIPT_CHECK_ENV, ""))
    except ValueError:
        return SCRIPT_CHECK_TIMEOUT_S
    return value if math.isfinite(value) and value > 0 else SCRIPT_CHECK_TIMEOUT_S


def check_script(script: Path | str, n_storeys: int | None = None, timeout_s: float | None = None) -> str | None:
    """Problem text if the model script raises or breaks the convention (or openseespy is missing), else None.

    For a check before a run: the script builds its model in a **child process** (this file run as a
    program), bounded by ``timeout_s`` (default :func:`check_timeout`), so that a script that never ends, ends
    the process (``sys.exit``, ``os._exit``), changes the working folder (``os.chdir``) or crashes cannot stop
    the caller, move its output or leave it without a message: each is a problem naming the script.
    ``n_storeys``: the unit's storey count, which the script's FLOOR_NODES must match (None: any).
    """
    script = Path(os.path.abspath(script))
    timeout_s = check_timeout() if timeout_s is None else timeout_s
    try:
        st = os.stat(script)
        key = (str(script), st.st_size, st.st_mtime_ns, n_storeys)
    except OSError:
        key = None
    if key in _CHECKED:  # a study plans each run: one child per script and version
        return _CHECKED[key]
    verdict = _check_script_in_child(script, n_storeys, timeout_s)
    if key is not None and (verdict is None or "did not finish" not in verdict):
        _CHECKED[key] = verdict
    return verdict


_CHECKED: dict[Any, str | None] = {}  # (path, size, mtime, storeys) -> verdict of check_script


def _check_script_in_child(script: Path, n_storeys: int | None, timeout_s: float) -> str | None:
    import subprocess

    with tempfile.TemporaryDirectory(prefix="mre-cosim-script-check-") as tmp:
        result, output = Path(tmp) / "result.txt", Path(tmp) / "output.txt"
        command = [sys.executable, str(Path(__file__).resolve()), _CHECK_FLAG, str(script), str(n_storeys or 0),
                   str(result)]
        try:
            with open(output, "wb") as out:
                done = subprocess.run(command, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                      timeout=timeout_s, check=False)
        except subprocess.TimeoutExpired:
            return (f"OpenSees model script {script} did not finish building its model within {timeout_s:g} s "
                    f"(a loop that never ends?); the check was stopped (set {SCRIPT_CHECK_ENV} for a longer bound)")
        except OSError as exc:
            return f"OpenSees model script {script}: cannot start the check of it: {exc.strerror or exc}"
        try:
            verdict = result.read_text(encoding="utf-8")
        except OSError:
            said = _tail(output)
            how = f"exit code {done.returncode}" if done.returncode >= 0 else f"signal {-done.returncode}"
            return (f"OpenSees model script {script} ended the process ({how}) before its model was built: a model "
                    "script must not call sys.exit, os._exit or end the interpreter otherwise"
                    + (f" (it printed: {said})" if said else ""))
    return verdict or None


def _tail(path: Path, limit: int = 300) -> str:
    """The last ``limit`` characters of a text file, on one line ('' if unreadable)."""
    try:
        with open(path, "rb") as f:
            f.seek(max(0, os.path.getsize(path) - limit))
            return " ".join(f.read().decode("utf-8", "replace").split())
    except OSError:
        return ""


def _check_in_child(script: str, n_storeys: int, result: str) -> None:
    """The child's side of :func:`check_script`: build the model, write the verdict ('' if sound) to ``result``."""
    cwd = os.getcwd()
    try:
        OpenSeesBuilding(script, n_storeys or None).close()
        verdict = ""
    except (ModelScriptError, OpenSeesUnavailable) as exc:
        verdict = str(exc)
    if not verdict and os.getcwd() != cwd:
        verdict = (f"OpenSees model script {script} changes the working folder (to {os.getcwd()}): a model script "
                   "must not call os.chdir (relative paths, the run's output among them, would move)")
    with open(result, "w", encoding="utf-8") as f:
        f.write(verdict)


def substeps_problem(substeps: Any) -> str | None:
    """Why ``substeps`` (Newmark steps per communication step) is out of its domain, or None."""
    if isinstance(substeps, bool) or int(substeps) != substeps or not 1 <= substeps <= 10_000:
        return f"substeps must be an integer from 1 to 10000, got {substeps!r}"
    return None


def parameter_problem(values: Mapping[str, Any], n_storeys: int | None = None) -> tuple[str, str] | None:
    """(parameter, message) for the unit's parameters (``script``, ``substeps``) before any run, or None.

    The script is run in a child process, bounded in time, as the unit runs it when it initializes
    (:func:`check_script`): a script that raises, ends the process, never ends, changes the working folder or
    declares no base node is refused up front.
    """
    text = substeps_problem(values.get("substeps", 1))
    if text is not None:
        return "substeps", text
    script = str(values.get("script", ""))
    if not script:
        return "script", "parameter 'script' is not set: name an OpenSeesPy model script"
    text = check_script(script, n_storeys)
    return ("script", text) if text is not None else None


# -- the model script --------------------------------------------------------------------------------------
def _script_line(exc: BaseException, script: Path) -> int | None:
    """Line of the script where ``exc`` arose (innermost frame in the script), if any."""
    if isinstance(exc, SyntaxError) and exc.filename == str(script):
        return exc.lineno
    line = None
    for frame in traceback.extract_tb(exc.__traceback__):
        if frame.filename == str(script):
            line = frame.lineno
    return line


def run_script(ops: Any, script: Path, log: LogTail | None = None) -> dict[str, Any]:
    """Wipe the model, execute the script and return its namespace; :class:`ModelScriptError` if it raises."""
    try:
        source = script.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelScriptError(f"OpenSees model script {script}: cannot read it: {exc}") from None
    ops.wipe()
    namespace: dict[str, Any] = {"__name__": "__opensees_model__", "__file__": str(script), "ops": ops}
    try:
        code = compile(source, str(script), "exec")
        exec(code, namespace)
    except (Exception, SystemExit) as exc:
        line = _script_line(exc, script)
        where = f"{script}, line {line}" if line else str(script)
        said = log.read() if log is not None else ""
        detail = f" (OpenSees: {said})" if said else ""
        raise ModelScriptError(f"OpenSees model script {where}: {type(exc).__name__}: {exc}{detail}") from None
    return namespace


def _node_tag(value: Any, what: str, script: Path) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ModelScriptError(f"OpenSees model script {script}: {what} must be a node tag (an integer), "
                               f"got {value!r}")
    return int(value)


class LogTail:
    """OpenSees' messages (its ``logFile``, not echoed): the new part since the last read.

    One per process (:meth:`of`): OpenSees echoes again after a second ``logFile`` command. The
    file is unlinked as soon as both OpenSees and this reader have it open (nothing is left
    behind; on systems that cannot unlink an open file it is removed at exit).
    """

    _ATTRIBUTE = "_mre_cosim_opensees_log"

    def __init__(self, ops: Any) -> None:
        fd, name = tempfile.mkstemp(prefix="opensees-", suffix=".log")
        os.close(fd)
        ops.logFile(name, "-noEcho")
        self._reader = open(name, "rb")  # kept open for the process's life
        try:
            os.unlink(name)
        except OSError:
            atexit.register(lambda: Path(name).unlink(missing_ok=True))

    @classmethod
    def of(cls, ops: Any) -> LogTail:
        """The process's log reader, set up on first use."""
        log = getattr(ops, cls._ATTRIBUTE, None)
        if log is None:
            log = cls(ops)
            setattr(ops, cls._ATTRIBUTE, log)
        return log

    def read(self, limit: int = 600) -> str:
        """New messages, joined on one line and cut to ``limit`` characters from the end."""
        try:
            data = self._reader.read()
        except OSError:
            return ""
        text = " ".join(data.decode("utf-8", "replace").split())
        return text if len(text) <= limit else "..." + text[-limit:]

    def skip(self) -> None:
        """Forget the messages so far."""
        try:
            self._reader.seek(0, os.SEEK_END)
        except OSError:
            pass


class OpenSeesBuilding:
    """An OpenSees model of a building on a base floor, stepped with inputs (ag, F) held over each step.

    ``OpenSeesBuilding(script, n_storeys=None, substeps=1, zoh=True)`` runs the model script
    (see the module docstring); ``step(ag, F, h)`` advances by h [s]; ``output_vector(ag, F)``
    gives the outputs; ``close()`` frees the process's OpenSees model for another building.
    """

    def __init__(self, script: Path | str, n_storeys: int | None = None, substeps: int = 1, zoh: bool = True) -> None:
        self.script = Path(script)
        self.closed = True
        text = substeps_problem(substeps)
        if text is not None:
            raise ValueError(text)
        try:
            size = self.script.stat().st_size if self.script.is_file() else None
        except OSError as exc:
            raise ModelScriptError(f"OpenSees model script {self.script}: cannot read it: "
                                   f"{exc.strerror or exc}") from None
        if size is None:
            raise ModelScriptError(f"OpenSees model script {self.script} does not exist or is not a regular file")
        if size > MAX_SCRIPT_BYTES:
            raise ModelScriptError(f"OpenSees model script {self.script} is {size:,} bytes, more than the "
                                   f"{MAX_SCRIPT_BYTES:,} a model script may have")
        reason = busy_reason()
        if reason is not None:
            raise ProcessBusy(reason)
        self.ops = ops = import_opensees()
        self.substeps = int(substeps)
        self.zoh = bool(zoh)
        setattr(ops, _OWNER_ATTRIBUTE, weakref.ref(self))
        self.closed = False
        self._log = LogTail.of(ops)
        self._log.skip()
        try:
            namespace = run_script(ops, self.script, self._log)
            self._declare(namespace, n_storeys)
            self._setup_analysis(bool(namespace.get("LINEAR", False)))
        except BaseException:
            self.close()
            raise
        self._log.skip()
        self.steps = 0
        self.time = 0.0  # time advanced so far [s]
        self._ag_s = 0.0  # inputs of the last step
        self._F_s = 0.0
        self._inputs = (math.nan, math.nan)  # as last set in OpenSees
        self._read_state()

    # -- setup -----------------------------------------------------------------------------------------
    def _declare(self, namespace: dict[str, Any], n_storeys: int | None) -> None:
        ops, script = self.ops, self.script
        if "BASE_NODE" not in namespace:
            raise ModelScriptError(f"OpenSees model script {script} defines no BASE_NODE: set BASE_NODE = <tag of "
                                   f"the base floor node> (and FLOOR_NODES = [floor 1, ..., roof])")
        base = _node_tag(namespace["BASE_NODE"], "BASE_NODE", script)
        floors_raw = namespace.get("FLOOR_NODES")
        if not isinstance(floors_raw, list | tuple) or not floors_raw:
            raise ModelScriptError(f"OpenSees model script {script}: FLOOR_NODES must be a non-empty list of node "
                                   f"tags, floor 1 to the roof, got {floors_raw!r}")
        floors = [_node_tag(v, "each of FLOOR_NODES", script) for v in floors_raw]
        if n_storeys is not None and len(floors) != n_storeys:
            raise ModelScriptError(f"OpenSees model script {script} declares {len(floors)} floors; this unit has "
                                   f"{n_storeys} storeys (build a variant: python -m components.build --storeys "
                                   f"{len(floors)})")
        nodes = [base, *floors]
        if len(set(nodes)) != len(nodes):
            raise ModelScriptError(f"OpenSees model script {script}: BASE_NODE and FLOOR_NODES repeat a node: {nodes}")
        existing = set(ops.getNodeTags())
        missing = [n for n in nodes if n not in existing]
        if missing:
            raise ModelScriptError(f"OpenSees model script {script}: node(s) {missing} declared in BASE_NODE/"
                                   f"FLOOR_NODES do not exist in the model")
        masses = [float(ops.nodeMass(n, 1)) for n in nodes]
        massless = [n for n, m in zip(nodes, masses, strict=True) if not m > 0]
        if massless:
            raise ModelScriptError(f"OpenSees model script {script}: node(s) {massless} have no mass in DOF 1 "
                                   f"(set it with ops.mass(node, m, ...) [kg])")
        fixed = [n for n in nodes if n in set(ops.getFixedNodes()) and 1 in ops.getFixedDOFs(n)]
        if fixed:
            raise ModelScriptError(f"OpenSees model script {script}: node(s) {fixed} are fixed in DOF 1; the base "
                                   f"and the floors must be free to move")
        self.base_node = base
        self.floor_nodes = floors
        self.nodes = nodes
        self.masses = np.asarray(masses)
        self.n_levels = len(nodes)

    def _setup_analysis(self, linear: bool) -> None:
        ops = self.ops
        try:
            ops.timeSeries("Constant", PATTERN_GROUND, "-factor", 0.0)
            ops.pattern("UniformExcitation", PATTERN_GROUND, 1, "-accel", PATTERN_GROUND)
            ops.parameter(PATTERN_GROUND, "loadPattern", PATTERN_GROUND, "factor")
            ops.timeSeries("Constant", PATTERN_FORCE)
            ops.pattern("Plain", PATTERN_FORCE, PATTERN_FORCE)
            ndf = len(ops.nodeDisp(self.base_node))
            ops.load(self.base_node, *([0.0] * ndf))
            ops.parameter(PATTERN_FORCE, "loadPattern", PATTERN_FORCE, "loadAtNode", self.base_node, 1)
            ops.constraints("Transformation")
            ops.numberer("RCM")
            ops.system("BandGeneral")
            ops.test("NormDispIncr", NEWTON_TOLERANCE, NEWTON_ITERATIONS)
            ops.algorithm("Linear" if linear else "Newton")
            ops.integrator("Newmark", 0.5, 0.25)
            ops.analysis("Transient")
        except Exception as exc:
            said = self._log.read()
            raise ModelScriptError(f"OpenSees model script {self.script}: the unit cannot set up its loads and "
                                   f"analysis on this model ({exc}; OpenSees: {said or 'no message'}); does the "
                                   f"script define load patterns or time series with tags {PATTERN_GROUND}-"
                                   f"{PATTERN_FORCE}?") from None
        self.linear = linear

    # -- stepping --------------------------------------------------------------------------------------
    def _set_inputs(self, ag: float, F: float) -> None:
        if (ag, F) != self._inputs:
            self.ops.updateParameter(PATTERN_GROUND, float(ag))
            self.ops.updateParameter(PATTERN_FORCE, -float(F))
            self._inputs = (ag, F)

    def _analyze(self, n: int, dt: float) -> bool:
        """n transient steps of dt; a failed one is retried as RETRY_REFINEMENT shorter ones."""
        ops = self.ops
        for _ in range(n):
            if ops.analyze(1, dt) != 0 and ops.analyze(RETRY_REFINEMENT, dt / RETRY_REFINEMENT) != 0:
                return False
        return True

    def step(self, ag: float, F: float, h: float) -> None:
        """Advance by h [s] with the ground acceleration ag [m/s^2] and isolator force F [N] held."""
        if self.closed:
            raise RuntimeError("the OpenSees building was closed")
        self._set_inputs(ag, F)
        dt = h / self.substeps
        if self.zoh:
            jump = h * ZOH_FRACTION
            ok = self._analyze(1, jump) and self._analyze(1, dt - jump) and self._analyze(self.substeps - 1, dt)
        else:
            ok = self._analyze(self.substeps, dt)
        if not ok:
            said = self._log.read()
            raise StepFailure(f"OpenSees' transient analysis failed to converge in the step from t = "
                              f"{self.time:.6g} s (h = {h:g} s, also with {RETRY_REFINEMENT}x shorter steps): "
                              f"{said or 'no message from OpenSees'}")
        self.time += h
        self.steps += 1
        self._ag_s, self._F_s = ag, F
        self._read_state()

    def _read_state(self) -> None:
        ops = self.ops
        self._x = np.array([ops.nodeDisp(n, 1) for n in self.nodes])
        self._v = np.array([ops.nodeVel(n, 1) for n in self.nodes])
        self._arel_s = np.array([ops.nodeAccel(n, 1) for n in self.nodes])

    # -- outputs ---------------------------------------------------------------------------------------
    def relative_acceleration(self, ag: float, F: float) -> np.ndarray:
        """Relative accelerations per level [m/s^2] for the present state and the inputs (ag, F)."""
        arel = self._arel_s - (ag - self._ag_s)
        arel[0] -= (F - self._F_s) / self.masses[0]
        return arel

    def output_vector(self, ag: float, F: float) -> np.ndarray:
        """[x (N), v (N), a absolute (N), a relative (N), drift (N-1), shear (N-1)], N levels (base first)."""
        arel = self.relative_acceleration(ag, F)
        a = arel + ag
        inertia = self.masses[1:] * a[1:]
        shear = -np.cumsum(inertia[::-1])[::-1]
        return np.concatenate((self._x, self._v, a, arel, np.diff(self._x), shear))

    @property
    def x(self) -> np.ndarray:
        """Relative displacements per level [m] (a copy)."""
        return self._x.copy()

    def close(self) -> None:
        """Wipe the OpenSees model and let another building use the process."""
        if self.closed:
            return
        self.closed = True
        try:
            self.ops.wipe()
        except Exception:
            pass
        ref = getattr(self.ops, _OWNER_ATTRIBUTE, None)
        if ref is not None and ref() is self:
            setattr(self.ops, _OWNER_ATTRIBUTE, None)

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass


if __name__ == "__main__" and len(sys.argv) == 5 and sys.argv[1] == _CHECK_FLAG:  # the child of check_script
    _check_in_child(sys.argv[2], int(sys.argv[3]), sys.argv[4])
