"""A report.html as headless Chromium renders it: every image loaded, no table wider than the page, no figure
drawn at less than half its own width (its text would be unreadable), and a screenshot.

The page is copied beside the original (so its relative image paths resolve) with a script that measures the
laid-out page on ``load`` and writes the result into the title; ``chromium --dump-dom`` prints the DOM after
the page has loaded, and the title is read back. Chromium is Debian's ``chromium`` (``.ci/run`` installs it).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

WIDTH = 1280  # [px] the browser window: a laptop's
CHECK = """<script>
window.addEventListener('load', function () {
  var imgs = Array.from(document.images);
  var width = document.documentElement.clientWidth;
  function alt(i) { return (i.getAttribute('alt') || '').slice(0, 80); }
  function shown(e) { return e.getBoundingClientRect().width; }
  var out = {images: imgs.length, width: width,
    broken: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); }).map(alt),
    wide: Array.from(document.querySelectorAll('table'))
      .filter(function (t) { return t.getBoundingClientRect().right > width + 1; })
      .map(function (t) { return (t.innerText || '').slice(0, 80); }),
    shrunk: imgs.filter(function (i) { return i.naturalWidth > 0 && shown(i) < 0.5 * i.naturalWidth; })
      .map(function (i) { return alt(i) + ': ' + Math.round(shown(i)) + ' of ' + i.naturalWidth + ' px'; })};
  document.title = 'CHECK ' + JSON.stringify(out);
});
</script>"""


def chromium() -> str | None:
    """The Chromium binary, if there is one."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


def _browser(*args: str) -> subprocess.CompletedProcess[str]:
    binary = chromium()
    assert binary is not None
    return subprocess.run([binary, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           f"--window-size={WIDTH},900", *args], capture_output=True, text=True, timeout=120)


def check_report(report: Path, screenshot: Path | None = None) -> dict:
    """What Chromium found in ``report`` (images, broken, wide, shrunk); a full-page screenshot if asked."""
    probe = report.with_name(".browser_check.html")
    html = report.read_text()
    probe.write_text(html.replace("</body>", CHECK + "</body>") if "</body>" in html else html + CHECK)
    try:
        dom = _browser("--virtual-time-budget=10000", "--dump-dom", probe.as_uri()).stdout
    finally:
        probe.unlink()
    found = re.search(r"<title>CHECK (.*?)</title>", dom, re.S)
    assert found, f"Chromium did not finish loading {report}: {dom[:500]}"
    result = json.loads(found.group(1))
    if screenshot is not None:
        _browser(f"--screenshot={screenshot}", "--window-size=1280,6000", report.as_uri())
    return result
