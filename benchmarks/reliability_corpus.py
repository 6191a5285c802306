"""Reliability corpus (not part of the test suite): hostile input and faults through every command-line tool.

``python benchmarks/reliability_corpus.py [--workers 2] [--only CLASS ...] [--report FILE]``

Builds several hundred cases of its own (bad scenarios, bad overrides, bad records, bad
FMUs, hostile SSP packages, unusable output folders, full and read-only disks, signals
during start-up and during a run, concurrent runs into one ``--out``, the other tools'
inputs; the ``35/`` classes: names that become paths, new-unit designs, study checks before the
pool, model scripts that exit, loop or ``chdir``, hostile caches, a stopped or killed CSV process,
unit-less outputs), runs each as a subprocess in a fresh folder (with its own temporary folder and a
file that must survive), and classifies the outcome:

* **clean**: one of the tool's documented exit codes (3, a bug, is not clean), no
  traceback, a message on stderr when it fails, nothing written on exit 2 or 130, no file
  outside the output folder, no temporary file left, and no folder that looks complete
  without being so (``summary.json`` says ``complete: true`` only with every file whole);
* **data loss**: a file that existed before the case (a previous run, a "precious" file)
  is changed or gone.

Writes the table of classes with counts and outcomes into the ``--report`` file (by default
``docs/reliability.md`` for a whole run, and no file for ``--only``; between the markers
``<!-- corpus:begin -->`` and ``<!-- corpus:end -->``) and, with ``--jsonl FILE``, every
case's outcome as JSON lines. Full and read-only disks are tmpfs mounts
(root only); without root they are simulated (RLIMIT_FSIZE makes writes fail with EFBIG;
a read-only folder is skipped).
"""

from __future__ import annotations

import argparse
import copy
import csv
import io
import json
import os
import random
import resource
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import threading
import time
import zipfile
from collections import Counter, defaultdict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

PROJECT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(PROJECT))

from tests.support.tree_mutation import key_paths, mutate  # noqa: E402  (the hostile-input tests' mutations)

SC = PROJECT / "scenarios"
RECORDS = SC / "records"
FMUS = PROJECT / "fmus"
PY = sys.executable
TOOLS = {
    "run.py": [PY, str(PROJECT / "orchestration" / "run.py")],
    "study.py": [PY, str(PROJECT / "orchestration" / "study.py")],
    "tune.py": [PY, str(PROJECT / "orchestration" / "tune.py")],
    "identify.py": [PY, str(PROJECT / "orchestration" / "identify.py")],
    "ssp.py": [PY, str(PROJECT / "orchestration" / "ssp.py")],
    "build": [PY, "-m", "components.build"],
    "api": [PY, "api_case.py"],  # a Python API script written by the case (engine_cases)
    "ida.py": [PY, str(PROJECT / "orchestration" / "ida.py")],
    "inspect": [PY, str(PROJECT / "orchestration" / "inspect_fmu.py")],
    "compare": [PY, str(PROJECT / "orchestration" / "compare.py")],
    "verdict": [PY, str(PROJECT / "orchestration" / "verdict.py")],
}
DOCUMENTED = {"run.py": {0, 1, 2, 130}, "study.py": {0, 1, 2, 130}, "tune.py": {0, 1, 2, 130}, "ida.py": {0, 1, 2, 130},
              "identify.py": {0, 1, 2, 130, 143}, "ssp.py": {0, 2, 130}, "build": {0, 1, 2, 130},
              "api": {0, 1, 2}, "inspect": {0, 1, 2, 130}, "compare": {0, 2, 130}, "verdict": {0, 2, 130}}
SHORT = "simulation.stop_time=0.05"
PRECIOUS = "precious.txt"
IS_ROOT = os.geteuid() == 0
SHARED_TMP = {"dask-scratch-space"}
"""Entries of the temporary folder that are shared caches reused by every run (dask's), not leftovers."""


@dataclass
class Case:
    """One command run on prepared files; ``setup(folder)`` makes them and returns extra argv."""

    cls: str
    name: str
    tool: str
    argv: list[str]
    setup: Callable[[Path], None] | None = None
    signal_after: tuple[int, float] | None = None  # (signal, seconds) sent to the process
    copies: int = 1  # concurrent copies of the same command (same --out)
    mount: str | None = None  # tmpfs at ``out``: "full" (small), "full-before" (filled up), "readonly"
    mount_size: str = "1M"
    out: str | None = "out"  # the output folder the case may create (relative to the case folder)
    timeout: float = 120.0
    env: dict[str, str] = field(default_factory=dict)  # extra environment variables of the command
    during: tuple[float, Callable[[Path], None]] | None = None  # (seconds, action on the case folder) while it runs
    changes: tuple[str, ...] = ()  # existing files the case itself changes (``during``), not counted as changed
    verify: Callable[[Path, list[int], str], list[str]] | None = None  # more reasons the outcome is not clean


@dataclass
class Result:
    cls: str
    name: str
    tool: str
    codes: list[int]
    clean: bool
    data_loss: bool
    reasons: list[str] = field(default_factory=list)
    seconds: float = 0.0
    stderr: str = ""


# -- inputs -------------------------------------------------------------------------------------------


class _Dumper(yaml.SafeDumper):
    pass


def _data_file(dumper: yaml.SafeDumper, value: Any) -> Any:
    return dumper.represent_scalar(f"!{value.kind}", value.name)


def standalone(path: Path) -> dict[str, Any]:
    """A real scenario as one self-contained tree (extends merged, FMU paths absolute), stopping at 0.05 s."""
    from orchestration.master.scenario import load_scenario
    from orchestration.master.yaml_source import DataFile

    _Dumper.add_representer(DataFile, _data_file)
    loaded = load_scenario(path, (SHORT,))
    tree = copy.deepcopy(loaded.raw)
    for unit in tree["units"]:
        tree["units"][unit]["fmu"] = str(loaded.fmu_path(unit))
    return tree


def hostile_zip(kind: str, src: Path, path: Path) -> bool:
    """Write ``path``: a copy of the archive ``src`` made hostile in one of the ways FMUs and SSP packages share
    (an entry escaping the folder, an absolute entry, a symbolic link, a zip bomb); False for other kinds."""
    if kind == "traversal":
        copy_zip(src, path, extra={"../../escaped.txt": b"x"})
    elif kind == "absolute":
        copy_zip(src, path, extra={"/tmp/mre-corpus-escaped.txt": b"x"})
    elif kind == "symlink":
        info = zipfile.ZipInfo("resources/link")
        info.external_attr = 0o120777 << 16
        copy_zip(src, path, infos=[(info, b"/etc/passwd")])
    elif kind == "bomb":
        copy_zip(src, path)
        with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as z:
            zeros_entry(z, "resources/zeros.bin", 1100)
    else:
        return False
    return True


def write_yaml(tree: Any) -> Callable[[Path], None]:
    text = yaml.dump(tree, Dumper=_Dumper, allow_unicode=True)
    return lambda d: (d / "s.yaml").write_text(text)


def write_bytes(name: str, data: bytes) -> Callable[[Path], None]:
    return lambda d: (d / name).write_bytes(data)


def copy_zip(src: Path, dest: Path, edit: Callable[[str, bytes], bytes | None] = lambda n, b: b,
             extra: dict[str, bytes] | None = None, infos: list[tuple[zipfile.ZipInfo, bytes]] = ()) -> None:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = edit(info.filename, zin.read(info))
            if data is not None:
                zout.writestr(info, data)
        for name, data in (extra or {}).items():
            zout.writestr(name, data)
        for info, data in infos:
            zout.writestr(info, data)


def zeros_entry(z: zipfile.ZipFile, name: str, mib: int) -> None:
    with z.open(name, "w", force_zip64=True) as f:
        block = bytes(1 << 20)
        for _ in range(mib):
            f.write(block)


# -- the cases ----------------------------------------------------------------------------------------


def scenario_cases(rng: random.Random, n: int) -> list[Case]:
    """One key of a real scenario changed (value, deletion or unknown sibling)."""
    from orchestration.master.yaml_source import DataFile

    values = [None, True, False, 0, -1, 1e308, -1e308, 5e-324, float("inf"), float("nan"), "", "x", "../../escape",
              "/dev/zero", "/etc/passwd", "1_0", "1e-3", [], {}, [[[["deep"]]]], "A" * 5000, {"a": [1, {"b": 2}]},
              DataFile("/dev/zero", "record"), DataFile("nowhere.csv", "data"), DataFile("/etc/passwd", "record"),
              DataFile("../../../etc/passwd", "data"), "passive", "sosm ", "Gauss-Seidel", 1, 2.5, "0.001"]
    names = ["elcentro.yaml", "kobe.yaml", "elcentro_constant_current.yaml", "elcentro_c_isolator.yaml",
             "hachinohe.yaml", "northridge.yaml", "elcentro_bouc_wen.yaml"]
    trees = {name: standalone(SC / name) for name in names}
    out = []
    for k in range(n):
        name = rng.choice(names)
        tree = trees[name]
        path = rng.choice(key_paths(tree))
        op = rng.choice(["replace", "replace", "replace", "delete", "add"])
        value = rng.choice(values)
        label = f"{name} {op} {'.'.join(map(str, path))}" + (f" = {value!r}"[:60] if op != "delete" else "")
        with_out = rng.random() < 0.7
        out.append(Case("scenario: one key changed", f"{k:03d} {label}", "run.py",
                        ["s.yaml", "--no-plots", "--quiet", *(["--out", "out"] if with_out else [])],
                        write_yaml(mutate(tree, path, op, value)), out="out" if with_out else "runs"))
    return out


def yaml_text_cases() -> list[Case]:
    """Hostile YAML text and files: encodings, nesting, aliases, special files, extends chains."""
    base = f"extends: {SC / 'elcentro.yaml'}\nsimulation: {{stop_time: 0.05}}\n"
    laughs = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True))
    texts: dict[str, bytes] = {
        "latin-1 name": ("name: caf\xe9\n" + base).encode("latin-1"),
        "utf-16": base.encode("utf-16"),
        "utf-8 with BOM": b"\xef\xbb\xbf" + base.encode(),
        "NUL byte": base.encode() + b"name: a\x00b\n",
        "binary garbage": bytes(random.Random(1).randrange(256) for _ in range(4096)),
        "deep lists": ("a: " + "[" * 5000 + "]" * 5000 + "\n").encode(),
        "deep maps": ("a: " + "{b: " * 3000 + "1" + "}" * 3000 + "\n").encode(),
        "65 levels": (base + "x: " + "[" * 65 + "]" * 65 + "\n").encode(),
        "billion laughs": laughs.encode(),
        "recursive alias": b"a: &a [*a]\n",
        "recursive map alias": b"a: &a {b: *a}\n",
        "undefined alias": (base + "name: *nothing\n").encode(),
        "many aliases": (base + "x: &x [1]\n" + "".join(f"y{k}: *x\n" for k in range(3000))).encode(),
        "duplicate keys": (base + "name: a\nname: b\n").encode(),
        "two documents": (base + "---\nname: b\n").encode(),
        "top-level list": b"- a\n- b\n",
        "top-level scalar": b"42\n",
        "empty": b"",
        "only comments": b"# nothing\n",
        "tabs": (base + "\tname: x\n").encode(),
        "unknown tag": (base + "name: !python/object:os.system echo\n").encode(),
        "python tag": (base + "name: !!python/object/apply:os.system [echo hi]\n").encode(),
        "binary tag": (base + "name: !!binary aGVsbG8=\n").encode(),
        "timestamp name": (base + "name: 2001-12-14\n").encode(),
        "huge integer": (base + "simulation: {step: " + "9" * 5000 + "}\n").encode(),
        "float tag garbage": (base + "simulation: {step: !!float abc}\n").encode(),
        "complex key": (base + "? [a, b]\n: 1\n").encode(),
        "very long line": (base + "description: " + "x" * 1_000_000 + "\n").encode(),
        "5 MB file": (base + "# " + "x" * (5 << 20) + "\n").encode(),
        "extends non-string": b"extends: [a, b]\n",
        "extends self": b"extends: s.yaml\n",
        "extends missing": b"extends: nowhere.yaml\n",
        "extends a folder": b"extends: /tmp\n",
        "extends /dev/zero": b"extends: /dev/zero\n",
        "extends /dev/urandom": b"extends: /dev/urandom\n",
        "extends /proc/self/mem": b"extends: /proc/self/mem\n",
        "extends a study": f"extends: {SC / 'case_study.yaml'}\n".encode(),
    }
    out = [Case("YAML text and files", name, "run.py", ["s.yaml", "--out", "out", "--quiet", "--no-plots"],
                write_bytes("s.yaml", data)) for name, data in texts.items()]

    def fifo(d: Path) -> None:
        os.mkfifo(d / "s.yaml")

    def fifo_extends(d: Path) -> None:
        os.mkfifo(d / "base.yaml")
        (d / "s.yaml").write_text("extends: base.yaml\n")

    def chain(d: Path) -> None:
        for k in range(40):
            (d / f"c{k}.yaml").write_text(f"extends: c{k + 1}.yaml\n" if k < 39 else base)
        shutil.copy(d / "c0.yaml", d / "s.yaml")

    def loop(d: Path) -> None:
        (d / "a.yaml").write_text("extends: s.yaml\n")
        (d / "s.yaml").write_text("extends: a.yaml\n")

    def symlink_loop(d: Path) -> None:
        os.symlink("s.yaml", d / "s.yaml")

    def unreadable(d: Path) -> None:
        (d / "s.yaml").write_text(base)
        os.chmod(d / "s.yaml", 0)

    for name, setup in (("a FIFO", fifo), ("extends a FIFO", fifo_extends), ("extends chain of 40", chain),
                        ("extends loop", loop), ("symlink to itself", symlink_loop), ("unreadable (mode 000)",
                                                                                      unreadable)):
        out.append(Case("YAML text and files", name, "run.py", ["s.yaml", "--out", "out", "--quiet"], setup))
    for name, path in (("/dev/zero", "/dev/zero"), ("/dev/null", "/dev/null"), ("a folder", "/tmp"),
                       ("missing", "nowhere.yaml"), ("/proc/self/mem", "/proc/self/mem")):
        out.append(Case("YAML text and files", f"scenario is {name}", "run.py", [path, "--out", "out", "--quiet"]))
    return out


def override_cases() -> list[Case]:
    """Hostile ``--set`` values on a real scenario."""
    sets = ["simulation.step=true", "simulation.step=false", "simulation.stop_time=.inf", "simulation.stop_time=.nan",
            "simulation.stop_time=-.inf", "simulation.step=1e-320", "simulation.step=5e-324", "simulation.step=0",
            "simulation.step=-1", "simulation.stop_time=1e308", "simulation.stop_time=1e9", "simulation.stop_time=1e5",
            "simulation.start_time=1e308", "simulation.step=0.0007", "x=&a [*a]", "x=&a {b: *a}",
            "x=" + "[" * 200, "x=" + "[" * 60 + "]" * 60, "controller.mode=pasive", "controller.mode=PASSIVE",
            "controller.mode=1", "controller.mode=true", "name=../../escape", "name=.hidden", "name=a/b",
            "name=" + "n" * 300, "name=", "units.ground.fmu=/dev/zero", "units.ground.fmu=/tmp",
            "units.ground.fmu=/etc/passwd", "units.ground.fmu=nowhere.fmu", "ground.record=!data missing.csv",
            "ground.record=!record /dev/zero", "ground.record=!record /etc/passwd", "ground.record=!record /tmp",
            "ground.record=!record ../../../etc/shadow", "ground.record=!bogus x", "ground.scale=1_0",
            "ground.scale=0x10", "ground.scale=.inf", "ground.scale=yes", "isolator.n_isolators=2.5",
            "isolator.n_isolators=true", "connections=[{source: ground.ag, target: building.ag, delayed: 1}]",
            "connections=[ground.ag -> ground.ag]", "connections=[a -> b]", "connections=7",
            "limits.max_abs={building.x_0: true}", "limits.max_abs={building.x_0: -1}",
            "limits.max_abs={nowhere.x: 1}", "report.displacement_limits={a: true}", "report.caption={a.b}",
            "outputs=[building.nothing]", "outputs=[]", "simulation.order=[ground]", "simulation.algorithm=magic",
            "simulation.executor=gpu", "results.dir=", "units={}", "units=&a {b: *a}", "units.x.fmu=1",
            "=1", "a..b=1", "noequals", "units.controller.parameters.lambda=-1e308",
            "controller.i_passive=.nan", "simulation=null", "description=" + "d" * 100000]
    return [Case("--set overrides", s[:70], "run.py", [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", s,
                                                     "--out", "out", "--quiet", "--no-plots"]) for s in sets]


def record_cases(rng: random.Random, n: int) -> list[Case]:
    """Real records with one token changed, and hostile record files (CSV and PEER AT2)."""
    tokens = ["1_0", "inf", "-inf", "nan", "NaN", "0x10", "abc", "", "1e400", "-1e400", "-", "1,2,3", "\xe9",
              "1e-3", "+.5", "1.2.3", "--1", "1e", "\x00", "9" * 400]
    sources = sorted(RECORDS.glob("*.csv"))
    out = []
    for k in range(n):
        src = rng.choice(sources)
        lines = src.read_text().splitlines()
        i = rng.randrange(min(len(lines), 300))
        parts = lines[i].split(",")
        j = rng.randrange(len(parts))
        token = rng.choice(tokens)
        parts[j] = token
        lines[i] = ",".join(parts)
        data = ("\n".join(lines) + "\n").encode("utf-8", "surrogateescape")
        out.append(Case("records: one token changed", f"{k:03d} {src.name}:{i + 1} col {j} = {token!r}"[:80],
                        "run.py", [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", "ground.record=!record r.csv",
                                   "--out", "out", "--quiet", "--no-plots"], write_bytes("r.csv", data)))
    at2 = {"DT=1e308": "NPTS= 3, DT= 1e308", "DT=..": "NPTS= 3, DT= ..", "DT=0": "NPTS= 3, DT= 0",
           "DT=-0.01": "NPTS= 3, DT= -0.01", "DT=1e-320": "NPTS= 3, DT= 1e-320", "no DT": "NPTS= 3",
           "NPTS huge": "NPTS= 99999999999999999999999, DT= 0.01", "NPTS mismatch": "NPTS= 5, DT= 0.01"}
    for name, header in at2.items():
        text = f"PEER\nrecord\nACCELERATION IN G\n{header}\n0.0 0.1 -0.1\n".encode()
        out.append(Case("records: hostile files", f"AT2 {name}", "run.py",
                        [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", "ground.record=!record r.at2", "--out",
                         "out", "--quiet", "--no-plots"], write_bytes("r.at2", text)))
    files: dict[str, Callable[[Path], None]] = {
        "empty": write_bytes("r.csv", b""),
        "header only": write_bytes("r.csv", b"time,acc\n"),
        "one sample": write_bytes("r.csv", b"0,0\n"),
        "time going back": write_bytes("r.csv", b"0,0\n0.02,1\n0.01,2\n"),
        "three columns": write_bytes("r.csv", b"0,0,0\n0.02,1,1\n"),
        "latin-1 header": write_bytes("r.csv", "t\xe9mps,acc\n0,0\n0.02,0.1\n".encode("latin-1")),
        "binary garbage": write_bytes("r.csv", bytes(random.Random(2).randrange(256) for _ in range(4096))),
        "300 MB sparse file": lambda d: os.truncate(_touch(d / "r.csv"), 300 << 20),
        "a FIFO": lambda d: os.mkfifo(d / "r.csv"),
        "a folder": lambda d: (d / "r.csv").mkdir(),
        "symlink to /dev/zero": lambda d: os.symlink("/dev/zero", d / "r.csv"),
    }
    for name, setup in files.items():
        out.append(Case("records: hostile files", name, "run.py",
                        [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", "ground.record=!record r.csv", "--out",
                         "out", "--quiet", "--no-plots"], setup))
    out.append(Case("records: hostile files", "plain-string record path missing", "run.py",
                    [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", "ground.record=nowhere.csv", "--out", "out",
                     "--quiet", "--no-plots"]))
    return out


