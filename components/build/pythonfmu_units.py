"""Build the project's pythonfmu FMUs and complete their modelDescription.

Every ``components/shells/*_fmu.py`` holds one ``Fmi2Slave`` shell; its FMU is named after
the class (the model identifier). The shell lists the physics modules of
``components/physics/`` it imports in ``FMU_CORE_MODULES`` (and any shared shell helper of
``components/shells/`` that is no FMU itself, e.g. ``model_based_shell``); they travel in the
FMU's resources under their own (unique) module names, and the shell imports them by that
bare name.

pythonfmu 0.7 writes no units and no output dependencies, so the build rewrites the
modelDescription (:mod:`components.build.model_description`). The Linux binary pythonfmu
0.7 ships has an exit hook that uses freed memory; the build removes it
(:mod:`components.build.exit_fix`). That binary also logs nothing unless the host turned
debug logging on, so on Linux the FMU's ``<model>.so`` is a small shim compiled from
``fmi2_log_shim.c`` that forwards warnings and errors always (and turns a failed step
into fmi2Error when the shell sets ``FMU_FAILED_STEP_STATUS = "error"``); pythonfmu's
library lies beside it as ``<model>.pythonfmu.so``. Without a C compiler the FMU is built
without the shim, with a note on stderr.

Build everything with ``python -m components.build``.
"""

from __future__ import annotations

import functools
import importlib.util
import inspect
import re
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from components.build.exit_fix import ExitHookError, remove_exit_hook
from components.build.model_description import DEFAULT_FMU_DIR, BuildError, complete_model_description
from mre_common.atomic_files import atomic_write
from mre_common.c_compile import CompileFailed, CompilerMissing, compile_c, compiler_name

COMPONENTS_DIR = Path(__file__).resolve().parents[1]
SHELLS_DIR = COMPONENTS_DIR / "shells"
CORES_DIR = COMPONENTS_DIR / "physics"
BUILD_DIR = Path(__file__).resolve().parent
LOG_SHIM_SOURCE = BUILD_DIR / "fmi2_log_shim.c"
INNER_SUFFIX = ".pythonfmu.so"  # pythonfmu's library beside the shim: <model>.pythonfmu.so
SHIM_CFLAGS = ("-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-std=c99", "-Wall", "-Wextra")
FAILED_STEP_STATUSES = ("discard", "error")


@dataclass(frozen=True)
class FmuSource:
    """One buildable FMU: the shell script and the class it holds."""

    script: Path
    class_name: str
    core_modules: tuple[str, ...]
    storeys: int | None = None  # only for shells that take N_STOREYS at build time
    requirements: tuple[str, ...] = ()  # Python packages the unit imports on the host
    handles_state: bool = False  # the shell implements fmi2GetFMUstate/fmi2SetFMUstate
    failed_step_is_error: bool = False  # FMU_FAILED_STEP_STATUS = "error": do_step False -> fmi2Error
    once_per_process: bool = False  # FMU_ONCE_PER_PROCESS = True: canBeInstantiatedOnlyOncePerProcess

    @property
    def fmu_name(self) -> str:
        if self.storeys is None or self.storeys == 3:
            return f"{self.class_name}.fmu"
        return f"{self.class_name}{self.storeys}.fmu"

    @property
    def sources(self) -> list[Path]:
        """Files whose change makes the FMU stale."""
        cores = [module_file(m) for m in self.core_modules]
        return [self.script, *cores, Path(__file__).resolve(), BUILD_DIR / "exit_fix.py",
                BUILD_DIR / "model_description.py", LOG_SHIM_SOURCE]


def module_file(name: str) -> Path:
    """The file of a module listed in ``FMU_CORE_MODULES``: a physics core, else a shared shell helper
    (a module of ``components/shells/`` that is no FMU itself, e.g. ``model_based_shell``)."""
    core = CORES_DIR / f"{name}.py"
    return core if core.is_file() or not (SHELLS_DIR / f"{name}.py").is_file() else SHELLS_DIR / f"{name}.py"


def _load_module(script: Path, module_name: str):
    sys.path[:0] = [str(CORES_DIR), str(SHELLS_DIR)]
    try:
        spec = importlib.util.spec_from_file_location(module_name, script)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(CORES_DIR))
        sys.path.remove(str(SHELLS_DIR))
    return module


def _shell_class(module):
    from pythonfmu import Fmi2Slave

    classes = [
        obj
        for _, obj in inspect.getmembers(module, inspect.isclass)
        if issubclass(obj, Fmi2Slave) and obj is not Fmi2Slave and obj.__module__ == module.__name__
    ]
    if len(classes) != 1:
        raise BuildError(f"{module.__file__}: expected one Fmi2Slave class, found {len(classes)}")
    return classes[0]


