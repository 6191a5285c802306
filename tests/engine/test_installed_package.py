"""``pip install .`` (not editable) gives a working ``mre-cosim``: the shipped scenarios are found by name, their
FMUs are built in the per-user cache, and nothing of the checkout is used.

The fresh environment reuses this environment's third-party packages (a path line in a ``.pth`` file, so the
editable install of the checkout is not active there); only mre-cosim itself is installed into it, from a copy of
the checkout's packaged files (the build writes ``build/`` and ``*.egg-info`` next to its sources).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from importlib import metadata
from pathlib import Path

import pytest

from ..conftest import PROJECT

pytestmark = pytest.mark.slow

PACKAGED = ("pyproject.toml", "README.md", "LICENSE", "components", "orchestration", "mre_common", "scenarios")


def _venv_python(venv: Path) -> Path:
    return venv / "bin" / "python"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh virtual environment with ``pip install --no-deps <copy of the checkout>``; its folder."""
    root = tmp_path_factory.mktemp("installed")
    source = root / "source"
    source.mkdir()
    for name in PACKAGED:
        src = PROJECT / name
        if src.is_dir():
            shutil.copytree(src, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(src, source / name)
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    python = _venv_python(venv)
    purelib = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True, timeout=60).stdout.strip()
    # this environment's packages after the new one's own (a path line: the .pth files there are not run)
    Path(purelib, "project_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    done = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet", "--no-deps",
                           str(source)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    shutil.rmtree(source)  # the installed package must not need its source
    return venv


def _in_venv(venv: Path, args: list[str], cwd: Path, env: dict[str, str], timeout: float = 300):
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def _env(venv: Path, cache: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["MRE_COSIM_CACHE"] = str(cache)
    return env


def test_the_installed_package_runs_the_shipped_kobe_scenario_by_name(installed, tmp_path):
    cache, work = tmp_path / "cache", tmp_path / "work"
    work.mkdir()
    env = _env(installed, cache)
    where = _in_venv(installed, [str(_venv_python(installed)), "-m", "mre_common.project_paths"], work, env)
    assert where.returncode == 0, where.stderr
    assert str(PROJECT) not in where.stdout and "kobe" in where.stdout, where.stdout  # the installed copy
    done = _in_venv(installed, [str(installed / "bin" / "mre-cosim"), "run", "kobe", "--set",
                                "simulation.stop_time=2", "--no-plots", "--quiet", "--out", str(work / "out")],
                    work, env)
    assert done.returncode == 0, done.stdout + done.stderr
    summary = json.loads((work / "out" / "summary.json").read_text())
    assert summary["complete"] is True
    manifest = json.loads((work / "out" / "manifest.json").read_text())
    fmus = [Path(entry["path"]) for entry in manifest["fmus"].values()]
    version = metadata.version("mre-cosim")
    assert fmus and all(p.parent == cache / "fmus" / version for p in fmus), fmus  # built in the per-user cache
    assert manifest["provenance"]["version"] == version
    assert manifest["provenance"]["commit"] is None  # an installed package is no checkout
    assert not any(str(PROJECT) in json.dumps(v) for v in (manifest["fmus"], manifest.get("data_files", {})))


def test_the_installed_package_runs_the_shipped_scenario_by_its_installed_path(installed, tmp_path):
    env = _env(installed, tmp_path / "cache")
    found = _in_venv(installed, [str(_venv_python(installed)), "-c",
                                 "from mre_common.project_paths import SCENARIOS_DIR; print(SCENARIOS_DIR)"],
                     tmp_path, env)
    assert found.returncode == 0, found.stderr
    kobe = Path(found.stdout.strip()) / "kobe.yaml"
    assert kobe.is_file() and PROJECT not in kobe.parents
    done = _in_venv(installed, [str(installed / "bin" / "mre-cosim"), "run", str(kobe), "--set",
                                "simulation.stop_time=0.5", "--no-plots", "--quiet", "--out", str(tmp_path / "o")],
                    tmp_path, env)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "o" / "summary.json").is_file()