def _touch(path: Path) -> Path:
    path.write_bytes(b"0,0\n")
    return path


def fmu_cases() -> list[Case]:
    """FMUs that are not FMUs, cannot load, or are hostile archives, in place of the isolator."""
    src = FMUS / "MreIsolator.fmu"

    def binary(how: str) -> Callable[[Path], None]:
        def setup(d: Path) -> None:
            def edit(name: str, raw: bytes) -> bytes | None:
                if not name.startswith("binaries/linux64/"):
                    return raw
                return {"garbage": b"garbage" * 1000, "truncated": raw[:4096], "empty": b"",
                        "other cpu": raw[:18] + b"\xb7\x00" + raw[20:], "32-bit": raw[:4] + b"\x01" + raw[5:],
                        "big-endian": raw[:5] + b"\x02" + raw[6:], "not a shared object": raw[:16] + b"\x02\x00"
                        + raw[18:], "zeros in the middle": raw[:len(raw) // 2] + bytes(4096) + raw[len(raw) // 2
                                                                                                     + 4096:],
                        "no binary": None}[how]
            copy_zip(src, d / "bad.fmu", edit)
        return setup

    def md(text: str | None) -> Callable[[Path], None]:
        return lambda d: copy_zip(src, d / "bad.fmu", lambda n, b: (None if text is None else text.encode())
                                  if n == "modelDescription.xml" else b)

    def archive(kind: str) -> Callable[[Path], None]:
        def setup(d: Path) -> None:
            path = d / "bad.fmu"
            if hostile_zip(kind, src, path):
                return
            if kind == "description bomb":
                copy_zip(src, path, lambda n, b: None if n == "modelDescription.xml" else b)
                with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as z:
                    zeros_entry(z, "modelDescription.xml", 100)
            elif kind == "20000 entries":
                copy_zip(src, path, extra={f"resources/e{k}": b"" for k in range(20_000)})
            elif kind == "truncated zip":
                path.write_bytes(src.read_bytes()[: src.stat().st_size // 2])
            elif kind == "corrupt CRC":
                data = bytearray(src.read_bytes())
                k = data.find(b"\x7fELF")
                data[k + 5000: k + 5010] = b"0123456789"  # inside the stored (deflated) binary: CRC mismatch
                path.write_bytes(bytes(data))
            elif kind == "zip without description":
                with zipfile.ZipFile(path, "w") as z:
                    z.writestr("other.txt", "x")
            elif kind == "plain text":
                path.write_text("not a zip")
            elif kind == "empty file":
                path.write_bytes(b"")
            elif kind == "a folder":
                path.mkdir()
            elif kind == "a FIFO":
                os.mkfifo(path)
        return setup

    fmi1 = ('<?xml version="1.0"?><fmiModelDescription fmiVersion="1.0" modelName="m" modelIdentifier="m" '
            'guid="{1}" numberOfContinuousStates="0" numberOfEventIndicators="0"><ModelVariables/>'
            '</fmiModelDescription>')
    me_only = ('<?xml version="1.0"?><fmiModelDescription fmiVersion="2.0" modelName="m" guid="{1}">'
               '<ModelExchange modelIdentifier="m"/><ModelVariables/><ModelStructure/></fmiModelDescription>')
    xxe = ('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
           '<fmiModelDescription fmiVersion="2.0" modelName="&e;" guid="{1}"><CoSimulation modelIdentifier="m"/>'
           '<ModelVariables/><ModelStructure/></fmiModelDescription>')
    entity_bomb = ('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaaaaaaaa">' + "".join(
        f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi", strict=True))
        + ']><fmiModelDescription fmiVersion="2.0" modelName="&i;" guid="{1}"><CoSimulation modelIdentifier="m"/>'
        '<ModelVariables/><ModelStructure/></fmiModelDescription>')
    setups: dict[str, Callable[[Path], None]] = {f"binary: {h}": binary(h) for h in (
        "garbage", "truncated", "empty", "other cpu", "32-bit", "big-endian", "not a shared object",
        "zeros in the middle", "no binary")}
    setups.update({"description: FMI 1.0": md(fmi1), "description: model exchange only": md(me_only),
                   "description: not XML": md("<<<"), "description: empty": md(""),
                   "description: missing": md(None), "description: external entity": md(xxe),
                   "description: entity expansion": md(entity_bomb),
                   "description: wrong root": md('<?xml version="1.0"?><x/>')})
    setups.update({f"archive: {k}": archive(k) for k in (
        "traversal", "absolute", "symlink", "bomb", "description bomb", "20000 entries", "truncated zip",
        "corrupt CRC", "zip without description", "plain text", "empty file", "a folder", "a FIFO")})
    cases = [Case("FMUs", name, "run.py", [str(SC / "elcentro.yaml"), "--set", SHORT, "--set",
                                           "units.isolator.fmu=bad.fmu", "--out", "out", "--quiet", "--no-plots"],
                  setup) for name, setup in setups.items()]
    for name, path in (("/dev/zero", "/dev/zero"), ("missing", "nowhere.fmu"), ("/etc/passwd", "/etc/passwd")):
        cases.append(Case("FMUs", f"FMU is {name}", "run.py", [str(SC / "elcentro.yaml"), "--set", SHORT, "--set",
                                                              f"units.isolator.fmu={path}", "--out", "out",
                                                              "--quiet"]))
    return cases


def ssp_cases(rng: random.Random, n: int, package: Path) -> list[Case]:
    """An exported SSP with one attribute changed, and hostile archives."""
    from lxml import etree

    values = ["abc", "INF", "-INF", "NaN", "", "1e400", "../../x", "/etc/passwd", "0", "-1", "true", "1_0",
              "resources/../../x", "\xe9", "1e-3", "x" * 3000]
    with zipfile.ZipFile(package) as z:
        members = {n: z.read(n) for n in z.namelist() if n.endswith((".ssd", ".ssv"))}
    out = []
    for k in range(n):
        member = rng.choice(sorted(members))
        root = etree.fromstring(members[member])
        elements = [e for e in root.iter() if isinstance(e.tag, str) and (e.attrib or (e.text and e.text.strip()))]
        element = rng.choice(elements)
        attrs = [*element.attrib, *(["#text"] if element.text and element.text.strip() else [])]
        attr = rng.choice(attrs)
        op = rng.choice(["set", "set", "set", "delete"])
        value = rng.choice(values)
        if attr == "#text":
            element.text = value if op == "set" else ""
        elif op == "set":
            element.set(attr, value)
        else:
            del element.attrib[attr]
        data = etree.tostring(root)
        tag = etree.QName(element).localname
        label = f"{k:03d} {member.rsplit('/', 1)[-1]} {tag}@{attr} {op}" + (f" {value!r}"[:30] if op == "set" else "")

        def setup(d: Path, member: str = member, data: bytes = data) -> None:
            copy_zip(package, d / "p.ssp", lambda name, raw: data if name == member else raw)
        tool = rng.choice(["run.py", "run.py", "ssp.py"])
        argv = ["p.ssp", "--out", "out", "--quiet", "--no-plots"] if tool == "run.py" else ["check", "p.ssp"]
        out.append(Case("SSP: one attribute changed", label, tool, argv, setup,
                        out="out" if tool == "run.py" else None))

    def hostile(kind: str) -> Callable[[Path], None]:
        def setup(d: Path) -> None:
            path = d / "p.ssp"
            ssd = lambda f: (lambda n, b: f(b) if n.endswith(".ssd") else b)  # noqa: E731
            if hostile_zip(kind, package, path):
                return
            if kind == "20000 entries":
                copy_zip(package, path, extra={f"resources/e{k}": b"" for k in range(20_000)})
            elif kind == "no SSD":
                copy_zip(package, path, lambda n, b: None if n.endswith(".ssd") else b)
            elif kind == "truncated":
                path.write_bytes(package.read_bytes()[: package.stat().st_size // 2])
            elif kind == "not a zip":
                path.write_text("plain text")
            elif kind == "FMU removed":
                copy_zip(package, path, lambda n, b: None if n.endswith("MreIsolator.fmu") else b)
            elif kind == "record removed":
                copy_zip(package, path, lambda n, b: None if n.endswith(".csv") else b)
            elif kind == "record replaced by garbage":
                copy_zip(package, path, lambda n, b: b"0,0\n0.01,1_0\n" if n.endswith(".csv") else b)
            elif kind == "settings set units":
                copy_zip(package, path, ssd(lambda b: b.replace(
                    b'"format": 1,', b'"format": 1, "units": {"x": {"fmu": "/etc/passwd"}},')))
            elif kind == "settings set name":
                copy_zip(package, path, ssd(lambda b: b.replace(b'"format": 1,', b'"format": 1, "name": "../x",')))
            elif kind == "settings set stop_time":
                copy_zip(package, path, ssd(lambda b: b.replace(b'"step":', b'"stop_time": 1e9, "step":')))
            elif kind == "settings not JSON":
                copy_zip(package, path, ssd(lambda b: b.replace(b'"format": 1,', b'"format": 1,,,')))
            elif kind == "settings a list":
                copy_zip(package, path, ssd(lambda b: b.replace(b"<mre:Settings>{", b"<mre:Settings>[{").replace(
                    b"}</mre:Settings>", b"}]</mre:Settings>")))
            elif kind == "results outside":
                copy_zip(package, path, ssd(lambda b: b.replace(b'"dir": "runs"', b'"dir": "/tmp/outside"')))
            elif kind == "results with ..":
                copy_zip(package, path, ssd(lambda b: b.replace(b'"dir": "runs"', b'"dir": "../../up"')))
            elif kind == "name with /":
                copy_zip(package, path, ssd(lambda b: b.replace(b'name="elcentro"', b'name="../../escape"', 1)))
            elif kind == "stopTime INF":
                copy_zip(package, path, ssd(lambda b: b.replace(b'stopTime="0.05"', b'stopTime="INF"')))
            elif kind == "stopTime 1e9":
                copy_zip(package, path, ssd(lambda b: b.replace(b'stopTime="0.05"', b'stopTime="1e9"')))
            elif kind == "external entity":
                copy_zip(package, path, ssd(lambda b: b.replace(
                    b"<?xml version='1.0' encoding='UTF-8'?>",
                    b"<?xml version='1.0' encoding='UTF-8'?><!DOCTYPE x [<!ENTITY e SYSTEM 'file:///etc/passwd'>]>"
                ).replace(b'name="elcentro"', b'name="&e;"', 1)))
            elif kind == "entity expansion":
                ents = "<!ENTITY a 'aaaaaaaaaa'>" + "".join(
                    f"<!ENTITY {c} '{('&' + p + ';') * 10}'>" for p, c in zip("abcdefgh", "bcdefghi", strict=True))
                copy_zip(package, path, ssd(lambda b: b.replace(
                    b"<?xml version='1.0' encoding='UTF-8'?>",
                    f"<?xml version='1.0' encoding='UTF-8'?><!DOCTYPE x [{ents}]>".encode()).replace(
                    b'description="', b'description="&i;', 1)))
            elif kind == "SSD not XML":
                copy_zip(package, path, ssd(lambda b: b"<<<not xml"))
            elif kind == "SSD 70 MB":
                copy_zip(package, path, ssd(lambda b: b.replace(b"</ssd:SystemStructureDescription>",
                                                                b"<!--" + b"x" * (70 << 20) + b"-->"
                                                                b"</ssd:SystemStructureDescription>")))
        return setup

    kinds = ["traversal", "absolute", "symlink", "bomb", "20000 entries", "no SSD", "truncated", "not a zip",
             "FMU removed", "record removed", "record replaced by garbage", "settings set units", "settings set name",
             "settings set stop_time", "settings not JSON", "settings a list", "results outside", "results with ..",
             "name with /", "stopTime INF", "stopTime 1e9", "external entity", "entity expansion", "SSD not XML",
             "SSD 70 MB"]
    for kind in kinds:
        out.append(Case("SSP: hostile packages", kind, "run.py", ["p.ssp", "--out", "out", "--quiet", "--no-plots"],
                        hostile(kind)))
    for kind in ("traversal", "bomb", "settings set units", "stopTime INF", "entity expansion"):
        out.append(Case("SSP: hostile packages", f"check: {kind}", "ssp.py", ["check", "p.ssp"], hostile(kind),
                        out=None))
    return out


def output_cases() -> list[Case]:
    """Output folders that are taken, unusable, full or read-only."""
    elc = [str(SC / "elcentro.yaml"), "--set", SHORT, "--quiet", "--no-plots"]
    out = [
        Case("output folders", "--out below a file", "run.py", [*elc, "--out", f"{PRECIOUS}/sub"], out=None),
        Case("output folders", "--out in /proc", "run.py", [*elc, "--out", "/proc/mre-corpus/run"], out=None),
        Case("output folders", "--out is a file", "run.py", [*elc, "--out", PRECIOUS], out=None),
        Case("output folders", "--out is a non-empty folder", "run.py", [*elc, "--out", "prev"],
             lambda d: _previous_run(d / "prev"), out=None),
        Case("output folders", "--out is an empty folder", "run.py", [*elc, "--out", "out"],
             lambda d: (d / "out").mkdir()),
        Case("output folders", "--out is a symlink to a full folder", "run.py", [*elc, "--out", "link"],
             lambda d: (_previous_run(d / "prev"), os.symlink("prev", d / "link")), out=None),
        Case("output folders", "--out is /dev/null", "run.py", [*elc, "--out", "/dev/null"], out=None),
        Case("output folders", "results.dir below a file", "run.py", [*elc, "--set", f"results.dir={PRECIOUS}/x"],
             out=None),
        Case("output folders", "results.dir in /proc", "run.py", [*elc, "--set", "results.dir=/proc/x"], out=None),
        Case("output folders", "results.dir holds a previous run", "run.py", [*elc, "--set", "results.dir=runs"],
             lambda d: _previous_run(d / "runs" / "elcentro-previous"), out="runs"),
    ]
    if IS_ROOT:
        out += [
            Case("full or read-only disks", "1 MiB disk fills while writing results", "run.py",
                 [str(SC / "kobe.yaml"), "--set", "simulation.stop_time=20", "--out", "out/run", "--quiet",
                  "--no-plots"], mount="full"),
            Case("full or read-only disks", "1 MiB disk fills while writing plots", "run.py",
                 [str(SC / "elcentro.yaml"), "--set", "simulation.stop_time=2.5", "--out", "out/run", "--quiet"],
                 mount="full"),
            Case("full or read-only disks", "disk full before the run", "run.py",
                 [*elc, "--out", "out/run"], mount="full-before"),
            Case("full or read-only disks", "read-only --out", "run.py", [*elc, "--out", "out/run"],
                 mount="readonly"),
            Case("full or read-only disks", "read-only results.dir", "run.py",
                 [*elc, "--set", "results.dir=out/runs"], mount="readonly"),
            Case("full or read-only disks", "ssp export to a read-only folder", "ssp.py",
                 ["export", str(SC / "elcentro.yaml"), "out/x.ssp"], mount="readonly"),
            Case("full or read-only disks", "ssp export to a 256 KiB disk", "ssp.py",
                 ["export", str(SC / "kobe.yaml"), "out/x.ssp"], mount="full", mount_size="256K"),
            Case("full or read-only disks", "build into a read-only folder", "build", ["--dest", "out/fmus"],
                 mount="readonly"),
            Case("full or read-only disks", "tune.py --out on a read-only folder", "tune.py",
                 [str(SC / "case_study.yaml"), "--out", "out/gains.yaml", "--set", "tuning.max_evals=2",
                  "--quiet"], mount="readonly", timeout=600),
            Case("full or read-only disks", "identify.py --out on a read-only folder", "identify.py",
                 ["id.yaml", "--out", "out/id", "--no-progress"], _id_config, mount="readonly"),
        ]
    else:
        out.append(Case("full or read-only disks", "writes fail with EFBIG (RLIMIT_FSIZE)", "run.py",
                        [str(SC / "kobe.yaml"), "--set", "simulation.stop_time=20", "--out", "out", "--quiet",
                         "--no-plots"], mount="fsize"))
    return out


def _previous_run(folder: Path) -> None:
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text('{"complete": true, "note": "a previous run: must survive"}')


def _id_config(d: Path) -> None:
    (d / "id.yaml").write_text(yaml.safe_dump({
        "data": {"conditions": [[4, 2, 0], [4, 2, 3]], "synthetic": {"repeats": 1}},
        "identifiers": ["hyperbolic-structured"], "bouc_wen_joint": {"enabled": False}, "figures": False}))


def fault_cases() -> list[Case]:
    """Signals during start-up and during a run; concurrent runs into one --out."""
    out = []
    kobe = [str(SC / "kobe.yaml"), "--out", "out", "--quiet", "--no-plots"]
    for sig in (signal.SIGINT, signal.SIGTERM):
        for delay in (0.15, 0.3, 0.5, 0.8, 1.2, 1.8, 2.5, 3.5, 5.0, 7.0):
            out.append(Case("signals", f"{sig.name} after {delay} s (Kobe, 150 s)", "run.py", kobe,
                            signal_after=(sig, delay), timeout=300))
    out.append(Case("signals", "SIGINT during an SSP run", "run.py", ["p.ssp", "--out", "out", "--quiet"],
                    lambda d: shutil.copy(_PACKAGE_LONG, d / "p.ssp"), signal_after=(signal.SIGINT, 3.0)))
    out.append(Case("signals", "SIGTERM to ssp.py export", "ssp.py", ["export", str(SC / "kobe.yaml"), "x.ssp"],
                    signal_after=(signal.SIGTERM, 1.0), out="x.ssp"))
    out.append(Case("signals", "SIGINT to study.py while starting", "study.py",
                    [str(SC / "case_study.yaml"), "--out", "out", "--quiet"], signal_after=(signal.SIGINT, 0.8)))
    out.append(Case("signals", "SIGTERM to study.py while running", "study.py",
                    [str(SC / "case_study.yaml"), "--out", "out", "--quiet", "--workers", "1"],
                    signal_after=(signal.SIGTERM, 6.0), timeout=300))
    out.append(Case("signals", "SIGINT to identify.py", "identify.py", ["id.yaml", "--out", "out", "--no-progress"],
                    _id_config, signal_after=(signal.SIGINT, 2.0)))
    out.append(Case("signals", "SIGTERM to tune.py", "tune.py", [str(SC / "case_study.yaml"), "--out", "g.yaml",
                                                                 "--quiet"], signal_after=(signal.SIGTERM, 3.0),
                    out="g.yaml"))
    for k, (n, existing) in enumerate([(2, False), (2, True), (3, False), (4, False), (2, False), (3, True)]):
        out.append(Case("concurrent runs, one --out", f"{n} runs{' into an empty folder' if existing else ''} #{k}",
                        "run.py", [str(SC / "elcentro.yaml"), "--set", "simulation.stop_time=0.5", "--out", "out",
                                   "--quiet", "--no-plots"], (lambda d: (d / "out").mkdir()) if existing else None,
                        copies=n))
    return out


_PACKAGE_LONG: Path = Path()


def other_tool_cases() -> list[Case]:
    """study.py, tune.py, identify.py, ssp.py and the build with hostile files and arguments."""
    out = []
    files: dict[str, Callable[[Path], None]] = {
        "latin-1": write_bytes("f.yaml", b"name: caf\xe9\n"),
        "deep nesting": write_bytes("f.yaml", ("a: " + "[" * 5000 + "]" * 5000).encode()),
        "billion laughs": write_bytes("f.yaml", ("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
            f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True))
        ).encode()),
        "recursive alias": write_bytes("f.yaml", b"a: &a [*a]\n"),
        "a FIFO": lambda d: os.mkfifo(d / "f.yaml"),
        "a folder": lambda d: (d / "f.yaml").mkdir(),
        "empty": write_bytes("f.yaml", b""),
        "a list": write_bytes("f.yaml", b"- 1\n"),
        "a run scenario": lambda d: shutil.copy(SC / "elcentro.yaml", d / "f.yaml"),
    }
    for tool, extra in (("study.py", ["--out", "out", "--quiet"]), ("tune.py", ["--out", "g.yaml", "--quiet"]),
                        ("identify.py", ["--out", "out", "--no-progress"])):
        for name, setup in files.items():
            # an empty identification file is the default identification, minutes of real work on 2 cores
            slow = tool == "identify.py" and name == "empty"
            out.append(Case(f"other tools: {tool.removesuffix('.py')}", f"{name}", tool, ["f.yaml", *extra], setup,
                            out="g.yaml" if tool == "tune.py" else "out", timeout=900.0 if slow else 120.0))
        out.append(Case(f"other tools: {tool.removesuffix('.py')}", "/dev/zero", tool, ["/dev/zero", *extra],
                        out="g.yaml" if tool == "tune.py" else "out"))
    study = str(SC / "case_study.yaml")
    for args in (["--workers", "0"], ["--set", "records=[]"], ["--set", "strategies=[magic]"],
                 ["--set", "x=&a [*a]"], ["--set", "workers=maybe"], ["--set", "name=../x"], ["--out", f"{PRECIOUS}/x"],
                 ["--report", "nowhere"], ["--report", "."], ["--set", "overrides=[simulation.stop_time=.inf]"]):
        out.append(Case("other tools: study", " ".join(args)[:60], "study.py", [study, *args, "--quiet"]))
    for args in (["--out", PRECIOUS], ["--set", "tuning.record=nowhere"], ["--set", "tuning.max_evals=true"],
                 ["--set", "x=&a [*a]"], ["--out", f"{PRECIOUS}/x", "--force", "--set", "tuning.max_evals=2"]):
        out.append(Case("other tools: tune", " ".join(args)[:60], "tune.py", [study, *args, "--quiet"],
                        out=None))
    for name, cfg in (("unknown key", {"nonsense": 1}), ("conditions a string", {"data": {"conditions": "x"}}),
                      ("negative repeats", {"data": {"synthetic": {"repeats": -1}}}),
                      ("unknown identifier", {"identifiers": ["magic"]}), ("a boolean", {"figures": "maybe"})):
        out.append(Case("other tools: identify", name, "identify.py", ["id.yaml", "--out", "out", "--no-progress"],
                        lambda d, cfg=cfg: (d / "id.yaml").write_text(yaml.safe_dump(cfg))))
    out.append(Case("other tools: identify", "--out is the working folder with --overwrite", "identify.py",
                    ["id.yaml", "--out", ".", "--overwrite", "--no-progress"], _id_config, out=None))
    out.append(Case("other tools: identify", "--out is a file", "identify.py",
                    ["id.yaml", "--out", PRECIOUS, "--no-progress"], _id_config, out=None))
    for name, args in (("--dpi nan", ["--dpi", "nan"]), ("--dpi 0", ["--dpi", "0"]), ("--dpi -5", ["--dpi", "-5"]),
                       ("--dpi of 10^30", ["--dpi", "1" + "0" * 30]), ("--format png", ["--format", "png"]),
                       ("--format ../x", ["--format", "../x"])):
        out.append(Case("other tools: identify", name, "identify.py",
                        ["id.yaml", "--out", "out", "--no-progress", *args], _id_config))
    for name, argv in (("export to a folder", ["export", str(SC / "elcentro.yaml"), "."]),
                       ("export over a file", ["export", str(SC / "elcentro.yaml"), PRECIOUS]),
                       ("export below a file", ["export", str(SC / "elcentro.yaml"), f"{PRECIOUS}/x.ssp"]),
                       ("export to /proc", ["export", str(SC / "elcentro.yaml"), "/proc/x.ssp"]),
                       ("export a FIFO", ["export", "f.yaml", "x.ssp"]),
                       ("export to /dev/null with --force", ["export", str(SC / "elcentro.yaml"), "/dev/null",
                                                              "--force"]),
                       ("check a YAML", ["check", str(SC / "elcentro.yaml")]), ("check /dev/zero", ["check",
                                                                                                    "/dev/zero"]),
                       ("check a FIFO", ["check", "f.yaml"]), ("no command", []), ("unknown command", ["nope"])):
        out.append(Case("other tools: ssp", name, "ssp.py", argv,
                        (lambda d: os.mkfifo(d / "f.yaml")) if "FIFO" in name else None, out="x.ssp"))
    for name, argv in (("--dest below a file", ["--dest", f"{PRECIOUS}/sub"]), ("--dest in /proc", ["--dest",
                                                                                                  "/proc/x"]),
                       ("--dest is a file", ["--dest", PRECIOUS]), ("--storeys 0", ["--storeys", "0"]),
                       ("--storeys -3", ["--storeys", "-3"]), ("--storeys 10000", ["--storeys", "10000"]),
                       ("--storeys x", ["--storeys", "x"]), ("unknown option", ["--nope"])):
        out.append(Case("other tools: build", name, "build", argv, out=None))
    return out


# -- the engine: environment, provenance, the Python API, exit classes, messages ---------

ENGINE = "26/engine"
"""Prefix of these classes: ``--only 26/engine`` runs them alone."""
INTERNALS = ("NoneType", "list index", "int()", "invalid literal", "local variable", "not iterable", "Traceback")


def _elc(*sets: str, out: str = "out") -> list[str]:
    return [str(SC / "elcentro.yaml"), "--set", SHORT, *[a for x in sets for a in ("--set", x)], "--out", out,
            "--quiet", "--no-plots"]


def _says(*words: str, never: tuple[str, ...] = ()) -> Callable[[Path, list[int], str], list[str]]:
    """Verification: stderr holds every word and none of ``never`` (nor a parser's internals)."""
    def check(work: Path, codes: list[int], err: str) -> list[str]:
        missing = [w for w in words if w not in err]
        leaked = [w for w in (*never, *INTERNALS) if w in err]
        return ([f"the message lacks {missing}"] if missing else []) + ([f"the message has {leaked}"] if leaked else [])
    return check


def _marked_if_said(work: Path, codes: list[int], err: str) -> list[str]:
    """'marked incomplete' is said only when summary.json or manifest.json of the run folder says so."""
    if "(marked incomplete)" not in err:
        return []
    for name in ("summary.json", "manifest.json"):
        try:
            if json.loads((work / "out" / "run" / name).read_text()).get("complete") is False:
                return []
        except (OSError, ValueError):
            continue
    return ["says 'partial results (marked incomplete)' but no file of the folder marks it"]


def _bounded_isolator(d: Path) -> None:
    """The isolator FMU with declared bounds: n_isolators in [1, 8], i_max in [0, 5] A."""
    import re

    def edit(name: str, raw: bytes) -> bytes:
        if name != "modelDescription.xml":
            return raw
        text = re.sub(r'(name="n_isolators"[^>]*>\s*<Integer) ', r'\1 min="1" max="8" ', raw.decode(), count=1)
        return re.sub(r'(name="i_max"[^>]*>\s*<Real) ', r'\1 min="0" max="5" ', text, count=1).encode()
    copy_zip(FMUS / "MreIsolator.fmu", d / "bounded.fmu", edit)


def _md_edit(pattern: str, replacement: str, flags: int = 0) -> Callable[[Path], None]:
    import re

    def setup(d: Path) -> None:
        copy_zip(FMUS / "MreIsolator.fmu", d / "bad.fmu", lambda n, b: re.sub(pattern, replacement, b.decode(), count=1,
                                                                               flags=flags).encode()
                 if n == "modelDescription.xml" else b)
    return setup


def _sha(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


_ZERO_RECORD = b"time_s,accel_g\n" + b"".join(f"{k * 0.01:.2f},0\n".encode() for k in range(1001))


def _record_truth(work: Path, codes: list[int], err: str) -> list[str]:
    """A record rewritten with zeros while the run goes: manifest.json's hash is of what was played.

    Exit 0: the hash is the original's and the ground moved, or the zeros' and it did not; exit 1:
    the message names the record."""
    if codes == [1]:
        return [] if "r.csv" in err else ["exit 1 without naming the record"]
    if codes != [0]:
        return [f"exit {codes}, expected 0 or 1"]
    manifest = json.loads((work / "out" / "manifest.json").read_text())
    digest = manifest["data_files"]["ground.record"]["sha256"]
    with open(work / "out" / "timeseries.csv") as f:
        header = f.readline().strip().split(",")
        k = header.index("ground.ag")
        moved = any(float(line.split(",")[k]) != 0.0 for line in f)
    import hashlib

    zeros = hashlib.sha256(_ZERO_RECORD).hexdigest()
    if digest == zeros:
        return [] if not moved else ["manifest has the zero record's hash but the ground moved"]
    if digest == (work / "original.sha").read_text():
        return [] if moved else ["manifest has the original record's hash but the ground did not move"]
    return ["manifest hash is of neither record"]


def _fmu_truth(work: Path, codes: list[int], err: str) -> list[str]:
    """An FMU changed while the run goes: exit 1 naming it, or exit 0 with a hash of one of its two versions."""
    if codes == [1]:
        return [] if "iso.fmu" in err else ["exit 1 without naming the FMU"]
    if codes != [0]:
        return [f"exit {codes}, expected 0 or 1"]
    digest = json.loads((work / "out" / "manifest.json").read_text())["fmus"]["isolator"]["sha256"]
    return [] if digest in ((work / "original.sha").read_text(), _sha(work / "iso.fmu")) else \
        ["manifest hash is of neither version of the FMU"]


def _api(body: str) -> Callable[[Path], None]:
    """Setup: ``api_case.py`` running ``body`` (which may set ``res``); exit 2 on TypeError, ValueError or
    ScenarioError, 1 on a failed result, 0 on a complete one; anything else is a traceback (not clean)."""
    text = (f"import sys\nsys.path.insert(0, {str(PROJECT)!r})\nfrom pathlib import Path\nimport shutil, zipfile\n"
            "from orchestration.api import ScenarioError, load_scenario, run\n"
            "from orchestration.master.execution import StopRequest\n"
            f"SC = Path({str(SC)!r}); FMUS = Path({str(FMUS)!r}); SHORT = {SHORT!r}\nres = None\ntry:\n"
            + "".join(f"    {line}\n" for line in body.splitlines())
            + "except (TypeError, ValueError, ScenarioError) as exc:\n"
              "    print(f'error: {type(exc).__name__}: {exc}', file=sys.stderr)\n    sys.exit(2)\n"
              "if res is None:\n    sys.exit(0)\n"
              "print(res.status, res.error, file=sys.stdout if res.complete else sys.stderr)\n"
              "sys.exit(0 if res.complete else 1)\n")

    def setup(d: Path) -> None:  # the files a script uses exist before the case (it writes only its run folder)
        (d / "api_case.py").write_text(text)
        shutil.copy(FMUS / "MreIsolator.fmu", d / "iso.fmu")
        shutil.copy(RECORDS / "elcentro_1940_ns.csv", d / "r.csv")
        (d / "s.yaml").write_text(f"extends: {SC / 'elcentro.yaml'}\nsimulation: {{stop_time: 0.05}}\n")
    return setup


def engine_cases(base: Path, package: Path) -> list[Case]:
    """The engine: MRE_COSIM_* values, inputs changed during a run, the Python API's arguments,
    problems known before the first step, and messages that say what a file is."""
    out: list[Case] = []
    # 10: environment variables
    bad_values = ["abc", "nan", "-1", "0", "inf", "-inf", "1e300", "0x10", "1,5", "5 MB"]
    for name in ("MRE_COSIM_MAX_UNPACKED_MB", "MRE_COSIM_MAX_RESULT_MB", "MRE_COSIM_SPILL_MB"):
        for value in bad_values:
            if name == "MRE_COSIM_SPILL_MB" and value == "0":
                continue  # 0 means "always spill": it must run
            out.append(Case(f"{ENGINE}: environment variables", f"{name}={value}", "run.py", _elc(),
                            env={name: value}, verify=_says(name, repr(value))))
    out += [
        Case(f"{ENGINE}: environment variables", "MRE_COSIM_SPILL_MB=0 (always spill) runs", "run.py", _elc(),
             env={"MRE_COSIM_SPILL_MB": "0"}, verify=lambda w, c, e: [] if c == [0] else [f"exit {c}"]),
        Case(f"{ENGINE}: environment variables", "MRE_COSIM_MAX_RESULT_MB=0.001 refuses the run", "run.py", _elc(),
             env={"MRE_COSIM_MAX_RESULT_MB": "0.001"}, verify=_says("MRE_COSIM_MAX_RESULT_MB", "more than")),
        Case(f"{ENGINE}: environment variables", "MRE_COSIM_MAX_UNPACKED_MB=abc, ssp.py check", "ssp.py",
             ["check", str(package)], env={"MRE_COSIM_MAX_UNPACKED_MB": "abc"},
             verify=_says("MRE_COSIM_MAX_UNPACKED_MB")),
        Case(f"{ENGINE}: environment variables", "MRE_COSIM_MAX_UNPACKED_MB=-1, run an SSP", "run.py",
             [str(package), "--out", "out", "--quiet", "--no-plots"], env={"MRE_COSIM_MAX_UNPACKED_MB": "-1"},
             verify=_says("MRE_COSIM_MAX_UNPACKED_MB")),
        Case(f"{ENGINE}: environment variables", "MRE_COSIM_SPILL_MB=nan, ssp.py export", "ssp.py",
             ["export", str(SC / "elcentro.yaml"), "x.ssp"], env={"MRE_COSIM_SPILL_MB": "nan"}, out="x.ssp",
             verify=_says("MRE_COSIM_SPILL_MB")),
    ]
    # 2: provenance, inputs changed while the run goes
    def record_setup(d: Path) -> None:
        shutil.copy(RECORDS / "elcentro_1940_ns.csv", d / "r.csv")
        (d / "original.sha").write_text(_sha(d / "r.csv"))

    def fmu_setup(d: Path) -> None:
        shutil.copy(FMUS / "MreIsolator.fmu", d / "iso.fmu")
        (d / "original.sha").write_text(_sha(d / "iso.fmu"))

    def append_entry(d: Path) -> None:
        with zipfile.ZipFile(d / "iso.fmu", "a") as z:
            z.writestr("resources/changed.txt", "changed during the run")

    for delay in (0.3, 0.8, 1.5, 2.5, 4.0, 6.0):
        out.append(Case(f"{ENGINE}: provenance", f"record rewritten {delay} s into the run", "run.py",
                        [str(SC / "elcentro.yaml"), "--set", "simulation.stop_time=3", "--set",
                         "ground.record=!record r.csv", "--out", "out", "--quiet", "--no-plots"], record_setup,
                        during=(delay, lambda d: (d / "r.csv").write_bytes(_ZERO_RECORD)), changes=("r.csv",),
                        verify=_record_truth))
    for delay in (0.5, 2.0, 4.0):
        out.append(Case(f"{ENGINE}: provenance", f"FMU changed {delay} s into the run", "run.py",
                        [str(SC / "elcentro.yaml"), "--set", "simulation.stop_time=3", "--set",
                         "units.isolator.fmu=iso.fmu", "--out", "out", "--quiet", "--no-plots"], fmu_setup,
                        during=(delay, append_entry), changes=("iso.fmu",), verify=_fmu_truth))
    # 8: the Python API
    load = "load_scenario(SC / 'elcentro.yaml', [SHORT])"
    with_fmu = "plan = load_scenario(SC / 'elcentro.yaml', [SHORT, 'units.isolator.fmu=iso.fmu'])\n"
    with_record = "plan = load_scenario(SC / 'elcentro.yaml', [SHORT, 'ground.record=!record r.csv'])\n"
    api_cases = {
        "data_dirs given as one string": "plan = load_scenario(str(SC / 'elcentro.yaml'), [SHORT, "
                                         "'ground.record=!record r.csv'], data_dirs='.')\n"
                                         "assert plan.data_files['ground.record'] == Path('r.csv').resolve()\n"
                                         "res = run(plan, out='out')",
        "overrides given as one string": "res = run(load_scenario(SC / 'elcentro.yaml', SHORT), out='out')",
        "run() given a scenario path": "res = run('s.yaml', out='out')",
        "run() given a missing path": "res = run('nowhere.yaml', out='out')",
        "run() given a dict": "res = run({'units': {}}, out='out')",
        "run() given None": "res = run(None, out='out')",
        "stop=5": f"res = run({load}, out='out', stop=5)",
        "stop='now'": f"res = run({load}, out='out', stop='now')",
        "plots='yes'": f"res = run({load}, out='out', plots='yes')",
        "out=7": f"res = run({load}, out=7)",
        "out=''": f"res = run({load}, out='')",
        "load_scenario(None)": "res = run(load_scenario(None), out='out')",
        "overrides=[1.5]": "res = run(load_scenario(SC / 'elcentro.yaml', [1.5]), out='out')",
        "data_dirs=5": "res = run(load_scenario(SC / 'elcentro.yaml', [SHORT], data_dirs=5), out='out')",
        "FMU replaced by garbage between load and run": with_fmu
            + "Path('iso.fmu').write_bytes(b'garbage')\nres = run(plan, out='out')",
        "FMU deleted between load and run": with_fmu + "Path('iso.fmu').unlink()\nres = run(plan, out='out')",
        "FMU given another entry between load and run": with_fmu + "with zipfile.ZipFile('iso.fmu', 'a') as z:\n"
            "    z.writestr('resources/x.txt', 'x')\nres = run(plan, out='out')",
        "record rewritten between load and run": with_record
            + "Path('r.csv').write_text('time_s,accel_g\\n0,0\\n0.05,0.1\\n')\nres = run(plan, out='out')",
        "stop set before the run": "stop = StopRequest()\nstop.set('asked')\n"
                                   f"res = run({load}, out='out', stop=stop)",
    }
    expect = {"FMU replaced by garbage between load and run": 1, "FMU deleted between load and run": 1,
              "FMU given another entry between load and run": 1, "record rewritten between load and run": 1,
              "stop set before the run": 1, "data_dirs given as one string": 0, "overrides given as one string": 0,
              "run() given a scenario path": 0}
    for name, body in api_cases.items():
        want = expect.get(name, 2)
        out.append(Case(f"{ENGINE}: Python API", name, "api", [], _api(body), changes=("iso.fmu", "r.csv"),
                        verify=lambda w, c, e, want=want: [] if c == [want] else [f"exit {c}, expected {want}"]))
    # 9: exit classes
    typed = base / "typed"
    typed.mkdir(exist_ok=True)
    try:
        from tests.support.typed_build import build_typed2

        typed_fmu: Path | None = build_typed2(typed)
    except Exception:  # no C compiler: the native cases are left out
        typed_fmu = None
    if typed_fmu is not None:
        for outputs, label in (("all", "typed outputs"), ("[]", "nothing recorded")):
            text = (f"name: typed\nunits:\n  a:\n    fmu: {typed_fmu}\nconnections: []\noutputs: {outputs}\n"
                    "simulation: {step: 0.1, stop_time: 0.5, executor: native}\n")
            want = 2 if outputs == "all" else None
            out.append(Case(f"{ENGINE}: exit class", f"executor native, FMI types, {label}", "run.py",
                            ["s.yaml", "--out", "out", "--quiet", "--no-plots"],
                            lambda d, text=text: (d / "s.yaml").write_text(text),
                            verify=(_says("simulation.executor", "native") if want == 2 else None)))
    out.append(Case(f"{ENGINE}: exit class", "executor native on a Real system runs", "run.py",
                    _elc("simulation.executor=native"), verify=lambda w, c, e: [] if c == [0] else [f"exit {c}"]))
    for setting, ok in (("isolator.n_isolators=0", False), ("isolator.n_isolators=9", False),
                        ("isolator.n_isolators=-1", False), ("isolator.n_isolators=8", True),
                        ("isolator.i_max=-0.1", False), ("isolator.i_max=5.5", False), ("isolator.i_max=1e9", False),
                        ("isolator.i_max=5", True)):
        out.append(Case(f"{ENGINE}: exit class", f"declared min/max: {setting}", "run.py",
                        _elc("units.isolator.fmu=bounded.fmu", setting), _bounded_isolator,
                        verify=(lambda w, c, e: [] if c == [0] else [f"exit {c}"]) if ok
                        else _says("outside its declared range")))
    bad_records = {"empty": b"", "header only": b"time_s,accel_g\n", "one sample": b"0,0\n",
                   "binary": bytes(range(256)) * 8, "time going back": b"0,0\n0.02,1\n0.01,2\n",
                   "NaN sample": b"0,0\n0.01,nan\n0.02,0\n", "text": b"hello world\n"}
    for name, data in bad_records.items():
        out.append(Case(f"{ENGINE}: exit class", f"!data record: {name}", "run.py",
                        _elc("ground.record=!data r.csv"), write_bytes("r.csv", data), verify=_says("r.csv")))
    plain = {"missing": (None, "not found"), "garbage": (write_bytes("r.csv", b"no numbers\n"), "unreadable record"),
             "a folder": (lambda d: (d / "r.csv").mkdir(), "a folder"),
             "a FIFO": (lambda d: os.mkfifo(d / "r.csv"), "FIFO"),
             "a record": (lambda d: shutil.copy(RECORDS / "elcentro_1940_ns.csv", d / "r.csv"), None)}
    for name, (setup, word) in plain.items():
        out.append(Case(f"{ENGINE}: exit class", f"plain-string record path: {name}", "run.py",
                        _elc("ground.record=r.csv"), setup,
                        verify=_says(word) if word else (lambda w, c, e: [] if c == [0] else [f"exit {c}"])))
    if IS_ROOT:
        for label, argv, size in (("Kobe 20 s on a 1 MiB disk", [str(SC / "kobe.yaml"), "--set",
                                                                "simulation.stop_time=20"], "1M"),
                                  ("Kobe 20 s on a 64 KiB disk", [str(SC / "kobe.yaml"), "--set",
                                                                 "simulation.stop_time=20"], "64K"),
                                  ("El Centro with plots on a 128 KiB disk", [str(SC / "elcentro.yaml"), "--set",
                                                                             "simulation.stop_time=2.5"], "128K")):
            no_plots = [] if "plots" in label else ["--no-plots"]
            out.append(Case(f"{ENGINE}: exit class", f"disk full: {label}", "run.py",
                            [*argv, "--out", "out/run", "--quiet", *no_plots], mount="full", mount_size=size,
                            verify=_marked_if_said))
    for tool, argv in (("run.py", _elc()), ("ssp.py", ["check", str(package)])):
        for delay in (0.05, 0.1, 0.2, 0.3, 0.4):
            out.append(Case(f"{ENGINE}: exit class", f"SIGINT {delay} s after {tool} starts", tool, argv,
                            signal_after=(signal.SIGINT, delay), out="out" if tool == "run.py" else None))
    # 11: messages
    import socket

    def make_socket(path: Path) -> None:
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(path))
        sock.close()

    kinds = {"a FIFO": (lambda d: os.mkfifo(d / "r.csv"), "FIFO"),
             "a folder": (lambda d: (d / "r.csv").mkdir(), "a folder"),
             "/dev/zero": (lambda d: os.symlink("/dev/zero", d / "r.csv"), "a character device"),
             "/dev/null": (lambda d: os.symlink("/dev/null", d / "r.csv"), "a character device"),
             "a symlink to a folder": (lambda d: (os.mkdir(d / "sub"), os.symlink("sub", d / "r.csv")), "a folder"),
             "a socket": (lambda d: make_socket(d / "r.csv"), "a socket")}
    for name, (setup, kind) in kinds.items():
        for tag in ("record", "data"):
            out.append(Case(f"{ENGINE}: messages", f"!{tag} r.csv is {name}", "run.py",
                            _elc(f"ground.record=!{tag} r.csv"), setup, verify=_says(kind, never=("not found",))))
    import re

    descriptions = {
        "no fmiVersion": (r'fmiVersion="2.0" ', "", "fmiVersion"),
        "fmiVersion 1.0": (r'fmiVersion="2.0"', 'fmiVersion="1.0"', "FMI 1.0"),
        "fmiVersion empty": (r'fmiVersion="2.0"', 'fmiVersion=""', "fmiVersion"),
        "variable without name": (r'(<ScalarVariable) name="[^"]*"', r"\1", "ScalarVariable"),
        "variable without valueReference": (r'(<ScalarVariable[^>]*?) valueReference="[^"]*"', r"\1",
                                            "valueReference"),
        "valueReference not a number": (r'valueReference="\d+"', 'valueReference="x"', "valueReference 'x'"),
        "variable without a type element": (r"(<ScalarVariable[^>]*>)\s*<Real[^>]*/>", r"\1", "type elements"),
        "no ModelVariables": (r"<ModelVariables>.*</ModelVariables>", "", "ModelVariables"),
        "output index out of range": (r'<Unknown index="\d+"', '<Unknown index="999"', 'index="999"'),
        "output without index": (r'<Unknown index="\d+"', "<Unknown", "index None"),
        "dependencies not numbers": (r'dependencies="[^"]*"', 'dependencies="a b"', "dependencies 'a'"),
        "BaseUnit exponent not a number": (r'<BaseUnit m="-1" A="-1" />', '<BaseUnit m="x" />', "BaseUnit"),
        "root element renamed": (r"<fmiModelDescription", "<somethingElse", "modelDescription"),
    }
    for name, (pattern, replacement, word) in descriptions.items():
        out.append(Case(f"{ENGINE}: messages", f"modelDescription: {name}", "run.py",
                        _elc("units.isolator.fmu=bad.fmu"), _md_edit(pattern, replacement, re.S),
                        verify=_says(word, "units.isolator.fmu")))
    return out


# -- running and classifying ----------------------------------------------------------------------------

_MOUNT_LOCK = threading.Lock()


# -- the study tools: bounded waits, stores, numbers, names in bytes, extends ---------------

STUDIES = "26/studies"
"""Prefix of these classes: ``--only 26/studies`` runs them alone."""
_LISTENERS: dict[bytes, int] = {}
_FIXTURES: dict[str, Path] = {}
_FIXTURE_LOCK = threading.Lock()
_EMOJI = "\N{GRINNING FACE}"


def _listener(greeting: bytes) -> int:
    """Port of a loopback listener for these cases: accepts, then says ``greeting`` (or nothing) and stays silent.

    A daemon thread: it ends with the corpus, or after an hour by itself.
    """
    import socket

    if greeting in _LISTENERS:
        return _LISTENERS[greeting]
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(16)
    sock.settimeout(0.5)
    end = time.monotonic() + 3600

    def serve() -> None:
        held = []
        while time.monotonic() < end:
            try:
                conn, _ = sock.accept()
            except OSError:
                continue
            if greeting:
                conn.sendall(greeting)
            held.append(conn)
        sock.close()

    threading.Thread(target=serve, daemon=True).start()
    _LISTENERS[greeting] = sock.getsockname()[1]
    return _LISTENERS[greeting]


def _mini_ida_file(folder: Path) -> Path:
    """A one-run IDA study file (one record, one level, one strategy) in ``folder``."""
    suite = folder / "suite"
    suite.mkdir(exist_ok=True)
    shutil.copy(RECORDS / "kobe_1995_jma_ns.csv", suite / "kobe.csv")
    spec = {"name": "mini-ida", "scenario": str(SC / "isolated_building.yaml"), "suite": {"folder": "suite"},
            "time_scale": 0.2, "window": {"tail_s": 0.2}, "intensity": {"measure": "pga", "levels": [0.1]},
            "strategies": ["passive-off"], "gains": str(SC / "sosm_gains.yaml"),
            "limit_states": {"iso15": {"quantity": "isolator_displacement", "threshold": 0.015}},
            "output": "studies"}
    path = folder / "ida.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


MINI_STUDY = ["--set", "overrides=[simulation.stop_time=0.3]", "--set", "records={kobe: kobe.yaml}",
              "--set", "strategies=[passive-off]", "--set", "reference={enabled: false}"]


def _fixture(kind: str, base: Path) -> Path:
    """A finished study folder of ``kind`` (``study`` or ``ida``) made once, on first use, for the cases to damage."""
    with _FIXTURE_LOCK:
        if kind not in _FIXTURES:
            where = base / f"fixture-{kind}"
            where.mkdir(parents=True, exist_ok=True)
            env = {**os.environ, "MRE_COSIM_CODE_VERSION": "corpus"}
            if kind == "study":
                argv = [*TOOLS["study.py"], str(SC / "case_study.yaml"), *MINI_STUDY, "--workers", "1"]
            else:
                argv = [*TOOLS["ida.py"], str(_mini_ida_file(where)), "--workers", "1"]
            subprocess.run([*argv, "--out", str(where / "done"), "--quiet"], cwd=where, env=env, check=True,
                           capture_output=True, timeout=600)
            _FIXTURES[kind] = where / "done"
        return _FIXTURES[kind]


def _damaged(kind: str, base: Path, damage: Callable[[Path], None]) -> Callable[[Path], None]:
    """Setup: a copy of the finished study folder as ``prev`` in the case folder, then ``damage(prev)``."""
    def setup(work: Path) -> None:
        shutil.copytree(_fixture(kind, base), work / "prev")
        (work / "prev" / ".mre-cosim-run").unlink(missing_ok=True)
        damage(work / "prev")
    return setup


def _job(folder: Path) -> Path:
    return sorted((folder / "jobs").glob("*.json"))[0]


def _edit_job(change: Callable[[dict], Any]) -> Callable[[Path], None]:
    def damage(folder: Path) -> None:
        path = _job(folder)
        data = json.loads(path.read_text())
        new = change(data)
        path.write_text(json.dumps(data if new is None else new))
    return damage


def _edit_record(name: str, change: Callable[[Any], Any]) -> Callable[[Path], None]:
    def damage(folder: Path) -> None:
        path = folder / name
        path.write_text(json.dumps(change(json.loads(path.read_text()))))
    return damage


def _jobs_a_file(folder: Path) -> None:
    shutil.rmtree(folder / "jobs")
    (folder / "jobs").write_text("not a folder\n")


def _untouched(work: Path, codes: list[int], err: str) -> list[str]:
    """A refused resume leaves no claim behind."""
    return [f"{m} left behind"] if (m := work / "prev" / ".resume-claim").exists() else []


def study_tool_cases(base: Path) -> list[Case]:
    """study.py, ida.py and tune.py: the scheduler, sizes, stores, numbers, names in bytes, extends."""
    out: list[Case] = []
    study = str(SC / "case_study.yaml")
    silent, http, ssh = _listener(b""), _listener(b"HTTP/1.1 400 Bad Request\r\n\r\n"), _listener(b"SSH-2.0-x\r\n")
    # class 1: every wait on the network has a bound; so has every size a user sets
    addresses = {"a silent listener": f"tcp://127.0.0.1:{silent}", "an HTTP answer": f"127.0.0.1:{http}",
                 "an SSH banner": f"tcp://127.0.0.1:{ssh}", "http://": f"http://127.0.0.1:{silent}",
                 "tls://": f"tls://127.0.0.1:{silent}", "no port": "tcp://127.0.0.1", "port 0": "tcp://127.0.0.1:0",
                 "port 99999": "tcp://127.0.0.1:99999", "a path": f"tcp://127.0.0.1:{silent}/x",
                 "garbage": "::::", "an unknown host": "tcp://no-such-host.invalid:8786"}
    ida_file = lambda d: _mini_ida_file(d)  # noqa: E731
    for name, address in addresses.items():
        words = ("within 10 s",) if name in ("a silent listener",) else ()
        out.append(Case(f"{STUDIES}: scheduler", f"study.py at {name}", "study.py",
                        [study, "--scheduler", address, "--out", "out", "--quiet"], timeout=90,
                        verify=_says(*words)))
    for name in ("a silent listener", "an HTTP answer", "http://", "garbage"):
        out.append(Case(f"{STUDIES}: scheduler", f"ida.py at {name}", "ida.py",
                        ["ida.yaml", "--scheduler", addresses[name], "--out", "out", "--quiet"], ida_file, timeout=90))
        out.append(Case(f"{STUDIES}: scheduler", f"tune.py at {name}", "tune.py",
                        [study, "--scheduler", addresses[name], "--out", "g.yaml", "--quiet"], out="g.yaml",
                        timeout=90))
    out.append(Case(f"{STUDIES}: scheduler", "DASK_SCHEDULER_ADDRESS a silent listener", "study.py",
                    [study, "--out", "out", "--quiet"], env={"DASK_SCHEDULER_ADDRESS": addresses["a silent listener"]},
                    timeout=90))
    for setting in ("sweep.step=1e-10", "sweep.step=5e-324", "sweep.stop=1e300", "i_max=1e300",
                    "tuning.n_samples=1000000000", "tuning.max_evals=1000000000000", "timeout_s=1e300"):
        out.append(Case(f"{STUDIES}: sizes", setting, "study.py", [study, "--set", setting, "--out", "out", "--quiet"],
                        timeout=60))
    out.append(Case(f"{STUDIES}: sizes", "tune.py tuning.n_samples=1e9", "tune.py",
                    [study, "--set", "tuning.n_samples=1000000000", "--out", "g.yaml", "--quiet"], out="g.yaml"))
    # class 4: stores and folders read defensively (a finished study folder, damaged)
    damages: dict[str, Callable[[Path], None]] = {
        "a stored peak edited": _edit_job(lambda d: d["value"].__setitem__("peak_base_displacement_m", 1e-3)
                                          if isinstance(d.get("value"), dict) and "peak_base_displacement_m"
                                          in d["value"] else d.__setitem__("wall_time_s", 1.0)),
        "a stored result without its checksum": _edit_job(lambda d: d.pop("checksum") and None),
        "a stored result of another key": _edit_job(lambda d: d.__setitem__("key", "0" * 32)),
        "a stored result a list": _edit_job(lambda d: [d]),
        "a stored result truncated": lambda f: _job(f).write_text(_job(f).read_text()[:40]),
        "a folder where a result was": lambda f: (_job(f).unlink(), (f / "jobs" / ("1" * 32 + ".json")).mkdir()),
        "a stray file in jobs": lambda f: (f / "jobs" / "notes.txt").write_text("mine\n"),
        "jobs a file": _jobs_a_file,
        "a claim of a running resume": lambda f: (f / ".resume-claim").write_text(json.dumps(
            {"pid": 1, "host": os.uname().nodename})),
    }
    for kind, tool, record in (("study", "study.py", "study.json"), ("ida", "ida.py", "ida.json")):
        for name, damage in damages.items():
            out.append(Case(f"{STUDIES}: stores", f"{tool} --resume, {name}", tool,
                            ["--resume", "prev", "--quiet", "--workers", "1"], _damaged(kind, base, damage),
                            out=None, timeout=180, verify=_untouched if "claim" not in name else None))
        for name, damage in ((f"{record} a list", _edit_record(record, lambda d: [d])),
                             (f"{record} without keys", _edit_record(record, lambda d: {})),
                             (f"{record} a folder", lambda f, r=record: ((f / r).unlink(), (f / r).mkdir())),
                             (f"{record} truncated", lambda f, r=record: (f / r).write_text((f / r).read_text()[:50]))):
            for flag in ("--resume", "--report"):
                out.append(Case(f"{STUDIES}: stores", f"{tool} {flag}, {name}", tool,
                                [flag, "prev", "--quiet"], _damaged(kind, base, damage), out=None, timeout=180))
        for flag in ("--resume", "--report"):
            out.append(Case(f"{STUDIES}: stores", f"{tool} {flag} of a file", tool, [flag, PRECIOUS, "--quiet"],
                            out=None))
            out.append(Case(f"{STUDIES}: stores", f"{tool} {flag} of nothing", tool, [flag, "nowhere", "--quiet"],
                            out=None))
    # class 5: numbers finite and in their domain, booleans true or false
    for setting in ("timeout_s=.nan", "timeout_s=0", "timeout_s=-1", "timeout_s=.inf", "objective.w_acc=.nan",
                    "objective.penalty=.inf", "objective.x_limit=-.inf", "tuning.bounds.lam=[.nan, 2]",
                    "tuning.seed=-1", "tuning.stop_time=-1", "tuning.stop_time=.nan", "x_limit=.nan",
                    "reference.rtol=.nan", "reference.enabled=yes", "reference.enabled=off",
                    "reference.enabled='yes'", "paper_current_range=[2, 1]", "fig15.i_max=.nan"):
        out.append(Case(f"{STUDIES}: numbers", f"study.py {setting}", "study.py",
                        [study, "--set", setting, "--out", "out", "--quiet"], verify=_says(setting.split("=")[0]
                                                                                         .split(".")[-1])))
    for setting in ("objective.w_drift=.nan", "tuning.seed=-5", "tuning.bounds.rho=[1, .inf]", "tuning.stop_time=0"):
        out.append(Case(f"{STUDIES}: numbers", f"tune.py {setting}", "tune.py",
                        [study, "--set", setting, "--out", "g.yaml", "--quiet"], out="g.yaml"))
    for setting in ("timeout_s=.nan", "timeout_s=0", "window.tail_s=.inf", "window.strong_motion=yes",
                    "intensity.levels=[.nan]", "confidence=.nan", "time_scale=-1", "i_max=.inf"):
        out.append(Case(f"{STUDIES}: numbers", f"ida.py {setting}", "ida.py",
                        ["ida.yaml", "--set", setting, "--out", "out", "--quiet"], ida_file))
    out.append(Case(f"{STUDIES}: numbers", "a study file with enabled: on", "study.py", ["s.yaml", "--quiet"],
                    lambda d: (d / "s.yaml").write_text(f"extends: {study}\nreference:\n  enabled: on\n"),
                    verify=_says("s.yaml:3")))
    # class 6: names and paths measured in bytes against the file system's limits
    for name, argv in (("name of 100 emoji", ["--set", f"name={_EMOJI * 100}"]),
                       ("name of 62 emoji (+ time stamp)", ["--set", f"name={_EMOJI * 62}"]),
                       ("--out of 100 emoji", ["--out", _EMOJI * 100]),
                       ("--out 5,000 bytes deep", ["--out", "/".join(["d" * 200] * 25)]),
                       ("output of 70 emoji", ["--set", f"output={_EMOJI * 70}/x"])):
        out.append(Case(f"{STUDIES}: names", f"study.py {name}", "study.py", [study, *argv, "--quiet"],
                        out=None, verify=_says("bytes")))
    out.append(Case(f"{STUDIES}: names", "ida.py --out of 100 emoji", "ida.py",
                    ["ida.yaml", "--out", _EMOJI * 100, "--quiet"], ida_file, out=None, verify=_says("bytes")))
    out.append(Case(f"{STUDIES}: names", "ida.py name of 100 emoji", "ida.py",
                    ["ida.yaml", "--set", f"name={_EMOJI * 100}", "--quiet"], ida_file, out=None,
                    verify=_says("bytes")))
    out.append(Case(f"{STUDIES}: names", "tune.py --out of 100 emoji", "tune.py",
                    [study, "--out", _EMOJI * 100 + ".yaml", "--quiet"], out=None, verify=_says("bytes")))
    # class 7: a study file extending a shipped one from another folder finds the shipped files
    # (a bad scheduler ends each case right after the study is loaded: the message must be the scheduler's)
    ext = lambda text: lambda d: ((d / "mine").mkdir(), (d / "mine" / "s.yaml").write_text(text))  # noqa: E731
    for name, setup in (("absolute extends", ext(f"extends: {study}\nname: mine\n")),
                        ("relative extends", lambda d: ext(f"extends: {os.path.relpath(study, d / 'mine')}\n")(d)),
                        ("two extends", lambda d: (ext(f"extends: {study}\n")(d), (d / "t.yaml").write_text(
                            "extends: mine/s.yaml\nname: t\n")))):
        target = "t.yaml" if name == "two extends" else "mine/s.yaml"
        out.append(Case(f"{STUDIES}: extends", f"study.py, {name}", "study.py",
                        [target, "--scheduler", "http://127.0.0.1:1", "--quiet"], setup, out=None,
                        verify=_says("only tcp://", never=("does not exist",))))
    out.append(Case(f"{STUDIES}: extends", "ida.py, a study extending another folder's", "ida.py",
                    ["mine/ida.yaml", "--scheduler", "http://127.0.0.1:1", "--quiet"],
                    lambda d: ((d / "mine").mkdir(), _mini_ida_file(d), (d / "mine" / "ida.yaml").write_text(
                        f"extends: {d / 'ida.yaml'}\nname: mine\n")), out=None,
                    verify=_says("only tcp://", never=("does not exist",))))
    return out


def _mount(folder: Path, kind: str, size: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)], check=True)
    if kind == "full-before":
        with open(folder / "filler", "wb") as f:
            try:
                while True:
                    f.write(bytes(65536))
                    f.flush()
            except OSError:
                pass
    if kind == "readonly":
        subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)