def discover(storeys: tuple[int, ...] = ()) -> list[FmuSource]:
    """All FMU shells in components/shells/, plus building variants for the given storey counts."""
    return list(_discover(tuple(sorted(set(storeys))), _shells_signature()))


def _shells_signature() -> tuple[tuple[str, float], ...]:
    """The shell scripts and their modification times: a changed shell is discovered again."""
    return tuple((p.name, p.stat().st_mtime) for p in sorted(SHELLS_DIR.glob("*_fmu.py")))


_SHELL_CONSTANTS = ("FMU_CORE_MODULES", "FMU_FAILED_STEP_STATUS", "FMU_REQUIREMENTS", "FMU_ONCE_PER_PROCESS",
                    "N_STOREYS")


def _read_shell(script: Path) -> tuple[str, dict[str, object], set[str]] | None:
    """(class name, module-level ``FMU_*``/``N_STOREYS`` constants, the class's method names) of a shell, read
    from its source without running it; None when that cannot be read statically (not exactly one class
    deriving from ``Fmi2Slave``, or a constant that is not a literal).

    Running a shell imports its physics cores (scipy.signal, scipy.linalg, ...): the staleness check
    before every run paid that for every shell in the project, most of which the run does not use.
    """
    import ast

    tree = ast.parse(script.read_text(), str(script))
    constants: dict[str, object] = {}
    classes = []
    for node in tree.body:
        targets = []
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets, value = [node.target], node.value
        for target in targets:
            if isinstance(target, ast.Name) and target.id in _SHELL_CONSTANTS:
                try:
                    constants[target.id] = ast.literal_eval(value)
                except ValueError:
                    return None
        if isinstance(node, ast.ClassDef) and any(
                (b.id if isinstance(b, ast.Name) else getattr(b, "attr", None)) == "Fmi2Slave" for b in node.bases):
            classes.append(node)
    if len(classes) != 1:
        return None
    methods = {f.name for f in classes[0].body if isinstance(f, ast.FunctionDef | ast.AsyncFunctionDef)}
    return classes[0].name, constants, methods


def _shell_by_running(script: Path) -> tuple[str, dict[str, object], set[str]]:
    """:func:`_read_shell` by importing the shell (for a shell whose constants are computed)."""
    module = _load_module(script, f"_discover_{script.stem}")
    cls = _shell_class(module)
    return cls.__name__, {k: getattr(module, k) for k in _SHELL_CONSTANTS if hasattr(module, k)}, set(vars(cls))


@functools.lru_cache(maxsize=16)
def _discover(storeys: tuple[int, ...], signature: tuple[tuple[str, float], ...]) -> tuple[FmuSource, ...]:
    """The shells read from their source (:func:`_read_shell`), once per process and set of shells."""
    found = []
    for script in sorted(SHELLS_DIR.glob("*_fmu.py")):
        class_name, module, methods = _read_shell(script) or _shell_by_running(script)
        cores = tuple(module.get("FMU_CORE_MODULES", ()))
        failed_step = module.get("FMU_FAILED_STEP_STATUS", "discard")
        if failed_step not in FAILED_STEP_STATUSES:
            raise BuildError(f"{script}: FMU_FAILED_STEP_STATUS must be one of {FAILED_STEP_STATUSES}")
        extra = {
            "requirements": tuple(module.get("FMU_REQUIREMENTS", ())),
            "handles_state": "_get_fmu_state" in methods and "_set_fmu_state" in methods,
            "failed_step_is_error": failed_step == "error",
            "once_per_process": bool(module.get("FMU_ONCE_PER_PROCESS", False)),
        }
        if "N_STOREYS" in module:
            for n in sorted({module["N_STOREYS"], *storeys}):
                found.append(FmuSource(script, class_name, cores, storeys=n, **extra))
        else:
            found.append(FmuSource(script, class_name, cores, **extra))
    return tuple(found)


def is_stale(source: FmuSource, fmu: Path) -> bool:
    """True if the FMU is missing or older than any of its sources."""
    if not fmu.exists():
        return True
    built = fmu.stat().st_mtime
    return any(p.stat().st_mtime > built for p in source.sources)


