"""The streaming pipeline: a toolpath fed in chunks gives the program of the whole, byte for byte.

One synthetic toolpath (a two thousand rows: feeds whose tool axis turns, rapids, events of every
kind, and steps smaller than the program can show) is converted whole (``post_process`` +
``emit_program``) and in chunks of 1, 7 and 10,000 rows (``program_text``, and through the atomic
writer); every chunking must give the same bytes. Errors name the input file and line.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from prs3_post.app.streaming import program_text
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import LimitError, ReachError
from prs3_post.core.output_files import write_atomic
from prs3_post.core.toolpath import Event, EventKind, MoveKind, Toolpath
from prs3_post.emit.gcode import emit_program
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.pipeline import PostStream, post_process

MACHINE = load_machine("patel2020")
DIALECT = load_dialect("linuxcnc")
SETUP = Setup((-100.0, -200.0, -970.0))                 # the wedge's setup: tips near z = -680 mm
CL = "parts/bracket.cl"


def synthetic(rows: int = 2000, seed: int = 8) -> Toolpath:
    """A part-frame toolpath around (0, 200, 290) mm: runs of feeds whose axis wanders up to ~25°
    off vertical, a rapid every 40 rows, repeated and sub-resolution steps, and events."""
    rng = np.random.default_rng(seed)
    tip = np.zeros((rows, 3))
    axis = np.zeros((rows, 3))
    kind = np.full(rows, int(MoveKind.FEED))
    position = np.array([0.0, 200.0, 290.0])
    tilt, azimuth = 0.2, 0.0
    for i in range(rows):
        if i % 40 == 0:
            kind[i] = MoveKind.RAPID
            position = np.array([0.0, 200.0, 290.0]) + rng.uniform(-30, 30, 3) * [1, 1, 0.3]
        elif i % 13 == 5:
            position = position + rng.uniform(-2e-5, 2e-5, 3)          # below the output's resolution
        elif i % 17 == 3:
            pass                                                   # a repeated point (an axis turn in place)
        else:
            position = position + rng.uniform(-1.5, 1.5, 3)
        position = np.clip(position, [-35, 165, 280], [35, 235, 300])
        if i % 3 == 0 and i % 13 != 5:
            tilt = float(np.clip(tilt + rng.uniform(-0.03, 0.03), 0.0, 0.45))
            azimuth += float(rng.uniform(-0.2, 0.2))
        tip[i] = position
        axis[i] = [math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)]
    # a feed that only turns the axis in place has zero length: make those rapids
    same = np.r_[False, np.all(tip[1:] == tip[:-1], axis=1)]
    kind[same] = MoveKind.RAPID
    feed = np.where(kind == MoveKind.FEED, rng.uniform(100, 1500, rows), 0.0)
    events = [Event(0, EventKind.COMMENT, text="synthetic (streamed)"), Event(0, EventKind.TOOL_CHANGE, 3, "tool 3"),
              Event(0, EventKind.SPINDLE_ON, 12000.0), Event(0, EventKind.COOLANT_ON)]
    for before in range(7, rows, 61):
        events.append(Event(before, EventKind.COMMENT, text=f"before row {before}"))
    for before in range(100, rows, 250):
        events += [Event(before, EventKind.DWELL, 0.5), Event(before, EventKind.STOP)]
    events += [Event(rows, EventKind.COOLANT_OFF), Event(rows, EventKind.SPINDLE_OFF)]
    return Toolpath(kind=kind, tip=tip, axis=axis, feed=feed, source=np.arange(rows) * 2 + 10,
                    events=tuple(events), source_file=CL)


def chunked(path: Toolpath, size: int, *, boundary_events_late: bool = True) -> list[Toolpath]:
    """``path`` cut every ``size`` rows (plus two empty chunks); an event at a cut goes to the chunk
    after it (``before == 0``) or, with ``boundary_events_late=False``, to the end of the one before."""
    out = []
    n = len(path)
    for lo in range(0, n, size):
        hi = min(n, lo + size)
        keep = np.zeros(n, dtype=bool)
        keep[lo:hi] = True
        take = (lambda b, lo=lo, hi=hi: lo <= b < hi or (b == hi == n)) if boundary_events_late else (
            lambda b, lo=lo, hi=hi: lo < b <= hi or (b == lo == 0))
        events = tuple(Event(e.before - lo, e.kind, e.value, e.text) for e in path.events if take(e.before))
        out.append(Toolpath(kind=path.kind[lo:hi], tip=path.tip[lo:hi], axis=path.axis[lo:hi],
                            feed=path.feed[lo:hi], source=path.source[lo:hi], events=events,
                            source_file=path.source_file))
        if lo == size:                                  # an empty chunk in the middle changes nothing
            out.append(Toolpath(kind=np.zeros(0, dtype=np.int64), tip=np.zeros((0, 3)), axis=np.zeros((0, 3)),
                                feed=np.zeros(0), source=np.zeros(0, dtype=np.int64), source_file=path.source_file))
    assert sum(len(c) for c in out) == n and sum(len(c.events) for c in out) == len(path.events)
    return out


def whole_program(path: Toolpath) -> str:
    result = post_process(MACHINE, path, SETUP, length_decimals=DIALECT.decimals.length,
                          tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    return emit_program(result.program, DIALECT, header=(("source", CL),))


@pytest.fixture(scope="module")
def path() -> Toolpath:
    return synthetic()


@pytest.fixture(scope="module")
def whole(path: Toolpath) -> str:
    return whole_program(path)


def test_the_synthetic_path_exercises_every_carried_state(path: Toolpath, whole: str):
    stream = PostStream(MACHINE, SETUP, length_decimals=DIALECT.decimals.length)
    text = "".join(program_text(MACHINE, [path], SETUP, DIALECT, header=(("source", CL),), stream=stream,
                                tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
    assert text == whole
    counts = stream.finish()
    assert counts.input_rows == 2000
    assert counts.inserted > 100                         # axis-changing feeds were subdivided
    assert counts.dropped > 100                          # sub-resolution steps were dropped
    assert counts.program_rows == 2000 + counts.inserted - counts.dropped
    assert counts.tip_before > 0.01 and 0.0 < counts.tip_after <= 0.002      # the default tolerances
    assert counts.angle_before > counts.angle_after and counts.angle_after <= np.radians(0.01)
    lines = whole.splitlines()
    assert lines.count("G93") == 1 and lines.count("M0") == 8 and lines.count("T3 M6") == 1


@pytest.mark.parametrize(("size", "late"), [(7, True), (10_000, True), (10_000, False)])
def test_chunks_of_any_size_give_the_same_bytes(path: Toolpath, whole: str, size: int, late: bool):
    pieces = list(program_text(MACHINE, chunked(path, size, boundary_events_late=late), SETUP, DIALECT,
                               header=(("source", CL),),
                               tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
    assert len(pieces) == len(chunked(path, size)) + 2                # begin, one per chunk, end
    assert "".join(pieces) == whole


@pytest.mark.parametrize("late", [True, False])
def test_chunks_of_one_row_give_the_same_bytes(late: bool):
    """One row a chunk costs a few ms a row, so on the path's first 500 rows (two stops, a tool
    change, dwells, subdivided and dropped rows among them)."""
    path = synthetic(500)
    text = "".join(program_text(MACHINE, chunked(path, 1, boundary_events_late=late), SETUP, DIALECT,
                                header=(("source", CL),),
                                tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
    assert text == whole_program(path)


def test_chunks_of_random_sizes_give_the_same_bytes(path: Toolpath, whole: str):
    """Random cuts; the events at a cut come in a chunk of their own, with no rows (as a reader
    yields a chunk of lines that holds only a comment or an M code)."""
    rng = np.random.default_rng(3)
    at_events = [e.before for e in path.events][::2]
    cuts = np.unique(np.r_[0, np.cumsum(rng.integers(1, 60, 200)), at_events, len(path)].clip(0, len(path)))
    pieces = []
    for lo, hi in itertools.pairwise(cuts):
        pieces.append(Toolpath(kind=np.zeros(0, dtype=np.int64), tip=np.zeros((0, 3)), axis=np.zeros((0, 3)),
                               feed=np.zeros(0), source=np.zeros(0, dtype=np.int64), source_file=CL,
                               events=tuple(Event(0, e.kind, e.value, e.text) for e in path.events
                                            if e.before == lo)))
        events = tuple(Event(e.before - lo, e.kind, e.value, e.text) for e in path.events
                       if lo < e.before < hi or e.before == hi == len(path))
        pieces.append(Toolpath(kind=path.kind[lo:hi], tip=path.tip[lo:hi], axis=path.axis[lo:hi],
                               feed=path.feed[lo:hi], source=path.source[lo:hi], events=events, source_file=CL))
    assert sum(len(p.events) for p in pieces) == len(path.events)
    assert sum(1 for p in pieces if not len(p) and p.events) > 10
    assert "".join(program_text(MACHINE, pieces, SETUP, DIALECT, header=(("source", CL),),
                                tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)) == whole


def test_the_atomic_writer_takes_the_chunks(path: Toolpath, whole: str, tmp_path: Path):
    out = tmp_path / "streamed.ngc"
    write_atomic(str(out), program_text(MACHINE, chunked(path, 300), SETUP, DIALECT, header=(("source", CL),),
                                        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
    assert out.read_bytes() == whole.encode("ascii")


def test_a_failing_chunk_leaves_no_file(path: Toolpath, tmp_path: Path):
    """A point out of reach in a later chunk: the error names the CL file and line; no output is left."""
    tip = path.tip.copy()
    tip[1500] += [0.0, 0.0, 600.0]                       # 600 mm higher: beyond the strokes
    bad = Toolpath(kind=path.kind, tip=tip, axis=path.axis, feed=path.feed, source=path.source,
                   events=path.events, source_file=CL)
    out = tmp_path / "bad.ngc"
    with pytest.raises((LimitError, ReachError)) as caught:
        write_atomic(str(out), program_text(MACHINE, chunked(bad, 1000), SETUP, DIALECT,
                                            tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
    assert str(caught.value).startswith(f"{CL}:{1500 * 2 + 10}: ")
    assert list(tmp_path.iterdir()) == []


def test_limit_and_reach_errors_name_the_file_and_line():
    axis = np.tile([0.0, 0.0, 1.0], (3, 1))
    tips = np.array([[0.0, 200.0, 290.0], [0.0, 200.0, 280.0], [0.0, 200.0, 890.0]])
    path = Toolpath(kind=[0, 1, 0], tip=tips, axis=axis, feed=[0, 100, 0], source=[4, 5, 9], source_file=CL)
    with pytest.raises(LimitError) as caught:
        post_process(MACHINE, path, SETUP, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == f"{CL}:9: T1 stroke -524.4730 mm is below the minimum -100.0000 mm by 424.4730 mm"
    stream = PostStream(MACHINE, SETUP)
    stream.feed(Toolpath(kind=[0, 1], tip=tips[:2], axis=axis[:2], feed=[0, 100], source=[4, 5], source_file=CL))
    with pytest.raises(LimitError) as caught:
        stream.feed(Toolpath(kind=[0, 0], tip=tips[[2, 2]] + [[0, 0, 0], [0, 0, 1]], axis=axis[:2], feed=[0, 0],
                             source=[9, 10], source_file=CL))
    assert str(caught.value) == (f"{CL}:9: T1 stroke -524.4730 mm is below the minimum -100.0000 mm by 424.4730 mm "
                                 "(2 points outside limits among the 4 checked so far)")
    with pytest.raises(RuntimeError):
        stream.feed(path)
    tilted = np.tile([0.6, 0.0, 0.8], (2, 1))                     # the head alone cannot put a tilted tip here
    with pytest.raises(ReachError) as caught:
        post_process(load_machine("patel2020-head"), Toolpath(kind=[0, 1], tip=tips[:2], axis=tilted, feed=[0, 100],
                                                              source=[4, 5], source_file=CL), SETUP,
        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value).startswith(f"{CL}:4: machine patel2020-head has no stage and its head alone misses")


def test_a_first_feed_in_a_later_chunk_starts_where_the_last_chunk_ended():
    axis = np.tile([0.0, 0.0, 1.0], (2, 1))
    stream = PostStream(MACHINE, SETUP)
    stream.feed(Toolpath(kind=[0], tip=[[0.0, 200.0, 290.0]], axis=axis[:1], feed=[0], source=[1], source_file=CL))
    second = stream.feed(Toolpath(kind=[1], tip=[[3.0, 204.0, 290.0]], axis=axis[:1], feed=[500], source=[2],
                                  source_file=CL))
    assert second.program.inverse_time.tolist() == [100.0]        # 500 mm/min over 5 mm
    with pytest.raises(LimitError) as caught:
        PostStream(MACHINE, SETUP).feed(Toolpath(kind=[1], tip=[[3.0, 204.0, 290.0]], axis=axis[:1], feed=[500],
                                                 source=[2], source_file=CL))
    assert str(caught.value) == f"{CL}:2: the program starts with a feed move; its start point is unknown"


@pytest.mark.parametrize("size", [1, 2, 3, 50])
def test_the_resolution_guard_keeps_the_same_rows_in_chunks(size: int):
    """A walk of steps around half an output unit: rows dropped in runs, the reference being the
    last row kept, and a row that is a long step from a dropped row but a short one from the last
    kept row (kept: only short steps are looked at)."""
    from prs3_post.core.rowwise import row_lengths
    from prs3_post.post.visible_moves import VisibleMoves, visible_moves

    rng = np.random.default_rng(size)
    steps = rng.uniform(-6e-5, 6e-5, (400, 3)) * (rng.random((400, 1)) < 0.9)
    steps[::37] = 0.2                                   # now and then a real move
    tip = np.cumsum(steps, axis=0)
    axis = np.tile([0.0, 0.0, 1.0], (400, 1))
    joints = tip @ np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.2], [0.1, 0.0, 1.0]])
    whole = visible_moves(joints, 4, tip=tip, axis=axis)
    assert 50 < int((~whole).sum()) < 350
    guard = VisibleMoves(4)
    pieces = [guard.keep(joints[lo:lo + size], tip=tip[lo:lo + size], axis=axis[lo:lo + size])
              for lo in range(0, 400, size)]
    assert np.concatenate(pieces).tolist() == whole.tolist()
    guard = VisibleMoves(4)                             # given each chunk's step lengths (the stream's way)
    pieces = [guard.keep(joints[lo:lo + size], tip=tip[lo:lo + size], axis=axis[lo:lo + size],
                         steps=row_lengths(np.diff(tip[lo:lo + size], axis=0))) for lo in range(0, 400, size)]
    assert np.concatenate(pieces).tolist() == whole.tolist()


def test_a_long_step_from_a_dropped_row_is_kept_across_chunks():
    from prs3_post.post.visible_moves import VisibleMoves, visible_moves

    tip = np.array([[0.0, 0, 0], [0.00004, 0, 0], [-0.00002, 0, 0]])   # near = 0.00005 mm
    axis = np.tile([0.0, 0.0, 1.0], (3, 1))
    joints = np.array([[0.0], [0.0001], [0.0002]])
    assert visible_moves(joints, 4, tip=tip, axis=axis).tolist() == [True, False, True]
    guard = VisibleMoves(4)
    assert [guard.keep(joints[i:i + 1], tip=tip[i:i + 1], axis=axis[i:i + 1]).tolist() for i in range(3)] == [
        [True], [False], [True]]


@pytest.mark.parametrize(("name", "text"), [
    ("job.cls", "RAPID\nGOTO/0,200,300,0,0,1\nFEDRAT/MMPM,100\nGOTO/0,200,290\nGOTO/0,200,890\nFINI\n"),
    ("job.nc", "G21 G90\nG0 X0 Y200 Z300\nG1 Z290 F100\nM0\nG1 Z890\nM2\n"),
])
def test_a_cam_file_streamed_names_its_line_in_a_limit_error(name: str, text: str):
    """CL and 3+2 G-code rows keep their file and line through the stream: the error names line 5."""
    from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE
    from prs3_post.readers.cl.reader import ClStream
    from prs3_post.readers.gcode.reader import GcodeStream

    reader = ClStream if name.endswith(".cls") else GcodeStream
    stream = PostStream(MACHINE, SETUP, length_decimals=4)
    with pytest.raises(LimitError) as caught:
        for chunk in reader(name, tolerance=0.002, text=text, chunk_lines=1, circle_tolerance=DEFAULT_CIRCLE_TOLERANCE):
            stream.feed(chunk)
    assert str(caught.value) == f"{name}:5: T1 stroke -524.4730 mm is below the minimum -100.0000 mm by 424.4730 mm"


@pytest.mark.parametrize("size", [1, 7, 61, 5000])
def test_toolpath_pieces_are_the_chunks_owning_their_rows(path: Toolpath, size: int):
    # the main job cuts its toolpath into pieces that own their rows and drops each once posted
    from prs3_post.core.toolpath import toolpath_chunks, toolpath_pieces

    names = ("kind", "tip", "axis", "feed", "source")
    columns = {name: getattr(path, name).copy() for name in names}
    pieces = toolpath_pieces(columns, size, events=path.events, source_file=CL)
    chunks = list(toolpath_chunks(path, size))
    assert columns == {} and len(pieces) == len(chunks) == math.ceil(len(path) / (size))
    for piece, chunk in zip(pieces, chunks, strict=True):
        for name in names:
            np.testing.assert_array_equal(getattr(piece, name), getattr(chunk, name))
            assert getattr(piece, name).base is None and not getattr(piece, name).flags.writeable   # owned, frozen
        assert piece.events == chunk.events and piece.source_file == CL
    empty = toolpath_pieces({name: getattr(path, name)[:0] for name in names}, 7)
    assert len(empty) == 1 and len(empty[0]) == 0 and empty[0].tip.shape == (0, 3)
