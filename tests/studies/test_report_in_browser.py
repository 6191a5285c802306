"""The study and IDA reports as headless Chromium renders them: every image loads, no table
is wider than a 1280 px window, no figure is drawn at less than half its own width. Slow: two small studies.
Screenshots are written beside the reports (``report.png``) for a person to look at."""

from __future__ import annotations

import subprocess
import sys

import pytest

from ..conftest import PROJECT
from ..support.browser_check import check_report, chromium

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(chromium() is None, reason="no Chromium (Debian: apt-get install chromium; "
                                                             ".ci/run installs it)")]

SCENARIOS = PROJECT / "scenarios"


def _tool(*args: str) -> None:
    done = subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]


def _clean(report, shot) -> None:
    found = check_report(report, shot)
    assert found["images"] > 0 and not found["broken"], found
    assert not found["wide"], found
    assert not found["shrunk"], found
    assert shot.is_file()


def test_the_case_study_report(tmp_path):
    out = tmp_path / "study"
    _tool(str(PROJECT / "orchestration" / "study.py"), str(SCENARIOS / "case_study.yaml"), "--out", str(out),
          "--quiet", "--set", "records={elcentro: elcentro.yaml, kobe: kobe.yaml}",
          "--set", "strategies=[passive-off, passive-on, sosm, sosm-fig15, on-off, clipped-optimal, lyapunov]",
          "--set", "overrides=[simulation.stop_time=3]", "--set", "reference={enabled: false}")
    _clean(out / "report.html", out / "report.png")


def test_the_ida_report(tmp_path):
    out = tmp_path / "ida"
    _tool(str(PROJECT / "orchestration" / "ida.py"), str(SCENARIOS / "ida_controllers.yaml"), "--out", str(out),
          "--quiet", "--set", "intensity.levels=[0.04, 0.08]", "--set", "strategies=[passive-off, sosm, lyapunov]")
    _clean(out / "report.html", out / "report.png")
