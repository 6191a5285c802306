"""Ground-motion records: formats, playback and clear errors naming file and line."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from components.physics.ground_motion_core import G, GroundMotion, RecordError, read_record

from ..conftest import shipped_record


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_two_column_csv_with_comments_and_header(tmp_path):
    path = write(tmp_path, "r.csv", "# a comment\ntime_s,accel_g\n0.0,0.0\n0.02,0.1 # inline\n0.04,-0.2\n")
    rec = read_record(path)
    assert rec.time.tolist() == [0.0, 0.02, 0.04]
    assert rec.accel_g.tolist() == [0.0, 0.1, -0.2]


def test_at2_format(tmp_path):
    text = "PEER NGA\nKOBE 1/16/95, KJM, 000\nACCELERATION TIME SERIES IN UNITS OF G\n" \
           "NPTS=    5, DT=   .0100 SEC\n  .1  .2  .3\n  .4  .5\n"
    rec = read_record(write(tmp_path, "r.AT2", text))
    assert rec.time == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])
    assert rec.accel_g.tolist() == [0.1, 0.2, 0.3, 0.4, 0.5]


def test_playback_interpolates_linearly_and_is_zero_after_the_end(tmp_path):
    rec = read_record(write(tmp_path, "r.csv", "0,0\n0.1,1.0\n0.2,-1.0\n"))
    gm = GroundMotion(rec, scale=0.5)
    ts = np.linspace(0, 0.2, 41)
    expected = 0.5 * G * np.interp(ts, rec.time, rec.accel_g)
    assert [gm.acceleration(t) for t in ts] == pytest.approx(expected, rel=1e-14, abs=1e-14)
    assert gm.acceleration(0.2000001) == 0.0
    assert gm.acceleration(10.0) == 0.0


def test_time_scale_stretches_the_record(tmp_path):
    rec = read_record(write(tmp_path, "r.csv", "0,0\n0.1,1.0\n0.2,0.0\n"))
    gm = GroundMotion(rec, scale=1.0, time_scale=2.0)
    assert gm.acceleration(0.2) == pytest.approx(G)
    assert gm.duration == pytest.approx(0.4)


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("", r"r\.csv: the file is empty"),
        ("0,0\n0.1,abc\n", r"r\.csv:2: not a number"),
        ("0,0\n0.1,0.2\n0.1,0.3\n", r"r\.csv:3: time 0.1 s does not increase"),
        ("0,0\n0.2,0.2\n0.1,0.3\n", r"r\.csv:3: time 0.1 s does not increase"),
        ("0,0,1\n", r"r\.csv:1: expected 2 columns"),
        ("# only comments\n", r"r\.csv: needs at least 2 samples"),
        ("0,0\n0.1,nan\n", r"r\.csv:2: non-finite"),
    ],
)
def test_bad_records_name_file_and_line(tmp_path, text, pattern):
    path = write(tmp_path, "r.csv", text)
    with pytest.raises(RecordError, match=pattern):
        read_record(path)


def test_missing_record(tmp_path):
    with pytest.raises(RecordError, match="no such file"):
        read_record(tmp_path / "nope.csv")


def test_bad_at2_header(tmp_path):
    with pytest.raises(RecordError, match=r"r\.at2:4: header line must give NPTS and DT"):
        read_record(write(tmp_path, "r.at2", "a\nb\nc\nno numbers here\n0.1\n"))


SOURCES = {  # file: (dt, npts, PGA in g) from scenarios/records/SOURCES.md
    "elcentro_1940_ns.csv": (0.02, 2688, 0.3487),
    "hachinohe_1968_ns.csv": (0.01, 3600, 0.2294),
    "northridge_1994_sylmar_ns.csv": (0.02, 3000, 0.8431),
    "kobe_1995_jma_ns.csv": (0.02, 7500, 0.8342),
}


@pytest.mark.parametrize("name", sorted(SOURCES))
def test_shipped_records_match_their_sources(name):
    path = shipped_record(name)
    dt, npts, pga = SOURCES[name]
    rec = read_record(path)
    assert len(rec.time) == npts
    assert np.diff(rec.time) == pytest.approx(np.full(npts - 1, dt), abs=1e-9)
    assert np.max(np.abs(rec.accel_g)) == pytest.approx(pga, abs=5e-5)
    assert re.match(r"^# record:", path.read_text().splitlines()[0])


@pytest.mark.parametrize(("value", "message"), [
    ("1_0", "not a number"), ("0x10", "not a number"), ("inf", "non-finite"), ("1e400", "non-finite")])
def test_only_plain_decimal_numbers_are_read(tmp_path, value, message):
    with pytest.raises(RecordError, match=rf"r\.csv:2: {message}"):
        read_record(write(tmp_path, "r.csv", f"0,0\n0.02,{value}\n"))


def test_plain_decimals_in_every_spelling_are_read(tmp_path):
    rec = read_record(write(tmp_path, "r.csv", "0,0\n.02,+1.5e-3\n0.04,-2.\n"))
    assert rec.time.tolist() == [0.0, 0.02, 0.04] and rec.accel_g.tolist() == [0.0, 0.0015, -2.0]


@pytest.mark.parametrize(("header", "message"), [
    ("NPTS= 3, DT= 1e308", "not finite and increasing"), ("NPTS= 3, DT= 1.2.3", "DT is not a number")])
def test_at2_time_step_must_give_finite_times(tmp_path, header, message):
    with pytest.raises(RecordError, match=message):
        read_record(write(tmp_path, "r.at2", f"a\nb\nc\n{header}\n0.1 0.2 0.3\n"))


def test_special_files_are_not_read(tmp_path):
    import os

    os.mkfifo(tmp_path / "fifo.csv")
    for path in (tmp_path / "fifo.csv", Path("/dev/zero"), tmp_path):
        with pytest.raises(RecordError, match="not a regular file"):
            read_record(path)