def _snapshot(folder: Path) -> dict[str, tuple[int, int, bool]]:
    """Every path under ``folder``: (size, mtime, is a regular file); symbolic links are not followed."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in files + dirs:
            p = Path(root) / name
            try:
                st = p.lstat()
            except OSError:
                continue
            out[str(p.relative_to(folder))] = (st.st_size, int(st.st_mtime_ns), stat.S_ISREG(st.st_mode))
    return out


def _check_run_folder(folder: Path, code: int, reasons: list[str]) -> None:
    """A run folder may look complete only if it is: summary complete <=> every file whole."""
    summary_path = folder / "summary.json"
    if not summary_path.is_file():
        return
    try:
        summary = json.loads(summary_path.read_text())
    except ValueError:
        reasons.append("summary.json is not valid JSON (half-written)")
        return
    if summary.get("complete") is True:
        if code != 0:
            reasons.append(f"summary.json says complete but the exit code is {code}")
        kept = summary.get("results_file") or {"file": "timeseries.csv", "every_nth_step": 1}
        try:
            manifest = json.loads((folder / "manifest.json").read_text())
            if kept.get("file") is None:  # a study's run that keeps no time series (timeseries: false)
                rows = 0 if not list(folder.glob("timeseries.*")) else -1
            elif str(kept["file"]).endswith(".parquet"):
                import pyarrow.parquet as pq

                rows = pq.read_metadata(folder / kept["file"]).num_rows
            else:
                with open(folder / kept["file"]) as f:
                    rows = sum(1 for _ in f) - 1  # the header
        except (OSError, ValueError) as exc:
            reasons.append(f"complete summary but {exc}")
            return
        n, every = summary.get("steps_done", -10) + 1, int(kept.get("every_nth_step") or 1)
        expected = 0 if kept.get("file") is None else len(range(0, n, every)) + ((n - 1) % every != 0)
        if manifest.get("complete") is not True or rows != expected:
            reasons.append(f"complete summary but manifest/results file disagree ({rows} rows, {expected} expected)")
    elif code == 0:
        reasons.append("exit 0 but summary.json says incomplete")


def run_case(case: Case, base: Path, index: int) -> Result:
    folder = base / f"{index:04d}"
    work = folder / "work"
    tmp = folder / "tmp"
    crash = folder / "crash"
    for d in (work, tmp, crash):
        d.mkdir(parents=True)
    (work / PRECIOUS).write_text("years of work\n")
    reasons: list[str] = []
    if case.setup is not None:
        case.setup(work)
    mounted: Path | None = None
    preexec = None
    if case.mount in ("full", "full-before", "readonly"):
        mounted = work / "out"
        with _MOUNT_LOCK:
            _mount(mounted, case.mount, case.mount_size)
    elif case.mount == "fsize":
        limit = _bytes(case.mount_size)

        def preexec() -> None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write beyond the limit fails with EFBIG
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    before = _snapshot(work)
    precious = {k: v for k, v in before.items() if v[2] and (k == PRECIOUS or k.startswith(("prev", "runs")))
                and k not in case.changes}  # a file the case is meant to change (a resumed study.json) is not lost
    env = {**os.environ, "TMPDIR": str(tmp), "MRE_COSIM_CRASH_DIR": str(crash), "PYTHONDONTWRITEBYTECODE": "1",
           **case.env}
    cmd = [*TOOLS[case.tool], *case.argv]
    t0 = time.monotonic()
    procs = [subprocess.Popen(cmd, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              errors="replace", preexec_fn=preexec) for _ in range(case.copies)]
    if case.signal_after is not None:
        sig, delay = case.signal_after
        time.sleep(delay)
        for p in procs:
            if p.poll() is None:
                p.send_signal(sig)
    if case.during is not None:
        delay, action = case.during
        time.sleep(delay)
        action(work)
    codes, errs = [], []
    for p in procs:
        try:
            out_text, err_text = p.communicate(timeout=case.timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            out_text, err_text = p.communicate()
            reasons.append(f"hung: killed after {case.timeout:.0f} s")
        codes.append(p.returncode)
        errs.append(err_text)
        text = out_text + err_text
        if "Traceback" in text or "Fatal Python error" in text:
            reasons.append("a traceback was printed")
        if p.returncode != 0 and not err_text.strip():
            reasons.append("failed without a message")
        if p.returncode not in DOCUMENTED[case.tool]:
            reasons.append(f"exit code {p.returncode} is not documented" + (" (3: an internal error, a bug)"
                                                                              if p.returncode == 3 else ""))
    seconds = time.monotonic() - t0
    after = _snapshot(work)
    data_loss = any(after.get(k, (None, None))[0] != v[0] for k, v in precious.items())
    if case.copies > 1:
        if sorted(codes) != [0] + [2] * (case.copies - 1):
            reasons.append(f"concurrent runs ended {sorted(codes)}, expected one 0 and the rest 2")
    new = {k for k in after if k not in before}
    changed = {k for k in before if k in after and after[k] != before[k] and k != "out" and k not in case.changes}
    top = {k.split("/")[0] for k in new}
    allowed_top = {case.out} if case.out else set()
    for code in set(codes):
        if code in (2, 130) and case.copies == 1 and new:
            reasons.append(f"exit {code} but wrote {sorted(new)[:5]}")
    if top - allowed_top - {"out"} if mounted is not None else top - allowed_top:
        reasons.append(f"wrote outside the output folder: {sorted(top - allowed_top)[:5]}")
    if changed - {k for k in changed if k.startswith(("out/", "runs/"))} - ({"runs"} if case.out == "runs" else set()):
        reasons.append(f"changed existing files: {sorted(changed)[:5]}")
    # the per-user cache of content-addressed FMUs and records (orchestration/batch/portable.py) is kept on purpose
    leftovers = sorted(n for n in set(os.listdir(tmp)) - SHARED_TMP if not n.startswith("mre-cosim-files-"))
    if leftovers:
        reasons.append(f"temporary files left: {leftovers[:3]}")
    if os.listdir(crash):
        reasons.append("an internal error (crash log written)")
    for key in sorted(new):
        if key.endswith("summary.json"):  # a run folder this case created
            _check_run_folder((work / key).parent, 0 if 0 in codes else max(codes), reasons)
    for escaped in (folder / "escaped.txt", base / "escaped.txt", Path("/tmp/mre-corpus-escaped.txt")):
        if escaped.exists():
            reasons.append(f"an archive entry escaped to {escaped}")
            escaped.unlink()
    if case.verify is not None:
        try:
            reasons += case.verify(work, codes, "\n".join(errs))
        except Exception as exc:  # the verification itself could not read what it needs: not clean
            reasons.append(f"verification failed: {exc!r}")
    if mounted is not None:
        with _MOUNT_LOCK:
            subprocess.run(["umount", str(mounted)], check=False)
    stderr = "\n".join(e.strip() for e in errs if e.strip())[-600:]
    return Result(case.cls, case.name, case.tool, codes, not reasons and not data_loss, data_loss, reasons,
                  round(seconds, 2), stderr)


def _run_case(case: Case, base: Path, index: int) -> Result:
    """run_case, a failure of the corpus itself reported as such (not clean, so it is looked at)."""
    try:
        return run_case(case, base, index)
    except Exception as exc:  # the harness itself failed
        return Result(case.cls, case.name, case.tool, [], False, False, [f"corpus harness error: {exc!r}"])


def new_unit_cases() -> list[Case]:
    """Hostile values of the parameters the newer units added: yielding storeys, the bounded
    isolator, the model-based controllers, the OpenSees script, study strategies. Each must be exit 2."""
    building = ["building.hysteresis=plastic", "building.hysteresis=1", "building.hysteresis=BILINEAR",
                "building.fy_1=.nan", "building.fy_1=-1", "building.fy_1=0", "building.fy_1=.inf",
                "building.b_1=1", "building.b_1=-0.1", "building.b_1=.nan", "building.n_1=0", "building.n_1=-2",
                "building.substeps=0", "building.substeps=1000000000", "building.p_delta=yes",
                "building.p_delta=true", "building.h_1=-0.5", "isolator.beyond_range=wall",
                "isolator.beyond_range=", "isolator.k_stop=.nan", "isolator.k_stop=-1", "isolator.c_stop=.inf",
                "isolator.c_stop=-5"]
    cases = [Case("new unit parameters", s[:70], "run.py",
                  [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", "building.hysteresis=bilinear"
                   if not s.startswith("building.hysteresis") else "building.fy_2=3700", "--set", s,
                   "--out", "out", "--quiet", "--no-plots"]) for s in building]
    controllers = {"elcentro_clipped_optimal.yaml": ["controller.q_x=-1", "controller.q_x=.nan", "controller.law=clip",
                                                     "controller.i_nom=99", "controller.x_lin=-1",
                                                     "controller.n_grid=1", "controller.n_grid=1000000000"],
                   "elcentro_lyapunov.yaml": ["controller.i_max=0", "controller.i_max=-3", "controller.r_acc=.inf"],
                   "elcentro_frequency.yaml": ["controller.window=1", "controller.window=0",
                                               "controller.window=1000000000000", "controller.update_every=0",
                                               "controller.f_hi=.nan"],
                   "elcentro_opensees.yaml": ["building.script=/dev/zero", "building.script=/tmp",
                                              "building.script=nowhere.py", "building.script=" + "é" * 200 + ".py",
                                              "building.substeps=0"]}
    cases += [Case("new unit parameters", f"{name}: {s}"[:70], "run.py",
                   [str(SC / name), "--set", SHORT, "--set", s, "--out", "out", "--quiet", "--no-plots"])
              for name, sets in controllers.items() for s in sets]
    strategies = ["strategies=[nope]", "strategies=[sosm, sosm]", "strategy_files=[/dev/zero]",
                  "strategy_files=[nowhere.yaml]", "strategy_definitions={x: {fmu: /tmp}}",
                  "strategy_definitions={x: {fmu: fmus/ConstantCurrent.fmu, connections: [building.nothing -> "
                  "controller.x]}}", "strategy_definitions={x: {parameters: {current: .nan}}}"]
    cases += [Case("new unit parameters", f"study: {s}"[:70], "study.py",
                   [str(SC / "case_study.yaml"), "--set", "overrides=[simulation.stop_time=0.05]", "--set", s,
                    "--out", "out", "--quiet", "--workers", "1"]) for s in strategies]
    return cases


def session_input_cases() -> list[Case]:
    """Hostile values of what the last round added: robustness variants (a study's ``robustness:`` section),
    strategy entries in an IDA, ``outputs:`` naming FMI locals, ``MRE_COSIM_CSV_PROCESS``. Each must be exit 2
    (refused before any run, nothing written)."""
    cls = "new ways in: robustness, IDA strategies, locals"
    one = ("records={elcentro: elcentro.yaml}", "strategies=[passive-off, sosm]",
           "overrides=[simulation.stop_time=0.05]")
    variant = ["{v: {scale: {building.m_1: .nan}}}", "{v: {scale: {building.m_1: .inf}}}",
               "{v: {scale: {building.m_1: -1}}}", "{v: {scale: {building.m_1: 0}}}",
               "{v: {scale: {building.m_1: abc}}}", "{v: {scale: {building.nothing: 1.2}}}",
               "{v: {scale: {controller.m_1: 1.2}}}", "{v: {current_lag: -0.01}}", "{v: {current_lag: .nan}}",
               "{v: {current_lag: .inf}}", "{v: {current_lag: [1]}}", "{v: {sensors: {delay: -1}}}",
               "{v: {sensors: {delay: 1000000000}}}", "{v: {sensors: {delay: 1.5}}}",
               "{v: {sensors: {seed: -1}}}", "{v: {sensors: {seed: 1e30}}}",
               "{v: {sensors: {noise_rms: {building.x_0: .nan}}}}",
               "{v: {sensors: {noise_rms: {building.x_0: -1e-4}}}}",
               "{v: {sensors: {noise_rms: {building.x_0: 1e300}}}}",
               "{v: {plant: {isolator: /dev/zero}}}", "{v: {plant: {isolator: /tmp}}}",
               "{v: {plant: {isolator: nowhere.fmu}}}", "{v: {plant: {controller: ../fmus/ConstantCurrent.fmu}}}",
               "{v: {plant: {isolator: " + "é" * 200 + ".fmu}}}", "{v: {}}", "{v: {colour: red}}", "[1, 2]",
               "{" + "é" * 200 + ": {current_lag: 0.01}}", "{nominal: {current_lag: 0.01}}"]
    cases = [Case(cls, f"robustness.variants={s}"[:70], "study.py",
                  [str(SC / "controller_robustness.yaml"), *(a for o in one for a in ("--set", o)),
                   "--set", f"robustness.variants={s}", "--out", "out", "--quiet", "--workers", "1"])
             for s in variant]
    ida = ["strategies=[nope]", "strategies=[best-constant]", "strategies=[]",
           "strategy_files=[/dev/zero]", "strategy_files=[nowhere.yaml]",
           "strategy_definitions={x: {fmu: /tmp}}", "strategy_definitions={x: {parameters: {i_passive: .nan}}}",
           "strategy_definitions={x: {fmu: ../fmus/ConstantCurrent.fmu, connections: "
           "[{source: building.a_9, target: controller.x}]}}"]
    cases += [Case(cls, f"ida: {s}"[:70], "ida.py", [str(SC / "ida_controllers.yaml"), "--set", s, "--out", "out",
                                                    "--quiet", "--workers", "1"]) for s in ida]
    outputs = ["outputs=[building.residual_drift_9]", "outputs=[building.k_1]", "outputs=[building.ag]",
               "outputs=[nowhere.residual_drift_1]", "limits.max_abs={building.residual_drift_1: 1.0}",
               "limits.max_abs={building.residual_drift_1: .nan}"]
    cases += [Case(cls, s[:70], "run.py", [str(SC / "kobe_yielding.yaml"), "--set", SHORT, "--set", s,
                                          "--out", "out", "--quiet", "--no-plots"]) for s in outputs]
    cases += [Case(cls, f"MRE_COSIM_CSV_PROCESS={v!r}", "run.py",
                   [str(SC / "elcentro.yaml"), "--set", SHORT, "--out", "out", "--quiet", "--no-plots"],
                   env={"MRE_COSIM_CSV_PROCESS": v}) for v in ("yes", "2", "nan", "-1", "on", "\u00e9" * 50)]
    for case in cases:
        case.verify = _exit_2
    return cases


def _exit_2(work: Path, codes: list[int], err: str) -> list[str]:
    """Refused before any run: exit 2 and one line naming what."""
    return [] if codes == [2] else [f"exit {codes}, expected 2"]


def _kept_every_fifth(work: Path, codes: list[int], err: str) -> list[str]:
    """A study whose runs keep every 5th step in Parquet: exit 0, and the run folder holds that file beside the
    run's numbers (computed from every step)."""
    run = work / "out" / "runs" / "elcentro-passive-off"
    reasons = [] if codes == [0] else [f"exit {codes}, expected 0"]
    reasons += [f"no {name}" for name in ("timeseries.parquet", "metrics.json") if not (run / name).is_file()]
    return reasons


# -- what was left: unused values, unlisted strategies, NUL in text, full disks, stuck workers ------------

LEFT = "26/leftovers"
"""Prefix of these classes: ``--only 26/leftovers`` runs them alone."""


def _bytes(size: str) -> int:
    """``512``, ``4K``, ``1M`` as bytes."""
    scale = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}.get(size[-1:].upper(), 1)
    return int(size[:-1] if scale > 1 else size) * scale