def _render_script(source: FmuSource, workdir: Path) -> Path:
    """The shell as it goes into the FMU: a storey variant gets its own module name."""
    if source.storeys is None:
        return source.script
    stem = f"{source.script.stem.removesuffix('_fmu')}_n{source.storeys}_fmu"
    text = source.script.read_text()
    text, count = re.subn(r"^N_STOREYS = \d+$", f"N_STOREYS = {source.storeys}", text, flags=re.M)
    if count != 1:
        raise BuildError(f"{source.script}: needs exactly one line 'N_STOREYS = <int>'")
    target = workdir / f"{stem}.py"
    target.write_text(text)
    return target


def _declared_metadata(script: Path) -> tuple[dict[str, str], dict[str, tuple[str, ...]], dict[str, float]]:
    from pythonfmu import Real
    from pythonfmu.variables import ScalarVariable

    module = _load_module(script, f"_meta_{script.stem}")
    instance = _shell_class(module)(instance_name="build", resources=str(script.parent))
    starts = {v.name: float(v.getter()) for v in instance.vars.values()
              if isinstance(v, Real) and ScalarVariable.requires_start(v)}
    return dict(instance.fmi_units), dict(instance.fmi_dependencies), starts


PYTHON_REQUIREMENT = "Python >= 3.11 (CPython, the interpreter of the host process)"


def _requirements_text(source: FmuSource) -> str:
    lines = [
        f"# {source.fmu_name} runs Python code through pythonfmu: the host process must provide",
        f"# {PYTHON_REQUIREMENT} with these packages installed:",
        *source.requirements,
    ]
    return "\n".join(lines) + "\n"


def _documentation(source: FmuSource) -> str:
    packages = ", ".join(source.requirements) or "none besides the standard library"
    return (
        f"<html><head><title>{source.class_name}</title></head><body>"
        f"<h1>{source.class_name}</h1>"
        f"<p>An FMI 2.0 co-simulation unit of the mre-cosim toolkit, built with pythonfmu. It executes "
        f"Python: the importing tool must run it in a process with {PYTHON_REQUIREMENT}; packages: "
        f"{packages} (also listed in resources/requirements.txt).</p>"
        f"<p>Variables, units and their meaning: see modelDescription.xml and the project README.</p>"
        f"</body></html>\n"
    )


def compile_log_shim(workdir: Path, inner: str, failed_step_is_error: bool) -> bytes | None:
    """The shim library (see fmi2_log_shim.c) loading ``inner`` from its own folder; None without a compiler."""
    from components.build.c_isolator import headers_dir

    target = workdir / "shim.so"
    flags = (*SHIM_CFLAGS, f"-I{headers_dir()}", f'-DINNER_LIBRARY="{inner}"',
             f"-DSTEP_FAILURE_IS_ERROR={int(failed_step_is_error)}")
    try:
        compile_c(LOG_SHIM_SOURCE, target, flags, ("-ldl", "-lpthread"))
    except CompilerMissing:
        return None
    except CompileFailed as exc:
        raise BuildError(f"compiling {LOG_SHIM_SOURCE.name} failed:\n{' '.join(exc.command)}\n{exc.stderr}") from None
    return target.read_bytes()


def _linux_binary(source: FmuSource, name: str, data: bytes, workdir: Path) -> list[tuple[str, bytes]]:
    """pythonfmu's Linux library, fixed, and the logging shim in its place (if a compiler exists)."""
    fixed = remove_exit_hook(data, f"{source.fmu_name}:{name}")
    if not name.endswith(".so"):
        return [(name, fixed)]
    inner = Path(name).name.removesuffix(".so") + INNER_SUFFIX
    shim = compile_log_shim(workdir, inner, source.failed_step_is_error)
    if shim is None:
        print(f"note: no C compiler ({compiler_name()}): {source.fmu_name} is built without its "
              f"logging shim, so a host sees its errors only with debug logging on", file=sys.stderr)
        return [(name, fixed)]
    return [(name, shim), (str(Path(name).parent / inner), fixed)]


def _has_builder_binaries(package_file: str | None) -> bool:
    return package_file is not None and (Path(package_file).parent / "resources" / "binaries").is_dir()


