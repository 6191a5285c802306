"""Messages that say what is wrong: a record that is a FIFO, a folder or a device; a malformed modelDescription.xml
named by its element and attribute, never by a parser's internals."""

from __future__ import annotations

import os
import re
import shutil
import threading
import time
import zipfile

import pytest

from orchestration.engine_hooks import plan_scenario
from orchestration.master.datapath import find_data_file
from orchestration.master.errors import ScenarioError
from orchestration.master.fmu_description import FmuFormatError, read_description

from ..conftest import PROJECT, shipped_record

ELCENTRO = PROJECT / "scenarios" / "elcentro.yaml"


@pytest.mark.parametrize(("make", "kind"), [
    (lambda p: os.mkfifo(p), "a FIFO"),
    (lambda p: p.mkdir(), "a folder"),
    (lambda p: os.symlink("/dev/zero", p), "a character device"),
])
def test_a_record_that_is_not_a_regular_file_says_what_it_is(tmp_path, make, kind):
    make(tmp_path / "r.csv")
    with pytest.raises(FileNotFoundError, match=f"is not a regular file: .*r.csv is {kind}"):
        find_data_file("r.csv", (tmp_path,))
    started = time.monotonic()
    with pytest.raises(ScenarioError) as err:  # a FIFO is never opened: no writer needed, no wait
        plan_scenario(ELCENTRO, ("simulation.stop_time=0.05", f"ground.record=!record {tmp_path / 'r.csv'}"))
    assert time.monotonic() - started < 30 and kind in str(err.value) and "not found" not in str(err.value)


def test_a_regular_file_later_on_the_path_is_still_found(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    (first / "r.csv").mkdir(parents=True)
    second.mkdir()
    shutil.copy(shipped_record("elcentro_1940_ns.csv"), second / "r.csv")
    assert find_data_file("r.csv", (first, second)) == (second / "r.csv").resolve()


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file")
def test_an_unreadable_record_says_permission(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("0,0\n")
    path.chmod(0)
    with pytest.raises(PermissionError, match="not readable"):
        find_data_file("r.csv", (tmp_path,))


def test_dev_zero_by_absolute_path_does_not_read_it():
    result: list[BaseException] = []
    thread = threading.Thread(target=lambda: _catch(result), daemon=True)
    thread.start()
    thread.join(10)
    assert not thread.is_alive() and "a character device" in str(result[0])


def _catch(into: list[BaseException]) -> None:
    try:
        find_data_file("/dev/zero")
    except FileNotFoundError as exc:
        into.append(exc)


SRC = PROJECT / "fmus" / "MreIsolator.fmu"


def _variant(tmp_path, edit) -> str:
    with zipfile.ZipFile(SRC) as z:
        text = z.read("modelDescription.xml").decode()
    path = tmp_path / "bad.fmu"
    with zipfile.ZipFile(SRC) as zin, zipfile.ZipFile(path, "w") as zout:
        for info in zin.infolist():
            zout.writestr(info, edit(text).encode() if info.filename == "modelDescription.xml" else zin.read(info))
    with pytest.raises(FmuFormatError) as err:
        read_description(path, "isolator")
    return str(err.value)


def _first_variable(attr: str, value: str | None):
    def edit(text: str) -> str:
        tag = re.search(r"<ScalarVariable [^>]*>", text).group(0)
        new = re.sub(rf'\s{attr}="[^"]*"', "" if value is None else f' {attr}="{value}"', tag)
        return text.replace(tag, new, 1)
    return edit


INTERNALS = ("NoneType", "list index", "int()", "invalid literal", "local variable", "not iterable")


@pytest.mark.parametrize(("edit", "expected"), [
    (lambda t: t.replace('fmiVersion="2.0" ', "", 1), "<fmiModelDescription> has no fmiVersion attribute"),
    (lambda t: t.replace('fmiVersion="2.0"', 'fmiVersion="1.0"', 1), "FMI 1.0 FMU"),
    (_first_variable("name", None), ("<ScalarVariable> number 1 (line",  # when fmpy's reader fails on it
                                     "Element 'ScalarVariable': The attribute 'name' is required")),  # else schema
    (_first_variable("valueReference", None), "valueReference None is not an integer"),
    (_first_variable("valueReference", "x"), "valueReference 'x' is not an integer"),
    (lambda t: re.sub(r"(<ScalarVariable[^>]*>)\s*<Real[^>]*/>", r"\1", t, count=1),
     "has 0 type elements (exactly one of Real"),
    (lambda t: re.sub(r"<ModelVariables>.*</ModelVariables>", "", t, flags=re.S), "no <ModelVariables> element"),
    (lambda t: re.sub(r'<Unknown index="\d+"', '<Unknown index="999"', t, count=1), 'index="999"> (line'),
    (lambda t: re.sub(r'<Unknown index="\d+"', "<Unknown", t, count=1), "index None is not an integer"),
    (lambda t: re.sub(r'dependencies="[^"]*"', 'dependencies="a b"', t, count=1), "dependencies 'a'"),
    (lambda t: t.replace('<BaseUnit m="-1" A="-1" />', '<BaseUnit m="x" />', 1), "<BaseUnit m='x'>"),
])
def test_a_malformed_description_is_named_by_element_and_attribute(tmp_path, edit, expected):
    text = _variant(tmp_path, edit)
    assert any(e in text for e in ((expected,) if isinstance(expected, str) else expected)), text
    assert not any(word in text for word in INTERNALS), text