def _exit(want: int) -> Callable[[Path, list[int], str], list[str]]:
    return lambda w, c, e: [] if c == [want] else [f"exit {c}, expected {want}"]


def _said_what_exists(work: Path, codes: list[int], err: str) -> list[str]:
    """'marked incomplete' only when a file of the folder says so; 'NOT marked' names every file the folder holds."""
    reasons = _marked_if_said(work, codes, err)
    folder = work / "out" / "run"
    if "NOT marked incomplete" in err and folder.is_dir():
        unnamed = [p.name for p in folder.iterdir() if p.is_file() and f"{p.name} ({p.stat().st_size} B)" not in err]
        reasons += [f"says NOT marked but does not name {unnamed}"] if unnamed else []
    return reasons


_STUCK: dict[str, Any] = {}
_STUCK_LOCK = threading.Lock()


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _stuck_cluster(port: int) -> Callable[[Path], None]:
    """Setup: a real Dask scheduler on ``port`` whose only worker is stopped (SIGSTOP) once it has registered, so
    it never answers; started once, on first use, and ended with the corpus."""
    def setup(work: Path) -> None:
        with _STUCK_LOCK:
            if _STUCK:
                return
            import atexit

            dask = str(Path(PY).parent / "dask")
            log = open(work.parent / "dask.log", "w")  # kept open while the cluster lives
            address = f"tcp://127.0.0.1:{port}"
            procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                       "--dashboard-address", ":0"], stdout=log, stderr=log, cwd=work.parent)]
            procs.append(subprocess.Popen([dask, "worker", address, "--no-nanny", "--nthreads", "1"], stdout=log,
                                          stderr=log, cwd=PROJECT))

            def end() -> None:
                for proc in procs:
                    if proc.poll() is None:
                        os.kill(proc.pid, signal.SIGCONT)
                        proc.kill()
                        proc.wait()
            atexit.register(end)
            from distributed import Client

            with Client(address, timeout="120s") as client:
                client.wait_for_workers(1, timeout=300)
            os.kill(procs[1].pid, signal.SIGSTOP)
            _STUCK["procs"] = procs
    return setup