def installed_pythonfmu() -> None:
    """Make ``import pythonfmu`` the installed package, whose builder ships the FMU binaries.

    pythonfmu FMUs run in the host's interpreter and carry a copy of pythonfmu in their
    resources: if one was instantiated in this process before pythonfmu was imported, that
    copy (without the binaries, its folder maybe deleted since) is ``sys.modules["pythonfmu"]``,
    and its builder would silently write FMUs with no binaries. The copy is dropped from
    ``sys.modules`` (live instances keep their module objects) and the installed one imported.
    """
    loaded = sys.modules.get("pythonfmu")
    if loaded is None or _has_builder_binaries(getattr(loaded, "__file__", None)):
        return
    for name in [m for m in sys.modules if m == "pythonfmu" or m.startswith("pythonfmu.")]:
        del sys.modules[name]
    saved = sys.path[:]
    # skip every folder that holds an FMU's copy (an instance still alive keeps its resources on sys.path)
    sys.path[:] = [p for p in saved if not (Path(p or ".") / "pythonfmu" / "fmi2slave.py").is_file()
                   or _has_builder_binaries(str(Path(p or ".") / "pythonfmu" / "__init__.py"))]
    try:
        import pythonfmu
    finally:
        sys.path[:] = saved
    if not _has_builder_binaries(pythonfmu.__file__):
        raise BuildError(f"the pythonfmu package at {Path(pythonfmu.__file__).parent} has no builder binaries "
                         "(resources/binaries): reinstall pythonfmu")


def build(source: FmuSource, dest: Path) -> Path:
    """Build one FMU into ``dest`` and complete its modelDescription; returns its path."""
    installed_pythonfmu()
    from pythonfmu import FmuBuilder

    dest.mkdir(parents=True, exist_ok=True)
    target = dest / source.fmu_name
    with tempfile.TemporaryDirectory(prefix="mre_build_") as tmp:
        tmp = Path(tmp)
        script = _render_script(source, tmp)
        cores = [module_file(m) for m in source.core_modules]
        requirements = tmp / "requirements.txt"
        requirements.write_text(_requirements_text(source))
        docs = tmp / "documentation"
        docs.mkdir()
        (docs / "index.html").write_text(_documentation(source))
        options = {"canGetAndSetFMUstate": True} if source.handles_state else {}
        if source.once_per_process:
            options["canBeInstantiatedOnlyOncePerProcess"] = True
        sys.path[:0] = [str(CORES_DIR), str(SHELLS_DIR)]  # its cores and shared shell helpers
        # The shell and its cores imported afresh, as they are in components/: a copy loaded earlier in this process
        # (by an FMU instantiated here, pythonfmu FMUs share the host's interpreter, or by a test importing the
        # shell while another pythonfmu was sys.modules["pythonfmu"]) may subclass another Fmi2Slave than the
        # builder's. Those are set aside and put back afterwards.
        shadowed = {m: sys.modules.pop(m) for m in (script.stem, *source.core_modules) if m in sys.modules}
        try:
            raw = FmuBuilder.build_FMU(script, dest=tmp / "raw.fmu", project_files=[*cores, requirements],
                                       documentation_folder=docs, **options)
            units, deps, starts = _declared_metadata(script)
        except Exception as exc:  # pythonfmu raises plain exceptions
            raise BuildError(f"building {source.fmu_name} from {source.script.name}: {exc}") from exc
        finally:
            sys.path.remove(str(CORES_DIR))
            sys.path.remove(str(SHELLS_DIR))
            # the copies imported here go too: an FMU of this process must not find a mix of a core left by the
            # build and another put back (two classes of one exception, one raised and the other caught)
            for name in (script.stem, *source.core_modules):
                sys.modules.pop(name, None)
            sys.modules.update(shadowed)
        def write(f: BinaryIO) -> None:
            with zipfile.ZipFile(raw) as zin, zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as zout:
                for item in zin.infolist():
                    data = zin.read(item.filename)
                    if item.filename == "modelDescription.xml":
                        data = complete_model_description(data, units, deps, starts)
                    elif item.filename.startswith("binaries/linux64/"):
                        for name, binary in _linux_binary(source, item.filename, data, tmp):
                            info = zipfile.ZipInfo(name, item.date_time)
                            info.external_attr, info.compress_type = item.external_attr, item.compress_type
                            zout.writestr(info, binary)
                        continue
                    zout.writestr(item, data)

        try:  # written next to the target and renamed: a concurrent reader never sees half an FMU
            atomic_write(target, write, binary=True, mode=0o644)
        except ExitHookError as exc:
            raise BuildError(str(exc)) from None
    return target


def known_fmu(path: Path) -> FmuSource | None:
    """The source of an FMU path in the project's FMU folder (``DEFAULT_FMU_DIR``), if the project builds it."""
    path = Path(path).resolve()
    if path.parent != DEFAULT_FMU_DIR.resolve():
        return None
    m = re.fullmatch(r"([A-Za-z]+?)(\d+)?\.fmu", path.name)
    storeys = (int(m.group(2)),) if m and m.group(2) else ()
    for source in discover(storeys):
        if source.fmu_name == path.name:
            return source
    return None



