"""The calibration measurement CSV: what it reads, and each refusal with its file and line."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from prs3_post.core.errors import InputError
from prs3_post.readers.measurements import read_measurements


def _read(tmp_path, text: str):
    path = tmp_path / "meas.csv"
    path.write_text(text, encoding="utf-8")
    return read_measurements(str(path)), str(path)


def test_reads_tips_axes_stage_and_tool_lengths(tmp_path):
    m, path = _read(tmp_path, "t1,t2,t3,x,y,px,py,pz,ax,ay,az,tool_length_mm\n"
                              "10,20,30,1,2,-80,20,-680,0,0,1.005,175\n"
                              "\n"
                              "11,21,31,0,0,-81,21,-681,0.6,0,0.8,\n")
    assert m.path == path and m.has_axis
    assert m.line.tolist() == [2, 4]
    assert_allclose(m.strokes, [[10, 20, 30], [11, 21, 31]], atol=0)
    assert_allclose(m.stage, [[1, 2], [0, 0]], atol=0)
    assert_allclose(m.tip, [[-80, 20, -680], [-81, 21, -681]], atol=0)
    assert_allclose(m.axis, [[0, 0, 1], [0.6, 0, 0.8]], atol=1e-15)      # normalized
    assert m.tool_length[0] == 175.0 and np.isnan(m.tool_length[1])      # empty: the machine's


def test_columns_in_any_order_and_no_stage_or_axis(tmp_path):
    m, _ = _read(tmp_path, "px,py,pz,t3,t2,t1\n1,2,3,30,20,10\n")
    assert not m.has_axis
    assert_allclose(m.strokes, [[10, 20, 30]], atol=0)
    assert_allclose(m.stage, [[0, 0]], atol=0)
    assert np.isnan(m.axis).all()


def test_axis_columns_empty_on_every_line_mean_not_measured(tmp_path):
    m, _ = _read(tmp_path, "t1,t2,t3,x,y,px,py,pz,ax,ay,az\n1,2,3,0,0,4,5,6,,,\n")
    assert not m.has_axis


@pytest.mark.parametrize(("text", "line", "message"), [
    ("", 1, "expected a header naming the columns (t1,t2,t3,x,y,px,py,pz,ax,ay,az,tool_length_mm), got an empty line"),
    ("t1,t2,t3,px,py,pz,q\n", 1, "unknown column 'q' (columns: t1,t2,t3,x,y,px,py,pz,ax,ay,az,tool_length_mm; "
                                 "required: t1,t2,t3,px,py,pz)"),
    ("t1,t2,t3,px,py,pz,t1\n", 1, "column t1 appears twice"),
    ("t1,t2,px,py,pz\n", 1, "missing column t3 (required: t1,t2,t3,px,py,pz)"),
    ("t1,t2,t3,x,px,py,pz\n", 1, "columns x,y go together: the header has only x"),
    ("t1,t2,t3,px,py,pz\n", 1, "no measured poses: the file has a header and no rows"),
    ("t1,t2,t3,px,py,pz\n1,2,3,4,5\n", 2, "expected 6 values (t1,t2,t3,px,py,pz), got 5"),
    ("t1,t2,t3,px,py,pz\n1,2,3,4,5,nan\n", 2, "pz is not a number: 'nan'"),
    ("t1,t2,t3,px,py,pz\n1,2,3,4,5,1e9\n", 2, "pz = 1e+09 is out of range (allowed: within ±1e+06)"),
    ("t1,t2,t3,px,py,pz\n1,2,3,4,5,6\n1,2,3,4,,6\n", 3,
     "py is empty: fill in the measured tool tip (px, py, pz) of this pose"),
    ("t1,t2,t3,px,py,pz\n1,,3,4,5,6\n", 2,
     "t2 is empty: every row needs the commanded strokes (t1, t2, t3) and the stage (x, y) it was measured at"),
    ("t1,t2,t3,px,py,pz,ax,ay,az\n1,2,3,4,5,6,0,,1\n", 2,
     "ay empty: give the whole measured axis (ax, ay, az) or none of it"),
    ("t1,t2,t3,px,py,pz,ax,ay,az\n1,2,3,4,5,6,0,0,1\n1,2,3,4,5,6,,,\n", 3,
     "the tool axis (ax, ay, az) is empty here but given on other lines: measure it on every line or on none"),
    ("t1,t2,t3,px,py,pz,ax,ay,az\n1,2,3,4,5,6,0,0,0.5\n", 2,
     "the measured axis (0, 0, 0.5) has length 0.5 and z 0.5: expected a unit vector (length within 0.02 of 1) "
     "pointing from the tip toward the spindle (az > 0)"),
    ("t1,t2,t3,px,py,pz,tool_length_mm\n1,2,3,4,5,6,-175\n", 2, "tool_length_mm must be > 0, got -175"),
])
def test_refusals_name_the_file_and_line(tmp_path, text, line, message):
    with pytest.raises(InputError) as caught:
        _read(tmp_path, text)
    assert str(caught.value) == f"{tmp_path / 'meas.csv'}:{line}: {message}"


def test_a_missing_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_measurements(str(tmp_path / "nothing.csv"))