def leftover_cases(base: Path) -> list[Case]:
    """What was left: values set but unused by the chosen law, strategies defined but not listed, a NUL in
    any text, writes that fail (RLIMIT_FSIZE, tmpfs), a scheduler whose worker never answers."""
    out: list[Case] = []
    # values the chosen law does not use: checked for their domain, refused when set
    unused = {"building.n_1=3": "set but unused", "building.n_1=0": "must be >= 1", "building.n_2=.nan": "finite",
              "building.fy_1=4000": "set but unused", "building.fy_2=-1": "finite number > 0",
              "building.b_1=0.1": "set but unused", "building.b_3=1.5": "[0, 1)", "building.bw_beta=2": "unused",
              "building.bw_gamma=5": "|gamma| <= beta", "building.substeps=0": "[1, 1000]",
              "building.h_1=3": "set but unused", "building.h_2=-1": "must be > 0", "building.h_3=.inf": "finite",
              "isolator.k_stop=1e6": "set but unused", "isolator.c_stop=100": "set but unused",
              "isolator.k_stop=-1": "must not be negative"}
    for setting, word in unused.items():
        out.append(Case(f"{LEFT}: unused values", f"linear building: {setting}", "run.py", _elc(setting),
                        verify=_says(setting.split("=")[0].split(".")[1], word)))
    for sets, word in ((("building.hysteresis=bilinear", "building.n_2=3"), "set but unused"),
                       (("building.hysteresis=bilinear", "building.bw_gamma=0.1"), "set but unused"),
                       (("isolator.beyond_range=tangent", "isolator.c_stop=-5"), "must not be negative"),
                       (("isolator.beyond_range=tangent", "isolator.k_stop=1"), "set but unused")):
        out.append(Case(f"{LEFT}: unused values", " ".join(sets), "run.py", _elc(*sets),
                        verify=_says(sets[1].split("=")[0].split(".")[1], word)))
    for sets in (("building.hysteresis=bouc-wen", "building.n_1=3"), ("building.p_delta=true", "building.h_1=3",
                                                                     "building.h_2=3", "building.h_3=3"),
                 # a stop stiffer than the paper's law past 8 mm (6.57 MN/m at 3 A), as docs/structures.md says
                 ("isolator.beyond_range=stop", "isolator.k_stop=1e7"), ("building.n_1=2", "isolator.k_stop=5e6")):
        out.append(Case(f"{LEFT}: unused values", f"used or the declared start: {' '.join(sets)}"[:70], "run.py",
                        _elc(*sets), verify=_exit(0)))
    out.append(Case(f"{LEFT}: unused values", "kobe_yielding switched back to linear runs", "run.py",
                    [str(SC / "kobe_yielding.yaml"), "--set", SHORT, "--set", "building.hysteresis=linear", "--out",
                     "out", "--quiet", "--no-plots"], verify=_exit(0)))
    out.append(Case(f"{LEFT}: unused values", "n_2: 3 in a scenario file names its line", "run.py",
                    ["s.yaml", "--out", "out", "--quiet", "--no-plots"],
                    lambda d: (d / "s.yaml").write_text(f"extends: {SC / 'elcentro.yaml'}\nname: s\nunits:\n"
                                                        "  building:\n    parameters:\n      n_2: 3.0\n"),
                    verify=_says("s.yaml:6", "n_2")))
    # strategies a study defines: every number finite and no NUL, listed or not
    study = str(SC / "case_study.yaml")
    definitions = {"current: .nan": "{x: {parameters: {current: .nan}}}",
                   "i_passive: .inf": "{x: {parameters: {mode: passive, i_passive: .inf}}}",
                   "lambda: -.inf": "{x: {parameters: {lambda: -.inf}}}",
                   "a list with .nan": "{x: {parameters: {gains: [1, .nan]}}}",
                   "a nested .nan": "{x: {parameters: {a: {b: .nan}}}}",
                   "a NUL in a value": '{x: {parameters: {mode: "passive\\0"}}}',
                   "a NUL in the FMU": '{x: {fmu: "a\\0.fmu"}}'}
    for name, definition in definitions.items():
        word = "NUL" if "NUL" in name else "finite"
        out.append(Case(f"{LEFT}: unlisted strategies", f"study.py, {name}", "study.py",
                        [study, "--set", f"strategy_definitions={definition}", "--out", "out", "--quiet"],
                        verify=_says(word, "strategy_definitions.x")))
    for name in ("current: .nan", "a NUL in a value"):
        out.append(Case(f"{LEFT}: unlisted strategies", f"ida.py, {name}", "ida.py",
                        ["ida.yaml", "--set", f"strategy_definitions={definitions[name]}", "--out", "out", "--quiet"],
                        _mini_ida_file, verify=_says("strategy_definitions.x")))
    out.append(Case(f"{LEFT}: unlisted strategies", "study.py, a strategy file with .nan", "study.py",
                    ["s.yaml", "--out", "out", "--quiet"],
                    lambda d: ((d / "mine.yaml").write_text("strategies:\n  calm:\n    parameters:\n"
                                                            "      i_passive: .nan\n"),
                               (d / "s.yaml").write_text(f"extends: {study}\nstrategy_files: [mine.yaml]\n")),
                    verify=_says("mine.yaml:4", "finite")))
    out.append(Case(f"{LEFT}: unlisted strategies", "study.py, a finite unlisted strategy runs", "study.py",
                    [study, *MINI_STUDY, "--set", "strategy_definitions={x: {parameters: {i_passive: 1.5}}}",
                     "--workers", "1", "--out", "out", "--quiet"], timeout=600, verify=_exit(0)))
    # a NUL in any text of a scenario: never cut short, never an OS error
    texts = {"a choice String": ("units: {controller: {parameters: {mode: \"passive\\0x\"}}}", "NUL"),
             "hysteresis": ("units: {building: {parameters: {hysteresis: \"linear\\0\"}}}", "NUL"),
             "beyond_range": ("units: {isolator: {parameters: {beyond_range: \"stop\\0\"}}}", "NUL"),
             "the FMU path": (f"units: {{isolator: {{fmu: \"{FMUS / 'MreIsolator.fmu'}\\0\"}}}}", "NUL"),
             "a plain record path": ("units: {ground: {parameters: {record: \"r.csv\\0\"}}}", "r.csv"),
             "a !record path": ("units: {ground: {parameters: {record: !record \"r.csv\\0\"}}}", "r.csv"),
             "a !data path": ("units: {ground: {parameters: {record: !data \"r.csv\\0\"}}}", "r.csv"),
             "the name": ("name: \"a\\0b\"", "name"), "results.dir": ("results: {dir: \"r\\0\"}", "results.dir"),
             "an output": ("outputs: [\"building.x_1\\0\"]", "outputs"),
             "a connection": ("connections: [\"ground.ag\\0 -> building.ag\"]", "connections"),
             "a unit name": ("units: {\"iso\\0\": {fmu: ../fmus/MreIsolator.fmu}}", "unit name"),
             "a limit's key": ("limits: {\"building.x_1\\0\": 0.1}", "limits")}
    for name, (body, word) in texts.items():
        text = f"extends: {SC / 'elcentro.yaml'}\nsimulation: {{stop_time: 0.05}}\n{body}\n"
        out.append(Case(f"{LEFT}: NUL in text", name, "run.py", ["s.yaml", "--out", "out", "--quiet", "--no-plots"],
                        lambda d, text=text: (shutil.copy(RECORDS / "elcentro_1940_ns.csv", d / "r.csv"),
                                              (d / "s.yaml").write_text(text)), verify=_says(word)))
    out.append(Case(f"{LEFT}: NUL in text", "the description (text only: runs)", "run.py",
                    ["s.yaml", "--out", "out", "--quiet", "--no-plots"],
                    lambda d: (d / "s.yaml").write_text(f"extends: {SC / 'elcentro.yaml'}\n"
                                                        "simulation: {stop_time: 0.05}\ndescription: \"a\\0b\"\n"),
                    verify=_exit(0)))
    # writes that fail: the kernel's EFBIG (RLIMIT_FSIZE, any user) and a full tmpfs (root)
    kobe5 = [str(SC / "kobe.yaml"), "--set", "simulation.stop_time=5", "--out", "out/run", "--quiet", "--no-plots"]
    for size in ("512", "2K", "4K", "16K", "64K", "1M", "4M"):
        out.append(Case(f"{LEFT}: full disk", f"every file at most {size} B (EFBIG)", "run.py", kobe5,
                        lambda d: (d / "out").mkdir(), mount="fsize", mount_size=size, verify=_said_what_exists))
    if IS_ROOT:
        for size in ("8K", "32K", "256K", "2M"):
            out.append(Case(f"{LEFT}: full disk", f"Kobe 5 s on a {size} disk (ENOSPC)", "run.py", kobe5,
                            mount="full", mount_size=size, verify=_said_what_exists))
        for size in ("64K", "1M"):
            out.append(Case(f"{LEFT}: full disk", f"study on a {size} disk", "study.py",
                            [study, *MINI_STUDY, "--workers", "1", "--out", "out/s", "--quiet"], mount="full",
                            mount_size=size, timeout=600))
    # a scheduler whose worker registered and then never answers: bounded, exit 2 naming the address and the bound
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    for tool, argv, where in (("study.py", [study, "--scheduler", address, "--out", "out", "--quiet"], "out"),
                              ("tune.py", [study, "--scheduler", address, "--out", "g.yaml", "--quiet"], "g.yaml")):
        out.append(Case(f"{LEFT}: stuck workers", f"{tool} at a scheduler whose worker is stopped", tool, argv,
                        _stuck_cluster(port), out=where, timeout=400,
                        verify=lambda w, c, e: ([] if c == [2] else [f"exit {c}, expected 2"])
                        + _says(address, "within 120 s")(w, c, e)))
    return out


