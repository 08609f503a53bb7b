"""check/timeline.py: every limit over program time with its bounds, the boundaries, the worst margin,
and a decimation that keeps every extreme."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from prs3_post.app.preview import program_marks
from prs3_post.app.verify import open_program, tool_lengths_of, verify_loaded
from prs3_post.check.timeline import Mark, MarkKind, timeline_of
from prs3_post.check.verify import row_times

GOLDEN = Path(__file__).resolve().parents[2] / "fixtures" / "golden"


def _replayed(name: str):
    context = open_program(str(GOLDEN / name))
    report = verify_loaded(context.program, context.machine, context.setup, context.dialect, tolerance=0.002,
                           tool_lengths=tool_lengths_of(context.header))
    return context, report


@pytest.fixture(scope="module")
def demo():
    """The demo's hole (the paper's case 2a): one operation, one tool."""
    context, report = _replayed("wedge-hole-case2a.ngc")
    return context, report, timeline_of(report, marks=program_marks(context.program, context.header, context.dialect))


@pytest.fixture(scope="module")
def job():
    """The two-face example job: a drill (T1) on face 5, a round (T2) on face 6."""
    context, report = _replayed("twofaces-job-example.ngc")
    return context, report, timeline_of(report, marks=program_marks(context.program, context.header, context.dialect))


def test_strokes_are_the_program_words_with_the_machines_stroke_range(demo):
    """T1 runs over the U words of the demo's program (27.2803..40.6968 mm) within the stroke limits -100..400 mm."""
    context, _, timeline = demo
    t1 = timeline.get("T1 stroke")
    assert (t1.group, t1.unit, t1.low, t1.high) == ("stroke", "mm", -100.0, 400.0)
    assert (float(t1.values.min()), float(t1.values.max())) == (27.2803, 40.6968)
    assert [s.name for s in timeline.group("stroke")] == ["T1 stroke", "T2 stroke", "T3 stroke"]
    assert [s.name for s in timeline.group("stage")] == ["stage X", "stage Y"]
    assert timeline.get("stage X").high == context.machine.stage.travel_x[1] == 300.0
    assert timeline.groups == ("stroke", "link angle", "tilt", "condition number", "stage", "stage speed",
                               "stroke speed")


def test_angles_are_kept_in_radians_and_shown_in_degrees(demo):
    """The wedge's face is inclined 26.5651°: the drilling tilt; the limit is the machine's 45° maximum."""
    _, _, timeline = demo
    tilt = timeline.get("tilt")
    values, low, high = tilt.shown()
    assert tilt.unit == "deg" and low == -math.inf and high == pytest.approx(45.0)
    assert float(np.nanmax(values)) == pytest.approx(26.5651, abs=1e-3)
    link = timeline.get("θ1 link angle")
    assert link.shown()[1:] == (pytest.approx(30.0), pytest.approx(85.0))


def test_each_sample_is_at_its_moves_time(demo):
    """Samples are placed linearly along each move between its start and end time, in order."""
    _, report, timeline = demo
    start, end = row_times(report.program, rapid_rate=timeline.rapid_rate, dynamics=report.dynamics)
    rep = report.samples_kept
    assert_allclose(timeline.time, start[rep.row] + rep.fraction * (end[rep.row] - start[rep.row]))
    assert np.all(np.diff(timeline.time) >= 0)
    assert timeline.dynamics and timeline.time[-1] == pytest.approx(0.082, abs=5e-4)   # the header's cycle time
    assert timeline.line[0] == 24 and timeline.line[-1] == 29


def test_the_jobs_tool_changes_and_operations_are_at_their_lines(job):
    """T1 M6 on line 27 and T2 M6 on line 60; the operations' titles on lines 25 and 58, before rows 0 and 23."""
    context, _, timeline = job
    tools = [(b.row, b.line, b.label) for b in timeline.boundaries if b.kind is MarkKind.TOOL_CHANGE]
    assert tools == [(0, 27, "T1 D6.000 mm tool"), (23, 60, "T2 D8.000 mm tool")]
    operations = [(b.row, b.line) for b in timeline.boundaries if b.kind is MarkKind.OPERATION]
    assert operations == [(0, 25), (23, 58)]
    assert timeline.operations == ("drill 2 holes D6.000 on face 5",
                                   "round D20.000 mm at [u 0.000, v 0.000] with tool D8.000 on face 6")
    second = next(b for b in timeline.boundaries if b.line == 60)
    assert second.time == pytest.approx(timeline.time[timeline.row == 22].max())   # when the round's first move starts
    assert set(timeline.operation[timeline.row < 23].tolist()) == {0}
    assert set(timeline.operation[timeline.row >= 23].tolist()) == {1}
    assert context.program.lines[59] == "T2 M6"


