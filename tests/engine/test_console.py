"""The ``mre-cosim`` console command: it lists every tool and runs each tool's own ``main(argv)``."""

from __future__ import annotations

import importlib
import importlib.metadata
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from orchestration import console

PROJECT = Path(__file__).resolve().parents[2]
TOOLS = ("run", "study", "ida", "identify", "tune", "compare", "verdict", "inspect", "ssp", "build")


def console_command() -> list[str]:
    """The installed ``mre-cosim`` script (beside this interpreter), else the module it points to."""
    script = Path(sys.executable).parent / "mre-cosim"
    if script.is_file():
        return [str(script)]
    found = shutil.which("mre-cosim")
    return [found] if found else [sys.executable, "-m", "orchestration.console"]


def test_entry_point_names_the_console_main():
    points = [ep for ep in importlib.metadata.entry_points(group="console_scripts") if ep.name == "mre-cosim"]
    assert points, "mre-cosim is not installed as a console script (pip install -e .)"
    assert points[0].value == "orchestration.console:main"
    assert points[0].load() is console.main


def test_help_lists_every_tool(tmp_path):
    done = subprocess.run([*console_command(), "--help"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    listed = [line.split()[0] for line in done.stdout.splitlines() if line.startswith("  ")]
    assert listed == list(TOOLS)
    assert set(console.TOOLS) == set(TOOLS)


def test_unknown_or_missing_tool_is_a_usage_error(capsys):
    assert console.main(["frobnicate"]) == 2
    assert "unknown tool 'frobnicate'" in capsys.readouterr().err
    assert console.main([]) == 2
    assert "no tool given" in capsys.readouterr().err


def test_version_is_the_installed_distributions(capsys):
    from importlib import metadata

    assert console.main(["--version"]) == 0
    assert capsys.readouterr().out.split() == ["mre-cosim", metadata.version("mre-cosim")]


def test_a_misspelt_tool_gets_a_suggestion(capsys):
    assert console.main(["stuyd"]) == 2
    assert "did you mean 'study'?" in capsys.readouterr().err
    assert console.main(["zzzz"]) == 2
    assert "did you mean" not in capsys.readouterr().err


def test_bad_scenario_exits_2_like_run_py(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("units: [\n")  # not YAML
    via_console = subprocess.run([*console_command(), "run", str(bad), "--out", str(tmp_path / "a")],
                                 cwd=tmp_path, capture_output=True, text=True, timeout=120)
    via_script = subprocess.run([sys.executable, str(PROJECT / "orchestration" / "run.py"), str(bad),
                                 "--out", str(tmp_path / "b")], cwd=tmp_path, capture_output=True, text=True,
                                timeout=120)
    assert via_script.returncode == 2, via_script.stderr
    assert via_console.returncode == 2, via_console.stderr
    assert via_console.stderr == via_script.stderr
    assert "Traceback" not in via_console.stderr
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_build_help_is_python_m_components_build(tmp_path):
    via_console = subprocess.run([*console_command(), "build", "--help"], cwd=tmp_path, capture_output=True,
                                 text=True, timeout=60)
    via_module = subprocess.run([sys.executable, "-m", "components.build", "--help"], cwd=PROJECT,
                                capture_output=True, text=True, timeout=60)
    assert via_module.returncode == 0 and via_console.returncode == 0, via_console.stderr
    assert via_console.stdout == via_module.stdout


@pytest.mark.parametrize("tool", TOOLS)
def test_dispatch_calls_the_tools_own_main(tool, monkeypatch):
    module = importlib.import_module(console.TOOLS[tool][0])
    assert console.tool_main(tool) is module.main
    calls = []
    monkeypatch.setattr(module, "main", lambda argv: calls.append(argv) or 17)
    assert console.main([tool, "x.yaml", "--set", "a=1"]) == 17
    assert calls == [["x.yaml", "--set", "a=1"]]


@pytest.mark.parametrize("tool", [t for t in TOOLS if t != "build"])
def test_a_tools_usage_names_the_command_the_user_typed(tool, capsys):
    with pytest.raises(SystemExit) as done:
        console.main([tool, "--help"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: mre-cosim {tool} ")
    module = importlib.import_module(console.TOOLS[tool][0])
    script = f"{module.__name__.rpartition('.')[2]}.py"  # inspect: inspect_fmu.py (no stdlib name shadowed)
    with pytest.raises(SystemExit):
        module.main(["--help"])  # the script itself, afterwards: its own name again
    assert capsys.readouterr().out.startswith(f"usage: {script} ")


def test_a_reader_that_leaves_early_is_no_internal_error(tmp_path):
    """``mre-cosim study --help | head -1``: the pipe breaks under the tool; no crash report, no traceback."""
    import os

    read, write = os.pipe()
    os.close(read)  # the reader has gone before the tool prints
    try:
        done = subprocess.run([*console_command(), "study", "--help"], cwd=tmp_path, stdout=write,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write)
    assert done.returncode in (0, 1), done.stderr
    assert "internal error" not in done.stderr and "Traceback" not in done.stderr, done.stderr