# -- hardening: names that become paths, caches, user scripts, new-unit designs, the CSV process, units ----------------

HARD = "35/"
_MODEL = SC / "structures" / "dyke_linear.py"
_SCRIPTS = {"os._exit(0)": "import os\nos._exit(0)\n", "sys.exit(0)": "import sys\nsys.exit(0)\n",
            "never ends": "while True:\n    pass\n", "os.chdir('/')": "import os\nos.chdir('/')\n"}


def _nothing_at(*paths: str) -> Callable[[Path, list[int], str], list[str]]:
    """Verification: exit 2 and none of these absolute paths exists (a chdir'd output would land there)."""
    def check(work: Path, codes: list[int], err: str) -> list[str]:
        found = [p for p in paths if os.path.lexists(p)]
        return ([f"exit {codes}, expected 2"] if codes != [2] else []) + ([f"wrote {found}"] if found else [])
    return check


def _exit_and_says(code: int, *words: str) -> Callable[[Path, list[int], str], list[str]]:
    said = _says(*words)

    def check(work: Path, codes: list[int], err: str) -> list[str]:
        return ([] if codes == [code] else [f"exit {codes}, expected {code}"]) + said(work, codes, err)
    return check


def _cache_tmp(work: Path) -> Path:
    """The case's temporary folder (its TMPDIR, beside ``work``)."""
    return work.parent / "tmp"


def _kernel_cache(kind: str) -> Callable[[Path], None]:
    """``MRE_COSIM_CACHE`` (../tmp/mre-cosim-files-kernels from the case's folder) made hostile."""
    def setup(work: Path) -> None:
        cache = _cache_tmp(work) / "mre-cosim-files-kernels"
        if kind == "a file":
            cache.write_text("not a folder\n")
        elif kind == "a symlink":
            (_cache_tmp(work) / "mre-cosim-files-elsewhere").mkdir()
            cache.symlink_to(_cache_tmp(work) / "mre-cosim-files-elsewhere")
        elif kind == "open to all":
            cache.mkdir()
            cache.chmod(0o777)
            (cache / "planted.so").write_bytes(b"\x7fELF planted")
        elif kind == "a planted kernel":
            from mre_common import c_compile
            from orchestration.master import native_stepper as ns

            cache.mkdir(mode=0o700)
            key = c_compile.cache_key(ns.SOURCE, ns.CFLAGS, ("-lm",))
            (cache / f"step_kernel-{key}.so").write_bytes(b"\x7fELF planted, truncated")
    return setup


def _kernel_untouched(work: Path, codes: list[int], err: str) -> list[str]:
    """Exit 0, the cache named, nothing written through a link."""
    reasons = [] if codes == [0] else [f"exit {codes}, expected 0"]
    elsewhere = _cache_tmp(work) / "mre-cosim-files-elsewhere"
    if elsewhere.is_dir() and any(elsewhere.iterdir()):
        reasons.append(f"wrote through the symlink into {elsewhere}")
    if "note: cache" not in err:
        reasons.append("no note names the cache")
    return reasons


def _files_cache(kind: str) -> Callable[[Path], None]:
    """The workers' per-user file and extraction cache in the case's temporary folder, made hostile."""
    def setup(work: Path) -> None:
        uid = os.getuid()
        root = _cache_tmp(work) / f"mre-cosim-files-{uid}"
        if kind == "a symlink":
            (_cache_tmp(work) / "mre-cosim-files-elsewhere").mkdir()
            root.symlink_to(_cache_tmp(work) / "mre-cosim-files-elsewhere")
        elif kind == "a file":
            root.write_text("not a folder\n")
        elif kind == "planted extractions":
            import hashlib

            root.mkdir(mode=0o700)
            for fmu in FMUS.glob("*.fmu"):
                entry = root / "extracted" / hashlib.sha256(fmu.read_bytes()).hexdigest()
                (entry / "binaries" / "linux64").mkdir(parents=True)
                (entry / "sitecustomize.py").write_text(f"open({str(work / 'pwned.txt')!r}, 'w').write('ran')\n")
                (entry / "binaries" / "linux64" / "x.so").write_bytes(b"\x7fELF planted")
    return setup


def _study_ran_clean(work: Path, codes: list[int], err: str) -> list[str]:
    reasons = [] if codes == [0] else [f"exit {codes}, expected 0"]
    if (work / "pwned.txt").exists():
        reasons.append("planted code ran")
    elsewhere = _cache_tmp(work) / "mre-cosim-files-elsewhere"
    if elsewhere.is_dir() and any(elsewhere.iterdir()):
        reasons.append(f"wrote through the symlink into {elsewhere}")
    return reasons


def _find_csv_child(work: Path, timeout: float = 60.0) -> int | None:
    """The pid of a run's CSV process: a process in ``work`` whose parent is one too (the run forked it)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        in_work = {}
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    if os.readlink(f"/proc/{entry}/cwd") == str(work):
                        stat_text = Path(f"/proc/{entry}/stat").read_text()
                        in_work[int(entry)] = int(stat_text.rpartition(")")[2].split()[1])
                except OSError:
                    continue
        for pid, ppid in in_work.items():
            try:
                forked = Path(f"/proc/{pid}/cmdline").read_bytes() == Path(f"/proc/{ppid}/cmdline").read_bytes()
            except OSError:
                continue
            if ppid in in_work and forked:  # a fork of the run (not a compiler it started)
                return pid
        time.sleep(0.05)
    return None


def _signal_csv_child(sig: int) -> Callable[[Path], None]:
    """Signal the run's CSV process once it has written some rows (its hidden temporary file holds 64 KiB)."""
    def action(work: Path) -> None:
        pid = _find_csv_child(work)
        deadline = time.monotonic() + 60
        while pid is not None and time.monotonic() < deadline:
            if sum(p.stat().st_size for p in (work / "out").glob(".timeseries.csv.*.tmp")) > 65536:
                break
            time.sleep(0.05)
        if pid is not None:
            os.kill(pid, sig)
            (work.parent / "signalled").write_text(str(pid))
    return action


def _csv_child_outcome(work: Path, codes: list[int], err: str) -> list[str]:
    """The CSV process stopped or killed: exit 1, the rows kept as timeseries.csv.incomplete, nothing hidden."""
    if not (work.parent / "signalled").exists():
        return ["the CSV process was not found to signal (the case did not test anything)"]
    reasons = [] if codes == [1] else [f"exit {codes}, expected 1"]
    out = work / "out"
    if not (out / "timeseries.csv.incomplete").is_file():
        reasons.append("no timeseries.csv.incomplete")
    hidden = [p.name for p in out.glob(".*.tmp")] if out.is_dir() else []
    if hidden:
        reasons.append(f"hidden partial files left: {hidden}")
    if "timeseries.csv.incomplete" not in err:
        reasons.append("the message does not name the rows kept")
    return reasons