def test_without_marks_each_tool_change_event_begins_an_operation(job):
    _, report, _ = job
    timeline = timeline_of(report)
    assert [(b.row, b.line, b.kind.value, b.label) for b in timeline.boundaries] == [
        (0, 31, "tool change", "T1"), (0, 31, "operation", "T1"),
        (23, 63, "tool change", "T2"), (23, 63, "operation", "T2")]
    assert timeline.operations == ("T1", "T2")


def test_the_worst_margin_is_the_closest_approach_of_the_report(job):
    """Its limit and line are those of the report's smallest fraction of range."""
    _, report, timeline = job
    worst = min(report.closest, key=lambda c: c.fraction_of_range)
    assert timeline.worst_series == worst.name == "stage X"
    assert timeline.line[timeline.worst] == worst.line == 57
    assert timeline.get("stage X").values[timeline.worst] == pytest.approx(worst.value)


def test_speeds_are_each_axis_feed_and_rapids_at_the_top_speed(demo):
    """A G1's axis speed is |Δq|·F; the rapids' slowest axis reaches [dynamics]' top speed or its triangle's peak."""
    context, _, timeline = demo
    moves = context.program.moves
    feed_row = int(np.flatnonzero(moves.kind == 1)[0])
    speed = timeline.get("T1 speed")
    at = timeline.row == feed_row
    expected = abs(moves.strokes[feed_row, 0] - moves.strokes[feed_row - 1, 0]) * moves.inverse_time[feed_row]
    assert_allclose(speed.values[at], expected)
    assert (speed.low, speed.high) == (0.0, 5000.0)
    assert float(speed.values.max()) <= 5000.0 + 1e-9
    assert timeline.get("stage X speed").high == 10000.0


def test_decimation_keeps_every_extreme_boundary_and_the_worst_sample(job):
    _, _, timeline = job
    small = timeline.decimate(200)
    assert len(small) <= 200 < len(timeline) == 1852
    assert small.kept[0] == 0 and small.kept[-1] == len(timeline) - 1
    for full, kept in zip(timeline.series, small.series, strict=True):
        assert np.nanmin(kept.values) == np.nanmin(full.values) and np.nanmax(kept.values) == np.nanmax(full.values)
        assert_allclose(kept.values, full.values[small.kept])
    assert small.kept[small.worst] == timeline.worst and small.worst_series == timeline.worst_series
    assert_allclose(small.time, timeline.time[small.kept])
    for boundary in timeline.boundaries:                 # both sides of each boundary stay
        first = int(np.searchsorted(timeline.row, boundary.row))
        assert first in small.kept and (first == 0 or first - 1 in small.kept)
    assert timeline.decimate(len(timeline)) is timeline


def test_decimation_of_a_long_series_keeps_each_buckets_extremes():
    """A million samples to 2,000: the spike at sample 777,777 survives, and so does every bucket's low and high."""
    _, report = _replayed("wedge-hole-case2a.ngc")
    timeline = timeline_of(report)
    n = 1_000_000
    values = np.sin(np.arange(n) / 5000.0)
    values[777_777] = 3.0
    long = dataclasses.replace(
        timeline, time=np.arange(n) / n, row=np.zeros(n, dtype=np.int64), kept=np.arange(n), worst=-1,
        boundaries=(), series=(dataclasses.replace(timeline.series[0], values=values),))
    small = long.decimate(2000)
    assert len(small) <= 2000
    assert 777_777 in small.kept and float(small.series[0].values.max()) == 3.0
    assert float(small.series[0].values.min()) == float(values.min())


def test_marks_given_are_placed_in_time(demo):
    _, report, _ = demo
    timeline = timeline_of(report, marks=[Mark(row=3, line=27, kind=MarkKind.OPERATION, label="second")])
    start, _ = row_times(report.program, rapid_rate=timeline.rapid_rate, dynamics=report.dynamics)
    assert timeline.boundaries[0].time == start[3]
    assert timeline.operations == ("second",)
    assert timeline.row_operation.tolist() == [0, 0, 0, 0, 0]