def hardening_cases(base: Path) -> list[Case]:
    """Names that become paths, caches that trust what they find, user scripts, new-unit designs found at t = 0,
    a study refused after the pool started, the CSV process, unit-less outputs (the hardening classes)."""
    from orchestration.engine_hooks import plan_scenario
    from orchestration.interop.ssp_package import export_ssp

    cases: list[Case] = []
    long, deep = "a" * 300, "/".join(["b" * 200] * 25)
    one = ("records={elcentro: elcentro.yaml}", "overrides=[simulation.stop_time=0.05]", "reference={enabled: false}")
    study = [str(SC / "case_study.yaml"), *(a for o in one for a in ("--set", o))]
    defined = "strategy_definitions={{{name}: {{parameters: {{mode: passive, i_passive: 1.0}}}}}}"
    names = {"strategy '../x'": [defined.format(name='"../x"'), 'strategies=[passive-off, "../x"]'],
             "strategy '../../escaped'": [defined.format(name='"../../escaped"'),
                                          'strategies=[passive-off, "../../escaped"]'],
             "record id '../up'": ['records={"../up": elcentro.yaml}'],
             "strategy of 250 bytes": [defined.format(name="s" * 250), f"strategies=[passive-off, {'s' * 250}]"],
             "strategy of 100 emoji": [defined.format(name="\U0001f600" * 100),
                                       f"strategies=[passive-off, {chr(0x1F600) * 100}]"],
             }
    cases += [Case(HARD + "names", f"study: {k}", "study.py",
                   [*study, *(a for o in v for a in ("--set", o)), "--out", "out", "--quiet", "--workers", "1"],
                   verify=_exit_2) for k, v in names.items()]
    cases += [Case(HARD + "names", f"study: name {k} (no --out: it names the folder)", "study.py",
                   [*study, "--set", f"name={v}", "--quiet", "--workers", "1"], out="studies", verify=_exit_2)
              for k, v in (("of 300 bytes", long), ("'../x'", "../x"), ("'.hidden'", ".hidden"))]
    cases += [Case(HARD + "names", "study: --out of 300 bytes", "study.py",
                   [*study, "--out", f"{long}/x", "--quiet", "--workers", "1"], out=None, verify=_exit_2),
              Case(HARD + "names", "run.py: --out of 300 bytes", "run.py", _elc(out=f"{long}/x"), out=None,
                   verify=_exit_2),
              Case(HARD + "names", "run.py: --out beyond PATH_MAX", "run.py", _elc(out=deep), out=None,
                   verify=_exit_2),
              Case(HARD + "names", "run.py: results.dir of 300 bytes", "run.py",
                   [str(SC / "elcentro.yaml"), "--set", SHORT, "--set", f"results.dir={long}", "--quiet",
                    "--no-plots"], out=None, verify=_exit_2)]
    for pattern in ("a" * 300 + ".AT2", "../*.csv", "/etc/*"):
        def ida_setup(d: Path, pattern: str = pattern) -> None:
            spec = yaml.safe_load(_mini_ida_file(d).read_text())
            spec["suite"]["patterns"] = [pattern]
            (d / "ida.yaml").write_text(yaml.safe_dump(spec))
        cases.append(Case(HARD + "names", f"ida.py: suite pattern {pattern[:20]!r}", "ida.py",
                          ["ida.yaml", "--out", "out", "--quiet", "--workers", "1"], setup=ida_setup,
                          verify=_exit_2))

    designs = {"elcentro_clipped_optimal.yaml": [("controller.r=0", "controller.q_acc=0"),
                                                 ("controller.s_ground=0", "controller.s_force=0")],
               "elcentro_lyapunov.yaml": [("controller.s_ground=0", "controller.s_force=0")],
               "nominal_plant_elcentro.yaml": [("coil.tau=-0.01",), ("coil.tau=-1e-9",)]}
    for name, variants in designs.items():
        for sets in variants:
            unit, _, rest = sets[0].partition(".")
            cases.append(Case(HARD + "new-unit designs", f"{name}: {' '.join(sets)}"[:70], "run.py",
                              [str(SC / name), "--set", SHORT, *(a for x in sets for a in ("--set", x)), "--out",
                               "out", "--quiet", "--no-plots"],
                              verify=_exit_and_says(2, f"units.{unit}.parameters.{rest.partition('=')[0]}")))

    def sensed(d: Path) -> None:
        (d / "sensed.yaml").write_text(f"extends: {SC / 'nominal_plant_elcentro.yaml'}\nname: sensed\nunits:\n"
                                       f"  sensors:\n    fmu: {FMUS / 'SensorChannels.fmu'}\n")
    for setter, parameter in (("sensors.delay=-1", "delay"), ("sensors.rms_disp_1=-0.001", "rms_disp_1")):
        cases.append(Case(HARD + "new-unit designs", f"SensorChannels: {setter}", "run.py",
                          ["sensed.yaml", "--set", SHORT, "--set", setter, "--out", "out", "--quiet", "--no-plots"],
                          setup=sensed, verify=_exit_and_says(2, f"units.sensors.parameters.{parameter}")))
    cases.append(Case(HARD + "study configuration", "study: ${best_current} without best-constant", "study.py",
                      [*study, "--set", "strategy_definitions={x: {parameters: {mode: passive, i_passive: "
                       "'${best_current}'}}}", "--set", "strategies=[passive-off, x]", "--out", "out", "--quiet",
                       "--workers", "1"], verify=_exit_and_says(2, "best-constant")))

    scripts = base / "scripts"
    scripts.mkdir(exist_ok=True)
    for label, head in _SCRIPTS.items():
        script = scripts / f"{len(list(scripts.iterdir()))}.py"
        script.write_text(head + _MODEL.read_text())
        verify = (_nothing_at("/out", "/out-corpus") if "chdir" in label else
                  _exit_and_says(2, str(script)))
        cases.append(Case(HARD + "user scripts", f"OpenSees script: {label}", "run.py",
                          [str(SC / "elcentro_opensees.yaml"), "--set", SHORT, "--set",
                           f"building.script=!data {script}", "--out", "out", "--quiet", "--no-plots"],
                          env={"MRE_COSIM_SCRIPT_CHECK_TIMEOUT_S": "5"}, timeout=60, verify=verify))
    package = export_ssp(plan_scenario(SC / "elcentro_opensees.yaml", (SHORT,)), base / "opensees.ssp")
    cases.append(Case(HARD + "user scripts", "SSP package carrying a script: said on the console", "run.py",
                      [str(package), "--out", "out", "--quiet", "--no-plots"],
                      verify=_exit_and_says(0, "carries a script", "resources/dyke_linear.py")))

    for kind in ("a file", "a symlink", "open to all", "a planted kernel"):
        cases.append(Case(HARD + "caches", f"MRE_COSIM_CACHE is {kind}", "run.py", _elc(),
                          setup=_kernel_cache(kind), env={"MRE_COSIM_CACHE": "../tmp/mre-cosim-files-kernels"},
                          verify=_kernel_untouched))
    for kind in ("a symlink", "a file", "planted extractions"):
        cases.append(Case(HARD + "caches", f"study: the workers' file cache is {kind}", "study.py",
                          [*study, "--set", "strategies=[passive-off]", "--out", "out", "--quiet", "--workers", "1"],
                          setup=_files_cache(kind), timeout=300, verify=_study_ran_clean))

    long_run = [str(SC / "kobe.yaml"), "--set", "simulation.stop_time=60", "--out", "out", "--quiet", "--no-plots"]
    for name, sig in (("stopped (SIGSTOP)", signal.SIGSTOP), ("killed (SIGKILL)", signal.SIGKILL)):
        cases.append(Case(HARD + "CSV process", f"the CSV process {name}", "run.py", long_run, timeout=240,
                          during=(0.0, _signal_csv_child(sig)), verify=_csv_child_outcome))

    def unitless(d: Path) -> None:
        import re

        copy_zip(FMUS / "SosmCurrentController.fmu", d / "unitless.fmu", lambda n, b: re.sub(
            r'(name="i"[^>]*>\s*<Real[^>]*?) unit="A"', r"\1", b.decode(), count=1).encode()
            if n == "modelDescription.xml" else b)
    cases.append(Case(HARD + "units", "a unit-less output into an input in A: accepted, warned", "run.py",
                      _elc("units.controller.fmu=unitless.fmu"), setup=unitless,
                      verify=_exit_and_says(0, "warning: controller.i declares no unit", "isolator.i in A")))
    return cases


STOP37 = "37/"


def _zip_of(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buffer.getvalue()


def _a_run(base: Path) -> Path:
    """One short El Centro run folder to compare against (made once for the corpus)."""
    run = base / "good-run"
    if not run.exists():
        done = subprocess.run([*TOOLS["run.py"], *_elc(out=str(run))], capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
    return run


def _run_copy(good: Path, edit: Callable[[Path], None]) -> Callable[[Path], None]:
    def setup(d: Path) -> None:
        shutil.copytree(good, d / "other")
        edit(d / "other")
    return setup


def _results(rows: list[dict[str, str]] | bytes) -> Callable[[Path], None]:
    def setup(d: Path) -> None:
        (d / "ida").mkdir()
        if isinstance(rows, bytes):
            (d / "ida" / "results.csv").write_bytes(rows)
            return
        with open(d / "ida" / "results.csv", "w", newline="") as f:
            w = csv.DictWriter(f, list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    return setup


def stop37_cases(base: Path) -> list[Case]:
    """The inputs of class 37/: the results file's interval and format, a strategy's role mapping, and the
    inspect, compare and verdict tools (files that are not what they claim, names long or with ../, numbers that
    are not)."""
    cases: list[Case] = []
    for value in ("nan", "inf", "-inf", "0", "-1", "1.5", "'10'", "true", "1e30", "100000000000000000000", "[1]"):
        cases.append(Case(STOP37 + "results file", f"output_interval={value}", "run.py",
                          _elc(f"simulation.output_interval={value}"), verify=_exit_2))
    for value in ("hdf5", "../x", "123", "PARQUET", "''", "null"):
        cases.append(Case(STOP37 + "results file", f"output_format={value}", "run.py",
                          _elc(f"simulation.output_format={value}"), verify=_exit_2))
    one = ("records={elcentro: elcentro.yaml}", "overrides=[simulation.stop_time=0.05, simulation.output_interval=5, "
           "simulation.output_format=parquet]", "reference={enabled: false}", "strategies=[passive-off]")
    cases.append(Case(STOP37 + "results file", "a study with output_interval and parquet, kept", "study.py",
                      [str(SC / "case_study.yaml"), *(a for o in one for a in ("--set", o)), "--set", "timeseries=true",
                       "--out", "out", "--quiet", "--workers", "1"], verify=_kept_every_fifth))
    for value in ("yes", "1", "null", "[true]", "'true'", ".nan"):  # timeseries is true or false, nothing else
        cases.append(Case(STOP37 + "results file", f"a study with timeseries: {value}", "study.py",
                          [str(SC / "case_study.yaml"), *(a for o in one for a in ("--set", o)), "--set",
                           f"timeseries={value}", "--out", "out", "--quiet", "--workers", "1"], verify=_exit_2))

    study = [str(SC / "case_study.yaml"), "--set", "records={elcentro: elcentro.yaml}", "--set",
             "overrides=[simulation.stop_time=0.05]", "--set", "reference={enabled: false}", "--out", "out",
             "--quiet", "--workers", "1"]
    fmu = FMUS / "ConstantCurrent.fmu"
    for key, value in (("current", '""'), ("current", '" i"'), ("current", '"u -> x"'), ("current", "5"),
                       ("current", '"../x"'), ("current", '"' + "c" * 300 + '"'), ("current", '"\\u0000"'),
                       ("limit", '"nope"'), ("limit", '"i"'), ("limit", "[1]"), ("current", '"current"')):
        entry = f"strategy_definitions={{mine: {{fmu: {fmu}, parameters: {{current: 1.0}}, connections: [], " \
                f"{key}: {value}}}}}"
        cases.append(Case(STOP37 + "role mapping", f"{key}: {value}"[:70], "study.py",
                          [*study, "--set", entry, "--set", "strategies=[passive-off, mine]"], verify=_exit_2))

    long = "a" * 300
    def text(name: str, data: bytes) -> Callable[[Path], None]:
        def setup(d: Path) -> None:
            (d / name).parent.mkdir(parents=True, exist_ok=True)
            (d / name).write_bytes(data)
        return setup
    inspect = {"a text file named .fmu": (["t.fmu"], text("t.fmu", b"not a zip")),
               "a zip without modelDescription": (["z.fmu"], text("z.fmu", _zip_of({"a.txt": b"x"}))),
               "a zip with a broken modelDescription": (["b.fmu"], text("b.fmu", _zip_of(
                   {"modelDescription.xml": b"<fmiModelDescription"}))),
               "a folder": (["."], None), "/dev/zero": (["/dev/zero"], None), "missing": (["none.fmu"], None),
               "a name of 300 bytes": ([f"{long}.fmu"], None), "a path with ../": (["../../../../etc/passwd"], None),
               "--role nope": ([str(FMUS / "ShearBuilding.fmu"), "--role", "nope"], None),
               "--map without =": ([str(FMUS / "ShearBuilding.fmu"), "--role", "building", "--map", "x"], None),
               "--map of an unknown name": ([str(FMUS / "ShearBuilding.fmu"), "--role", "building", "--map", "zz=1"],
                                            None)}
    cases += [Case(STOP37 + "inspect", name, "inspect", argv, setup, out=None, verify=_exit_2)
              for name, (argv, setup) in inspect.items()]
    cases.append(Case(STOP37 + "inspect", "a building in the controller role: exit 1", "inspect",
                      [str(FMUS / "ShearBuilding.fmu"), "--role", "controller"], out=None,
                      verify=lambda work, codes, err: [] if codes == [1] else [f"exit {codes}, expected 1"]))

    good = _a_run(base)

    def put(name: str, data: bytes | str) -> Callable[[Path], None]:
        def edit(run: Path) -> None:
            (run / name).write_bytes(data if isinstance(data, bytes) else data.encode())
        return edit
    bad_runs = {"summary.json is a list": put("summary.json", "[1, 2]"),
                "summary.json is not JSON": put("summary.json", "{bad"),
                "summary.json of 65 MiB": put("summary.json", b" " * (65 << 20)),
                "timeseries.csv of text": put("timeseries.csv", "time,a\nx,y\n"),
                "timeseries.csv rows shorter than its header": put("timeseries.csv", "time,a,b\n0,1\n"),
                "timeseries.csv of random bytes": put("timeseries.csv", random.Random(37).randbytes(4096)),
                "timeseries.parquet that is not Parquet": put("timeseries.parquet", "PAR1 no"),
                "no results file": lambda run: (run / "timeseries.csv").unlink()}
    cases += [Case(STOP37 + "compare", name, "compare", [str(good), "other", "--out", "out"],
                   _run_copy(good, edit), verify=_exit_2) for name, edit in bad_runs.items()]
    cases += [Case(STOP37 + "compare", name, "compare", [str(good), *argv], out=out, verify=_exit_2)
              for name, argv, out in (("a file as a run", [PRECIOUS, "--out", "out"], "out"),
                                      ("/dev/null as a run", ["/dev/null", "--out", "out"], "out"),
                                      ("a run of 300 bytes", [long, "--out", "out"], "out"),
                                      ("--out is a file", [str(good), "--out", PRECIOUS], None),
                                      ("--out of 300 bytes", [str(good), "--out", f"{long}/x"], None),
                                      ("--out below a file", [str(good), "--out", f"{PRECIOUS}/x"], None),
                                      ("--dpi 0", [str(good), "--dpi", "0", "--out", "out"], "out"),
                                      ("--dpi nan", [str(good), "--dpi", "nan", "--out", "out"], "out"),
                                      ("--dpi of 10^30", [str(good), "--dpi", "1" + "0" * 30, "--out", "out"], "out"),
                                      ("--format tiff", [str(good), "--format", "tiff", "--out", "out"], "out"))]

    def row(record: str, strategy: str, value: str, intensity: str = "0.1") -> dict[str, str]:
        return {"record": record, "component": "-", "intensity": intensity, "strategy": strategy, "valid": "True",
                **{c: value for c in ("J1", "J2", "J3", "J4", "J5", "J7", "J8")}}
    good_rows = [row(f"R{k}", s, str(1 + k + (s == "b") * 0.1)) for k in range(6) for s in "ab"]
    verdicts = {"results.csv of random bytes": (_results(random.Random(7).randbytes(3000)), []),
                "results.csv without the columns": (_results(b"a,b\n1,2\n"), []),
                "an intensity that is text": (_results([row("R1", "a", "1", "zz"), row("R1", "b", "1", "zz")]), []),
                "an intensity of nan": (_results([row("R1", "a", "1", "nan"), row("R1", "b", "1", "nan")]), []),
                "--level nan": (_results(good_rows), ["--level", "nan"]),
                "--level inf": (_results(good_rows), ["--level", "inf"]),
                "--alpha nan": (_results(good_rows), ["--alpha", "nan"]),
                "--alpha 0": (_results(good_rows), ["--alpha", "0"]),
                "--alpha 1e308": (_results(good_rows), ["--alpha", "1e308"]),
                "--criteria ../J3": (_results(good_rows), ["--criteria", "../J3"]),
                "--strategies of one": (_results(good_rows), ["--strategies", "a"]),
                "--out is a file": (_results(good_rows), ["--out", PRECIOUS]),
                "--out of 300 bytes": (_results(good_rows), ["--out", f"{long}/x"])}
    for name, (setup, extra) in verdicts.items():
        argv = ["ida", *extra] + ([] if "--out" in extra else ["--out", "out"])
        cases.append(Case(STOP37 + "verdict", name, "verdict", argv, setup,
                          out=None if "--out" in extra else "out", verify=_exit_2))
    cases.append(Case(STOP37 + "verdict", "values nan, inf, -1 and text: left out, not a crash", "verdict",
                      ["ida", "--out", "out"], _results([row("R0", s, v) for s, v in (("a", "nan"), ("b", "inf"))]
                                                        + [row("R1", s, v) for s, v in (("a", "-1"), ("b", "x"))]
                                                        + good_rows),
                      verify=lambda work, codes, err: [] if codes == [0] else [f"exit {codes}, expected 0"]))
    cases.append(Case(STOP37 + "verdict", "no results.csv", "verdict", [".", "--out", "out"], verify=_exit_2))
    return cases


STOP42 = "42/"
"""Prefix of these classes: ``--only 42/`` runs them alone."""


def stop42_cases(base: Path) -> list[Case]:
    """The inputs of class 42/: the run figures' units and storey heights, the sampled plants of a benchmark
    (robustness.plant_samples: its file, sizes, axes, seed and unit), robustness.strategies and ``set`` variants."""
    cases: list[Case] = []
    for key, value in (("acceleration_unit", "ft/s2"), ("acceleration_unit", "G"), ("acceleration_unit", "nan"),
                       ("acceleration_unit", "1"), ("acceleration_unit", "../x"), ("drift_unit", "ratio"),
                       ("drift_unit", "''"), ("storey_heights", "[nan, 3, 3]"), ("storey_heights", "[inf, 3, 3]"),
                       ("storey_heights", "[-1, 3, 3]"), ("storey_heights", "[0, 3, 3]"),
                       ("storey_heights", "['3', 3, 3]"), ("storey_heights", "[true, 3, 3]"),
                       ("storey_heights", "[3]"), ("storey_heights", "[" + ", ".join(["3"] * 10000) + "]"),
                       ("storey_heights", "../x")):
        sets = [f"report.{key}={value}"]
        if key == "storey_heights":
            sets.append("report.drift_unit=ratio")
        cases.append(Case(STOP42 + "figure units", f"{key}={value}"[:70], "run.py", _elc(*sets), verify=_exit_2))
    nominal = SC / "nominal_plant_elcentro.yaml"
    study = [str(SC / "controller_benchmark.yaml"), "--set", f"records={{elcentro: {nominal}}}",
             "--set", "strategies=[passive-off, passive-on]", "--set", f"overrides=[{SHORT}]",
             "--set", "reference={enabled: false}", "--out", "out", "--quiet", "--workers", "1"]
    samples = SC / "plants" / "plant_samples_bouc_wen-joint.yaml"

    made = base / "stop42"
    made.mkdir(parents=True, exist_ok=True)
    good = samples.read_text()

    def sample_file(name: str, text: str) -> str:
        (made / name).write_text(text)
        return str(made / name)

    files = {  # the file key is relative to the study file (scenarios/); these are absolute or resolve from there
        "missing": "none.yaml", "a folder": str(SC), "/dev/zero": "/dev/zero",
        "a path with ../": "../../../../../../etc/passwd", "a name of 300 bytes": "é" * 150 + ".yaml",
        "not YAML": sample_file("notyaml.yaml", "{{{ not yaml"),
        "another kind": sample_file("other.yaml", "kind: other\n"),
        "a NaN coefficient": sample_file("nan.yaml", good.replace("k_0: ", "k_0: .nan #", 2)),
        "no samples": sample_file("none_listed.yaml", good.split("samples:")[0] + "samples: []\n"),
        "no samples key": sample_file("nokey.yaml", good.split("samples:")[0]),
    }
    for name, path in files.items():
        cases.append(Case(STOP42 + "plant samples", f"file: {name}", "study.py",
                          [*study, "--set", f"robustness={{plant_samples: {{file: '{path}', lhs: 2}}}}"],
                          verify=_exit_2))
    for key, value in (("lhs", "-1"), ("lhs", "1"), ("lhs", "'2'"), ("lhs", "1000000000"), ("lhs", ".nan"),
                       ("sobol", "3"), ("sobol", "-2"), ("sobol", "1000000000"), ("sobol", ".inf"), ("axes", "0"),
                       ("axes", "11"), ("axes", "99"), ("seed", "-1"), ("seed", "1099511627776"), ("seed", "1.5"),
                       ("unit", "../isolator"), ("unit", "''"), ("unit", "ghost"), ("lhs", "0")):
        extra = "" if key in ("sobol", "axes") else ", sobol: 0" if key == "lhs" else ""
        spec = f"{{file: {samples}, lhs: 2, sobol: 2, axes: 1, {key}: {value}}}" if key in ("sobol", "axes") else \
            f"{{file: {samples}, lhs: 2{extra}, {key}: {value}}}"
        cases.append(Case(STOP42 + "plant samples", f"{key}: {value}"[:70], "study.py",
                          [*study, "--set", f"robustness={{plant_samples: {spec}}}"], verify=_exit_2))
    for name, rob in (("strategies an unknown one", "{strategies: [nope], variants: {lag: {current_lag: 0.01}}}"),
                      ("strategies a number", "{strategies: 5, variants: {lag: {current_lag: 0.01}}}"),
                      ("set NaN", "{variants: {v: {set: {isolator.k_0: .nan}}}}"),
                      ("set on the controller", "{variants: {v: {set: {controller.i_max: 1.0}}}}"),
                      ("set a String parameter", "{variants: {v: {set: {isolator.beyond_range: 1.0}}}}"),
                      ("set a parameter the plant lacks", "{variants: {v: {set: {isolator.nope: 1.0}}}}"),
                      ("set a name with ../", "{variants: {v: {set: {'../x.y': 1.0}}}}"),
                      ("set text", "{variants: {v: {set: {isolator.k_0: 'big'}}}}")):
        cases.append(Case(STOP42 + "set variants", name, "study.py", [*study, "--set", f"robustness={rob}"],
                          verify=_exit_2))
    return cases


STOP43 = "43/"
"""Prefix of these classes: ``--only 43/`` runs them alone."""


def stop43_cases(base: Path) -> list[Case]:
    """The inputs of class 43/: the suite benchmark's ``benchmark:`` section (split, tuning, verdict), an IDA's
    ``events`` and a study's ``figure_units``."""
    cases: list[Case] = []
    bench = [str(SC / "controller_suite_benchmark.yaml"), "--out", "out", "--quiet", "--workers", "1"]
    for key, value in (("train", ".nan"), ("train", ".inf"), ("train", "-3"), ("train", "0"), ("train", "1.5"),
                       ("train", "'3'"), ("train", "true"), ("train", "1000000000"), ("train", "[]"),
                       ("train", "[FF01, FF01]"), ("train", "['../FF01']"), ("train", "['" + "é" * 150 + "']"),
                       ("train", "[FF01]"), ("score", "[FF99]"), ("score", "[]"), ("split_by", "station"),
                       ("split_by", "../x"), ("split_seed", "-1"), ("split_seed", "1099511627776"),
                       ("split_seed", ".nan"), ("overlap", "'yes'"), ("tune", "[]"), ("tune", "[nope]"),
                       ("tune", "[passive-on]"), ("tune", "[sosm, sosm]"), ("tune", "5"), ("budget", "0"),
                       ("budget", "2"), ("budget", "-5"), ("budget", "1000000000"), ("budget", ".inf"),
                       ("seed", "-1"), ("alpha", "0"), ("alpha", "1"), ("alpha", ".nan"),
                       ("criteria", "[J6]"), ("criteria", "[]"), ("objective", "{w_zero: 1.0}"),
                       ("objective", "{w_acc: -1}"), ("objective", "{x_limit: .nan}"), ("bogus", "1")):
        cases.append(Case(STOP43 + "suite benchmark", f"{key}: {value}"[:70], "study.py",
                          [*bench, "--set", f"benchmark.{key}={value}"], verify=_exit_2))
    cases.append(Case(STOP43 + "suite benchmark", "too many records trained on", "study.py",
                      [*bench, "--set", "benchmark.split_by=record", "--set", "benchmark.train=20"], verify=_exit_2))
    cases.append(Case(STOP43 + "suite benchmark", "a folder suite split by earthquake", "study.py",
                      [*bench, "--set", f"suite={{folder: {SC / 'records'}}}"], verify=_exit_2))
    cases.append(Case(STOP43 + "suite benchmark", "events in a benchmark", "study.py",
                      [*bench, "--set", "events=[FF01]"], verify=_exit_2))
    cases.append(Case(STOP43 + "suite benchmark", "ida.py on a benchmark", "ida.py", bench[:3], verify=_exit_2))
    ida = [str(SC / "ida_controllers_far_field.yaml"), "--out", "out", "--quiet", "--workers", "1"]
    for value in ("[FF99]", "[]", "[FF01, FF01]", "['../FF01']", "5", "[.nan]"):
        cases.append(Case(STOP43 + "ida events", f"events: {value}", "ida.py", [*ida, "--set", f"events={value}"],
                          verify=_exit_2))
    study = [str(SC / "case_study.yaml"), "--out", "out", "--quiet", "--workers", "1"]
    for value in ("{drift: ratio}", "{acceleration: ft/s2}", "{storey_heights: [.nan, 3, 3]}",
                  "{drift: ratio, storey_heights: [.inf, 3, 3]}", "{drift: ratio, storey_heights: [-1, 3, 3]}",
                  "{drift: ratio, storey_heights: [0, 3, 3]}", "{drift: ratio, storey_heights: ['3', 3, 3]}",
                  "{drift: ratio, storey_heights: [3]}", "{drift: ratio, storey_heights: []}",
                  "{drift: ratio, storey_heights: [" + ", ".join(["3"] * 10000) + "]}", "{units: g}", "'../x'"):
        cases.append(Case(STOP43 + "study figure units", f"figure_units: {value}"[:70], "study.py",
                          [*study, "--set", f"figure_units={value}"], verify=_exit_2))
    return cases


STOP45 = "45/"
"""Prefix of these classes: ``--only 45/`` runs them alone."""


def stop45_cases(base: Path) -> list[Case]:
    """The inputs of class 45/: a strategy entry's flags (uncontrolled, radau_reference, paper_figures, style), the
    uncontrolled case of a study, a suite benchmark and an IDA, a benchmark's j6_reference, and a study's
    ``timeseries``."""
    cases: list[Case] = []
    study = [str(SC / "case_study.yaml"), "--set", "records={elcentro: elcentro.yaml}", "--set",
             f"overrides=[{SHORT}]", "--set", "reference={enabled: false}", "--out", "out", "--quiet",
             "--workers", "1"]
    entry = "strategy_definitions={{mine: {{parameters: {{mode: passive, i_passive: 1.0}}, {flag}}}}}"
    for flag in ("uncontrolled: 'yes'", "uncontrolled: 1", "uncontrolled: null", "radau_reference: 'true'",
                 "radau_reference: [true]", "paper_figures: fig16", "paper_figures: ''", "paper_figures: 1",
                 "style: {color: nope}", "style: {color: '#12345'}", "style: {color: 1}", "style: {line: '~'}",
                 "style: {line: [1, 2, 3]}", "style: {line: [.nan, 1]}", "style: {line: [.inf, 1]}",
                 "style: {line: [0, 1]}", "style: {line: [" + ", ".join(["1"] * 40) + "]}",
                 "style: {marker: '$x$'}", "style: {marker: ../x}", "style: {bogus: 1}", "style: '../x'",
                 "style: [1]", "bogus_flag: true"):
        cases.append(Case(STOP45 + "strategy flags", flag[:70], "study.py",
                          [*study, "--set", entry.format(flag=flag), "--set", "strategies=[passive-off, mine]"],
                          verify=_exit_2))
    mine = entry.format(flag="uncontrolled: true")
    for strategies in ("[passive-on]", "[passive-off, mine]", "[mine, passive-off, passive-on]"):
        cases.append(Case(STOP45 + "uncontrolled case", f"case study: {strategies}", "study.py",
                          [*study, "--set", mine, "--set", f"strategies={strategies}"], verify=_exit_2))
    radau = entry.format(flag="radau_reference: true").replace("mode: passive, i_passive: 1.0", "mode: sosm")
    cases.append(Case(STOP45 + "strategy flags", "radau_reference on a controller", "study.py",
                      [*study, "--set", radau, "--set", "strategies=[passive-off, mine]", "--set",
                       "reference={enabled: true}"], verify=_exit_2))
    bench = [str(SC / "controller_benchmark.yaml"), *study[1:]]
    for value in ("passive-of", "'../x'", "1", "''", "[passive-on]"):
        cases.append(Case(STOP45 + "benchmark", f"j6_reference: {value}", "study.py",
                          [*bench, "--set", f"benchmark.j6_reference={value}"], verify=_exit_2))
    suite = [str(SC / "controller_suite_benchmark.yaml"), "--out", "out", "--quiet", "--workers", "1"]
    cases.append(Case(STOP45 + "uncontrolled case", "suite benchmark without one", "study.py",
                      [*suite, "--set", "strategies=[passive-on, sosm]", "--set", "benchmark.tune=[sosm]"],
                      verify=_exit_2))
    for value in ("yes", "1", "null", "[true]", "'true'", ".nan", "{a: 1}"):
        cases.append(Case(STOP45 + "study timeseries", f"timeseries: {value}", "study.py",
                          [*study, "--set", f"timeseries={value}"], verify=_exit_2))
    cases += run_file_cases(base)
    return cases


def _run_file(name: str, write: Callable[[Path], None]) -> Callable[[Path], None]:
    """Damage: the first run folder's ``name`` replaced by what ``write(path)`` makes there."""
    def damage(folder: Path) -> None:
        path = sorted((folder / "runs").iterdir())[0] / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)
        write(path)
    return damage


def _edit_numbers(change: Callable[[dict], Any]) -> Callable[[Path], None]:
    def damage(folder: Path) -> None:
        path = sorted((folder / "runs").iterdir())[0] / "metrics.json"
        data = json.loads(path.read_text())
        new = change(data)
        path.write_text(json.dumps(data if new is None else new))
    return damage


def _parquet_with(columns: dict[str, Any]) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.table(columns), path)
    return write


def _says_file(name: str, code: int) -> Callable[[Path, list[int], str], list[str]]:
    """Exit ``code`` with a message that names the damaged file; nothing left half-written in the study folder."""
    def verify(work: Path, codes: list[int], err: str) -> list[str]:
        reasons = [] if codes == [code] else [f"exit {codes}, expected {code}"]
        reasons += [] if name in err else [f"the message does not name {name}"]
        reasons += [f"{p} left behind" for p in (work / "prev").rglob(".*.tmp*")]
        return reasons
    return verify


def run_file_cases(base: Path) -> list[Case]:
    """A finished study folder whose run files (``metrics.json``, ``figure_series.parquet``) are not what the runs
    wrote, for ``--report`` (exit 2, nothing written) and ``--resume`` (its runs and jobs kept; the report not
    written: exit 1)."""
    big = "{" + ", ".join(f'"k{k}": {k}' for k in range(120_000)) + "}"
    damages = {
        "metrics.json not JSON": _run_file("metrics.json", lambda p: p.write_text("{nope")),
        "metrics.json empty": _run_file("metrics.json", lambda p: p.write_text("")),
        "metrics.json random bytes": _run_file("metrics.json", lambda p: p.write_bytes(os.urandom(4096))),
        "metrics.json a list": _edit_numbers(lambda d: [d]),
        "metrics.json NaN literal": _run_file("metrics.json", lambda p: p.write_text('{"metrics": NaN}')),
        "metrics.json metrics a list": _edit_numbers(lambda d: d.__setitem__("metrics", [1])),
        "metrics.json a peak of text": _edit_numbers(lambda d: d["metrics"].__setitem__("acc_3", "x")),
        "metrics.json a peak true": _edit_numbers(lambda d: d["metrics"].__setitem__("acc_3", True)),
        "metrics.json a peak missing": _edit_numbers(lambda d: d["metrics"].pop("acc_3") and None),
        "metrics.json criteria missing": _edit_numbers(lambda d: d.pop("criteria") and None),
        "metrics.json 2 MiB": _run_file("metrics.json", lambda p: p.write_text(big + " " * (2 << 20))),
        "metrics.json a folder": _run_file("metrics.json", lambda p: p.mkdir()),
        "metrics.json a link to /dev/zero": _run_file("metrics.json", lambda p: p.symlink_to("/dev/zero")),
        "figure_series.parquet random bytes": _run_file("figure_series.parquet",
                                                        lambda p: p.write_bytes(os.urandom(5000))),
        "figure_series.parquet JSON": _run_file("figure_series.parquet", lambda p: p.write_text("{}")),
        "figure_series.parquet a folder": _run_file("figure_series.parquet", lambda p: p.mkdir()),
        "figure_series.parquet without time": _run_file("figure_series.parquet", _parquet_with(
            {"building.x_0": [0.0, 1.0]})),
        "figure_series.parquet of text": _run_file("figure_series.parquet", _parquet_with(
            {c: ["a", "b"] for c in ("time", "building.x_0", "isolator.F", "controller.i", "building.a_top")})),
    }
    cases = []
    for name, damage in damages.items():
        file = name.split(" ")[0]
        cases.append(Case(STOP45 + "run files", f"--report, {name}", "study.py", ["--report", "prev"],
                          _damaged("study", base, damage), out=None, timeout=180, verify=_says_file(file, 2)))
    for name in ("metrics.json not JSON", "figure_series.parquet random bytes"):
        cases.append(Case(STOP45 + "run files", f"--resume, {name}", "study.py",  # the fixture's code version: its
                          ["--resume", "prev", "--quiet", "--workers", "1"],  # jobs are reused, nothing computed
                          _damaged("study", base, damages[name]), out="prev", timeout=180,
                          env={"MRE_COSIM_CODE_VERSION": "corpus"}, changes=("prev", "prev/study.json"),  # resumed
                          verify=_says_file(name.split(" ")[0], 1)))
    return cases


def build_cases(seed: int, base: Path) -> list[Case]:
    global _PACKAGE_LONG
    from orchestration.engine_hooks import plan_scenario
    from orchestration.interop.ssp_package import export_ssp

    rng = random.Random(seed)
    package = export_ssp(plan_scenario(SC / "elcentro.yaml", (SHORT,)), base / "elcentro.ssp")
    _PACKAGE_LONG = export_ssp(plan_scenario(SC / "kobe.yaml"), base / "kobe.ssp")
    return [*scenario_cases(rng, 110), *yaml_text_cases(), *override_cases(), *record_cases(rng, 30), *fmu_cases(),
            *ssp_cases(rng, 40, package), *output_cases(), *fault_cases(), *other_tool_cases(),
            *engine_cases(base, package), *study_tool_cases(base), *new_unit_cases(), *session_input_cases(),
            *leftover_cases(base), *hardening_cases(base), *stop37_cases(base),
            *stop42_cases(base), *stop43_cases(base), *stop45_cases(base)]


def write_report(results: list[Result], report: Path, command: str, seconds: float) -> None:
    by_class: dict[str, list[Result]] = defaultdict(list)
    for r in results:
        by_class[r.cls].append(r)
    lines = ["<!-- corpus:begin -->",
             f"Measured with `{command}` ({len(results)} cases, {seconds / 60:.1f} min on this project's 2-core "
             "machine):", "",
             "| class | cases | clean | not clean | data loss | exit codes seen |", "|---|---:|---:|---:|---:|---|"]
    for cls, rs in by_class.items():
        codes = Counter(c for r in rs for c in r.codes)
        seen = ", ".join(f"{c}: {n}" for c, n in sorted(codes.items()))
        clean = sum(r.clean for r in rs)
        lines.append(f"| {cls} | {len(rs)} | {clean} | {len(rs) - clean} | {sum(r.data_loss for r in rs)} | {seen} |")
    total_clean = sum(r.clean for r in results)
    lines += [f"| **all** | **{len(results)}** | **{total_clean}** | **{len(results) - total_clean}** | "
              f"**{sum(r.data_loss for r in results)}** | |", "",
              f"Clean: {100 * total_clean / len(results):.1f} %; data loss: {sum(r.data_loss for r in results)} cases."]
    bad = [r for r in results if not r.clean]
    if bad:
        lines += ["", "Cases that were not clean:", ""]
        lines += [f"* {r.cls} / {r.name} ({r.tool}, exit {r.codes}): {'; '.join(r.reasons)}" for r in bad]
    lines.append("<!-- corpus:end -->")
    block = "\n".join(lines)
    text = report.read_text() if report.exists() else ""
    if "<!-- corpus:begin -->" in text and "<!-- corpus:end -->" in text:
        head, rest = text.split("<!-- corpus:begin -->", 1)
        text = head + block + rest.split("<!-- corpus:end -->", 1)[1]
    else:
        text = text + ("\n" if text else "") + block + "\n"
    report.write_text(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2, help="cases run at a time")
    parser.add_argument("--only", nargs="*", default=[], help="run only the classes whose name contains one of these")
    parser.add_argument("--seed", type=int, default=13)
    parser.add_argument("--report", type=Path, default=None,
                        help="file whose table is replaced (default: docs/reliability.md for a whole run; none "
                             "with --only, so that a part never overwrites the whole run's table)")
    parser.add_argument("--jsonl", type=Path, default=None, help="also write every case's outcome here (JSON lines)")
    parser.add_argument("--keep", action="store_true", help="keep the case folders")
    args = parser.parse_args(argv)
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:  # started in the background (`&`, nohup): the cases'
        signal.signal(signal.SIGINT, signal.default_int_handler)  # tools would inherit an ignored Ctrl-C
    subprocess.run([PY, "-m", "components.build"], check=True, stdout=subprocess.DEVNULL)  # no build races later
    base = Path(tempfile.mkdtemp(prefix="mre-corpus-"))
    started = time.monotonic()
    try:
        cases = build_cases(args.seed, base)
        if args.only:
            cases = [c for c in cases if any(o in c.cls for o in args.only)]
        print(f"{len(cases)} cases in {base}", flush=True)
        results: list[Result] = []
        with ThreadPoolExecutor(args.workers) as pool:
            futures = [pool.submit(_run_case, c, base / "cases", k) for k, c in enumerate(cases)]
            for k, fut in enumerate(futures):
                r = fut.result()
                results.append(r)
                mark = "ok " if r.clean else "BAD"
                print(f"[{k + 1:3d}/{len(cases)}] {mark} {r.cls} / {r.name} -> {r.codes} {'; '.join(r.reasons)}",
                      flush=True)
        seconds = time.monotonic() - started
        command = "python benchmarks/reliability_corpus.py" + (f" --only {' '.join(args.only)}" if args.only else "")
        report = args.report if args.report is not None or args.only else PROJECT / "docs" / "reliability.md"
        if report is not None:
            write_report(results, report, command, seconds)
        if args.jsonl is not None:
            args.jsonl.write_text("".join(json.dumps(asdict(r)) + "\n" for r in results))
        clean = sum(r.clean for r in results)
        print(f"{clean}/{len(results)} clean ({100 * clean / len(results):.1f} %), "
              f"{sum(r.data_loss for r in results)} with data loss, {seconds / 60:.1f} min")
        return 0
    finally:
        for line in Path("/proc/mounts").read_text().splitlines() if IS_ROOT else []:
            where = line.split()[1]
            if where.startswith(str(base)):
                subprocess.run(["umount", where], check=False)
        if not args.keep:
            for root, dirs, _ in os.walk(base):
                for d in dirs:
                    os.chmod(os.path.join(root, d), 0o755)
            shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    raise SystemExit(main())
