"""The APT / CL reader on the corpus (../shared/corpus/cl, read in place) and on bad and synthetic input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.core.errors import InputError
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.readers.cl.reader import ClFile, ClStream, parse_cl, read_cl
from prs3_post.toolpaths.arcs import arc_segment_count
from prs3_post.toolpaths.cycles import DrillCycle, Pecking, drill_rows

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus" / "cl"
BAD = REPO / "fixtures" / "bad" / "cl"
TOL = 0.002

pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason="../shared/corpus is not there")


def _read(name: str, tolerance: float = TOL) -> ClFile:
    return read_cl(str(CORPUS / name), tolerance=tolerance, circle_tolerance=CIRCLE_TOL)


def _parse(text: str, **kwargs: object) -> ClFile:
    return parse_cl(text, path="t.cls", tolerance=TOL, **({"circle_tolerance": CIRCLE_TOL} | kwargs))  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# Every corpus file reads; the counts below were checked with grep on the files
# (e.g. `grep -c '^GOTO/' f`, `grep -c '^GOTO/.*,.*,.*,.*,.*,' f`, `wc -l f`).
# --------------------------------------------------------------------------------------------
CORPUS_COUNTS = {
    # name: (units, records, gotos, gotos_with_axis, moves, arcs, cycles, cycle_holes, skipped)
    "humman_1_KONTUR_NAR_40_N2.cls": ("mm", 84, 46, 1, 27, 19, 0, 0, (("PAINT", 10), ("TOOL PATH", 1))),
    "humman_4_SVERL_63_N2.cls": ("mm", 249, 89, 0, 91, 0, 0, 0, (("PAINT", 92), ("TOOL PATH", 1))),
    "humman_deep_drill.clsf": ("mm", 14, 2, 1, 0, 0, 1, 2, (("PAINT", 5), ("TOOL PATH", 1))),
    "humman_standart_drill.clsf": ("mm", 14, 2, 1, 0, 0, 1, 2, (("PAINT", 5), ("TOOL PATH", 1))),
    "humman_ust_a_variable_contour.cls": ("mm", 662, 546, 120, 546, 0, 0, 0, (("PAINT", 70), ("TOOL PATH", 1))),
    "mech491_APT_SimpleMillPlane.cls": ("mm", 82, 35, 1, 33, 2, 0, 0,
                                        (("PAINT", 36), ("TOOL PATH", 1), ("Tool Path Listing", 1))),
    "mech491_APT_Variable_Axis.cls": ("inch", 389, 348, 329, 348, 0, 0, 0,
                                      (("PAINT", 31), ("TOOL PATH", 1), ("Tool Path Listing", 1))),
    "mech491_APT_Zig_Zag_Smoothed.cls": ("mm", 163, 75, 1, 40, 35, 0, 0,
                                         (("PAINT", 42), ("TOOL PATH", 1), ("Tool Path Listing", 1))),
}


def test_the_corpus_list_is_complete() -> None:
    assert sorted(p.name for p in CORPUS.iterdir() if p.suffix in (".cls", ".clsf")) == sorted(CORPUS_COUNTS)


@pytest.mark.parametrize("name", sorted(CORPUS_COUNTS))
def test_every_corpus_file_reads_with_exact_counts(name: str) -> None:
    units, records, gotos, with_axis, moves, arcs, cycles, holes, skipped = CORPUS_COUNTS[name]
    cl = _read(name)
    c = cl.counts
    assert (cl.units, c.records, c.gotos, c.gotos_with_axis, c.moves, c.arcs, c.cycles, c.cycle_holes, c.skipped) \
        == (units, records, gotos, with_axis, moves, arcs, cycles, holes, skipped)
    assert sum(count for _, count in c.by_word) == c.records          # every record accounted for once
    assert c.comments == 1                                            # each file has one "$$ centerline data"
    assert c.rows == len(cl.toolpath) == c.moves + c.arc_segments + c.cycle_rows
    tp = cl.toolpath
    assert_allclose(np.linalg.norm(tp.axis, axis=1), 1.0, atol=1e-12)
    assert np.all(np.isfinite(tp.tip))
    assert np.all((tp.feed > 0) == (tp.kind == MoveKind.FEED))
    assert np.all(np.diff(tp.source) >= 0) and tp.source.min() >= 1 and tp.source.max() <= records
    assert [e.text for e in tp.events if e.kind is EventKind.COMMENT] == ["centerline data"]


def test_modal_tool_axis_and_rapid_for_the_next_move_only() -> None:
    """mech491_APT_Variable_Axis: the first GOTO sets i,j,k; the next ones without it keep it."""
    tp = _read("mech491_APT_Variable_Axis.cls").toolpath
    first = np.array([-0.3778015, -0.0069217, 0.9258607])
    first /= np.linalg.norm(first)
    assert_allclose(tp.axis[:10], np.tile(first, (10, 1)), atol=1e-15)          # lines 10 … 25
    assert tp.source[:4].tolist() == [10, 13, 16, 17]
    assert tp.kind[:4].tolist() == [MoveKind.RAPID, MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED]
    assert int(np.sum(tp.kind == MoveKind.RAPID)) == 3                          # 3 RAPID records


def test_inches_implied_by_ipm_are_converted_to_mm() -> None:
    cl = _read("mech491_APT_Variable_Axis.cls")
    tp = cl.toolpath
    # MSYS/3,3,0 (identity axes) in inches; GOTO/-4.2721,-3.0148,3.0000 (line 10)
    assert_allclose(tp.tip[0], np.array([-1.2721, -0.0148, 3.0]) * 25.4, atol=1e-12)
    assert_allclose(cl.frames[0].origin, [76.2, 76.2, 0.0], atol=1e-12)
    assert set(tp.feed[tp.kind == MoveKind.FEED].tolist()) == {254.0}             # FEDRAT/IPM,10


def test_units_given_by_the_caller_override_the_ipm_guess() -> None:
    text = "FEDRAT/IPM,10.0\nGOTO/1.0,2.0,3.0\n"
    as_mm = _parse(text, units="mm")
    assert (as_mm.units, as_mm.toolpath.tip[0].tolist(), as_mm.toolpath.feed[0]) == ("mm", [1.0, 2.0, 3.0], 254.0)
    guessed = _parse(text)
    assert guessed.units == "inch"
    assert_allclose(guessed.toolpath.tip[0], [25.4, 50.8, 76.2], atol=1e-12)


def test_units_record_wins_and_contradictions_are_refused() -> None:
    assert _parse("UNITS/INCHES\nFEDRAT/MMPM,100\nGOTO/1,0,0\n").toolpath.tip[0].tolist() == [25.4, 0.0, 0.0]
    with pytest.raises(InputError) as info:
        _parse("UNITS/MM\nGOTO/1,0,0\n", units="inch")
    assert str(info.value) == ("t.cls:1: the file says UNITS/ mm but inch was asked for: leave the unit out or give "
                               "the file's own")


def test_msys_round_trip_on_the_flipped_frame() -> None:
    """humman_4: MSYS/393,-297.5,3, x=(0,1,0), y=(1,0,0) → z = x × y = (0,0,-1)."""
    cl = _read("humman_4_SVERL_63_N2.cls")
    (frame,) = cl.frames
    assert frame.line == 3
    assert_allclose(frame.rotation, [[0, 1, 0], [1, 0, 0], [0, 0, -1]], atol=0)
    local = np.array([[1558.4057, -837.0281, 418.0]])                   # line 10
    part = frame.to_part(local)
    assert_allclose(part, [[393 - 837.0281, -297.5 + 1558.4057, 3 - 418.0]], atol=1e-9)
    assert_allclose(frame.to_local(part), local, atol=1e-9)
    tp = cl.toolpath
    assert tp.source[:2].tolist() == [8, 10]                             # FROM/, then the GOTO of line 10
    assert_allclose(tp.tip[1], part[0], atol=1e-9)
    assert_allclose(tp.axis, np.tile([0.0, 0.0, -1.0], (len(tp), 1)), atol=0)   # local +z is part -z
    assert tp.kind[0] == MoveKind.RAPID and tp.kind[-1] == MoveKind.RAPID       # FROM/ and GOHOME/
    assert set(tp.feed[tp.kind == MoveKind.FEED].tolist()) == {120.0}


def test_msys_later_in_the_file_reframes_the_current_position() -> None:
    text = ("RAPID\nGOTO/1,2,3,0,0,1\nMSYS/10,0,0,0,1,0,-1,0,0\nFEDRAT/100\nGOTO/0,0,0\n")
    tp = _parse(text).toolpath
    assert_allclose(tp.tip, [[1, 2, 3], [10, 0, 0]], atol=1e-12)
    assert_allclose(tp.axis, [[0, 0, 1], [0, 0, 1]], atol=1e-12)        # the modal axis stays the same direction


# --------------------------------------------------------------------------------------------
# Arcs: the direction convention, from the corpus
# --------------------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@pytest.mark.parametrize(("name", "junctions", "tangent_junctions"), [
    ("mech491_APT_Zig_Zag_Smoothed.cls", 68, 67), ("humman_1_KONTUR_NAR_40_N2.cls", 38, 34),
    ("mech491_APT_SimpleMillPlane.cls", 4, 2),
])
def test_arcs_run_clockwise_about_their_axis_tangent_to_their_neighbours(name: str, junctions: int,
                                                                        tangent_junctions: int) -> None:
    """Where a move meets an arc along (or against) the arc's tangent, the expanded arc continues the
    move: the first chord leaves in the incoming direction, the next move leaves the last chord's way.
    Reading the direction the other way round turns every one of these junctions into a reversal.
    The other junctions are corners (plunges onto an arc, the 55° corners of humman_1), and none of
    them reverses either."""
    tp = _read(name, tolerance=1e-4).toolpath
    arc_lines = {int(line) for line in np.unique(tp.source) if (tp.source == line).sum() > 1}
    tip = tp.tip
    cosines = []
    for line in sorted(arc_lines):
        rows = np.flatnonzero(tp.source == line)
        first, last = rows[0], rows[-1] + 1                  # + 1: the end GOTO's row
        if first >= 2:
            cosines.append(float(_unit(tip[first] - tip[first - 1]) @ _unit(tip[first - 1] - tip[first - 2])))
        if last + 1 < len(tip):
            cosines.append(float(_unit(tip[last + 1] - tip[last]) @ _unit(tip[last] - tip[last - 1])))
    cosines_arr = np.array(cosines)
    tangent = np.abs(cosines_arr) > math.cos(0.05)           # within 3° either way (chords of 1e-4 mm sagitta)
    assert (len(cosines_arr), int(tangent.sum())) == (junctions, tangent_junctions)
    assert np.all(cosines_arr[tangent] > math.cos(0.05))
    assert np.all(cosines_arr > -1e-9)


def test_arc_rows_lie_on_the_circle_and_end_on_the_goto() -> None:
    tp = _read("mech491_APT_SimpleMillPlane.cls").toolpath
    rows = np.flatnonzero(tp.source == 14)                  # CIRCLE/-265,172.4997,100,0,0,-1,7.5 ; GOTO line 15
    assert tp.source[rows[-1] + 1] == 15
    arc = tp.tip[np.r_[rows[0] - 1, rows, rows[-1] + 1]]     # from the start point (the GOTO of line 13)
    assert_allclose(np.linalg.norm(arc[:, :2] - [-265.0, 172.4997], axis=1), 7.5, atol=1e-9)
    assert_allclose(arc[-1], [-265.0, 164.9997, 100.0], atol=0)
    # clockwise about (0,0,-1) = counter-clockwise seen from +z: from the left of the centre to below it
    # the short way round is a quarter turn through angles 180° → 270°
    angle = np.degrees(np.arctan2(arc[:, 1] - 172.4997, arc[:, 0] + 265.0)) % 360
    assert angle[0] == pytest.approx(180.0) and np.all(np.diff(angle[:-1]) > 0) and angle[-2] < 270


def test_an_arc_end_equal_to_its_start_is_a_full_circle() -> None:
    text = "FEDRAT/MMPM,100\nGOTO/10,0,0,0,0,1\nCIRCLE/0,0,0,0,0,1,10\nGOTO/10,0,0\n"
    cl = _parse(text)
    # sagitta 10·(1 − cos(Δ/2)) ≤ 0.002 → Δ ≤ 0.04 rad → 2π / 0.04 → 158 segments
    assert cl.counts.arcs == 1 and cl.counts.arc_segments == arc_segment_count(10.0, 2 * math.pi, tolerance=TOL) == 158
    assert_allclose(np.linalg.norm(cl.toolpath.tip[:, :2], axis=1), 10.0, atol=1e-9)


# --------------------------------------------------------------------------------------------
# Cycles, events, records
# --------------------------------------------------------------------------------------------
def test_drill_cycle_from_the_corpus() -> None:
    """CYCLE/DRILL,RAPTO,3,FEDTO,0,MMPM,250 on two holes at z=240, axis +z."""
    cl = _read("humman_standart_drill.clsf")
    (cycle,) = cl.cycles
    assert (cycle.line, cycle.holes, cycle.cycle) == (7, 2, DrillCycle(depth=0.0, clearance=3.0, retract=3.0,
                                                                       feed=250.0))
    tp = cl.toolpath
    assert_allclose(tp.tip, [[66, 0, 243], [66, 0, 240], [66, 0, 243], [-255, 0, 243], [-255, 0, 240],
                             [-255, 0, 243]], atol=0)
    assert tp.kind.tolist() == [0, 1, 0, 0, 1, 0]
    assert tp.source.tolist() == [9, 9, 9, 10, 10, 10]
    assert tp.feed.tolist() == [0, 250, 0, 0, 250, 0]


def test_peck_cycle_with_step_dwell_and_retract() -> None:
    text = ("SPINDL/RPM,1000,CLW\nCYCLE/DRILL,DEEP,FEDTO,-5,RAPTO,2,RTRCTO,10,STEP,2,DWELL,0.5,MMPR,0.1\n"
            "GOTO/0,0,0,0,0,1\nCYCLE/OFF\n")
    cl = _parse(text)
    assert cl.cycles[0].cycle == DrillCycle(depth=5.0, clearance=2.0, retract=10.0, feed=100.0,
                                            pecking=Pecking.FULL_RETRACT, peck=2.0, dwell=0.5)
    assert cl.toolpath.tip[:, 2].tolist() == [2, -2, 2, -1.5, -4, 2, -3.5, -5, 10]
    dwell = [e for e in cl.toolpath.events if e.kind is EventKind.DWELL]
    assert [(e.before, e.value) for e in dwell] == [(8, 0.5)]


def test_chip_break_pattern_along_a_tilted_axis() -> None:
    axis = _unit(np.array([[1.0, 0.0, 1.0]]))
    tip, kind, bottom = drill_rows(np.array([[5.0, 0, 0]]), axis,
                                   DrillCycle(depth=3, clearance=1, retract=4, feed=50, pecking=Pecking.CHIP_BREAK,
                                              peck=1.5, gap=0.25))
    heights = (tip - [5.0, 0, 0]) @ axis[0]
    assert_allclose(heights, [1, -1.5, -1.25, -3, 4], atol=1e-12)
    assert (kind.tolist(), bottom.tolist()) == ([0, 1, 0, 1, 0], [3])


def test_events_spindle_coolant_tools_comments_stops() -> None:
    text = ("TLDATA/MILL,10.0000,0.0000,50.0000,0.0000,0.0000\nLOADTL/3\nSPINDL/RPM,1200,CCLW\n"
            "COOLNT/MIST\nPPRINT/ROUGH, THEN FINISH\nRAPID\nGOTO/0,0,10 $$ above\nSTOP\nOPSTOP\nCOOLNT/OFF\n"
            "SPINDL/OFF\nSELECT/TOOL,4\nLOAD/TOOL,4\nFINI\n")
    tp = _parse(text).toolpath
    shown = [(e.before, e.kind.value, e.value, e.text) for e in tp.events]
    assert shown == [
        (0, "tool_change", 3.0, "tool 3: TLDATA/MILL,10.0000,0.0000,50.0000,0.0000,0.0000"),
        (0, "spindle_on_ccw", 1200.0, ""), (0, "coolant_on", 0.0, "mist"),
        (0, "comment", 0.0, "ROUGH, THEN FINISH"), (0, "comment", 0.0, "above"), (1, "stop", 0.0, ""),
        (1, "optional_stop", 0.0, ""),
        (1, "coolant_off", 0.0, ""), (1, "spindle_off", 0.0, ""),
        (1, "tool_change", 4.0, "tool 4: TLDATA/MILL,10.0000,0.0000,50.0000,0.0000,0.0000"),
    ]


@pytest.mark.parametrize("chunk_lines", [1, 2, 10_000])
def test_continuation_lines_and_exponents(chunk_lines: int) -> None:
    text = "FEDRAT/$\nMMPM,$\n1.5E+02\nGOTO/1.0E+01,$\n-2,3\nPPRINT/NEXT: $\nGOTO/0,0,0\n"
    cl = _parse(text, chunk_lines=chunk_lines)
    assert cl.toolpath.tip.tolist() == [[10.0, -2.0, 3.0]] and cl.toolpath.feed.tolist() == [150.0]
    assert cl.toolpath.source.tolist() == [4] and cl.counts.records == 3
    assert [e.text for e in cl.toolpath.events] == ["NEXT: GOTO/0,0,0"]      # a continued comment, not a move


def test_feed_unit_after_the_value_and_per_revolution() -> None:
    cl = _parse("SPINDL/2000\nFEDRAT/0.05,MMPR\nGOTO/1,0,0\nFEDRAT/20,IPM\nGOTO/2,0,0\n", units="mm")
    assert cl.toolpath.feed.tolist() == [100.0, 508.0]


def test_ignored_words_are_skipped_and_counted() -> None:
    cl = _parse("CUTCOM/LEFT\nRAPID\nGOTO/0,0,0\nCUTCOM/OFF\n", ignore=frozenset({"cutcom"}))
    assert cl.counts.skipped == (("CUTCOM", 2),) and len(cl.toolpath) == 1
    with pytest.raises(InputError) as info:
        _parse("GOTO/0,0,0\n", ignore=frozenset({"GOTO", "PAINT"}))
    assert str(info.value) == ("t.cls: cannot ignore GOTO, PAINT: the reader understands them (only unknown major "
                               "words can be ignored)")


@pytest.mark.parametrize("name", sorted(p.name for p in BAD.glob("*.cls")))
def test_bad_cl_files_give_their_exact_message(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)
    path = f"fixtures/bad/cl/{name}"
    first = (REPO / path).read_text().splitlines()[0]
    assert first.startswith("$$ expect: ")
    with pytest.raises(InputError) as info:
        read_cl(path, tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == first.removeprefix("$$ expect: ")
    assert info.value.exit_code == 2


def test_not_text_and_empty_files_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)
    with pytest.raises(InputError) as info:
        read_cl("fixtures/bad/cube.stl", tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == "fixtures/bad/cube.stl: not a CL file: binary data (byte 0x00 at offset 0)"
    with pytest.raises(InputError) as info:
        _parse("\n  \n")
    assert str(info.value) == "t.cls: not a CL file: no records (the file is empty)"


def test_rapid_is_used_up_by_the_next_motion_record_even_inside_a_cycle() -> None:
    text = ("FEDRAT/MMPM,100\nCYCLE/DRILL,RAPTO,1,FEDTO,2\nRAPID\nGOTO/0,0,0\nCYCLE/OFF\nGOTO/5,0,0\n")
    tp = _parse(text).toolpath
    assert tp.kind.tolist() == [MoveKind.RAPID, MoveKind.FEED, MoveKind.RAPID, MoveKind.FEED]
    assert tp.feed.tolist() == [0.0, 100.0, 0.0, 100.0]


def test_tlaxis_sets_the_modal_axis_and_multax_off_refuses_ijk() -> None:
    tp = _parse("TLAXIS/0,0.6,0.8\nRAPID\nGOTO/0,0,0\n").toolpath
    assert tp.axis.tolist() == [[0.0, 0.6, 0.8]]
    with pytest.raises(InputError) as info:
        _parse("MULTAX/OFF\nRAPID\nGOTO/0,0,0,0,0,1\n")
    assert str(info.value) == "t.cls:3: GOTO/ with i,j,k under MULTAX/OFF: give x,y,z only, or MULTAX/ON first"


def test_deep_cycle_without_step_drills_in_one_feed() -> None:
    """humman_deep_drill: CYCLE/DRILL,DEEP with no STEP has no peck depth: one feed per hole."""
    (cycle,) = _read("humman_deep_drill.clsf").cycles
    assert cycle.words == ("DRILL", "DEEP", "RAPTO", "3.0000", "FEDTO", "0.0000", "MMPM", "250.0000")
    assert cycle.cycle.pecking is Pecking.NONE


# --------------------------------------------------------------------------------------------
# Streaming and the bulk path
# --------------------------------------------------------------------------------------------
def _same(a: ClFile, b: ClFile) -> None:
    for name in ("kind", "tip", "axis", "feed", "source"):
        assert np.array_equal(getattr(a.toolpath, name), getattr(b.toolpath, name)), name
    assert a.toolpath.events == b.toolpath.events
    assert (a.counts, a.units, a.end_lines, a.cycles) == (b.counts, b.units, b.end_lines, b.cycles)


@pytest.mark.parametrize("name", sorted(CORPUS_COUNTS))
def test_chunks_of_1_7_and_10000_lines_read_the_same_rows(name: str) -> None:
    text = (CORPUS / name).read_text()
    whole = _read(name)
    for lines in (1, 7, 10_000):
        _same(parse_cl(text, path=str(CORPUS / name), tolerance=TOL, chunk_lines=lines,
                       circle_tolerance=CIRCLE_TOL), whole)


@pytest.mark.parametrize("name", ["mech491_APT_Variable_Axis.cls", "humman_ust_a_variable_contour.cls",
                                  "humman_1_KONTUR_NAR_40_N2.cls", "humman_4_SVERL_63_N2.cls"])
def test_the_bulk_path_reads_exactly_what_the_record_path_reads(name: str) -> None:
    """A space after GOTO/ sends every GOTO through the record-by-record path."""
    text = (CORPUS / name).read_text()
    slow = parse_cl(text.replace("GOTO/", "GOTO/ "), path=name, tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    _same(slow, parse_cl(text, path=name, tolerance=TOL, circle_tolerance=CIRCLE_TOL))


def test_stream_chunks_count_events_from_their_own_start(tmp_path: Path) -> None:
    path = tmp_path / "s.cls"
    path.write_text("FEDRAT/MMPM,100\nGOTO/0,0,0\nPPRINT/A\nGOTO/1,0,0\nGOTO/2,0,0\nPPRINT/B\nGOTO/3,0,0\n")
    stream = ClStream(str(path), tolerance=TOL, chunk_lines=3, piece_bytes=5, circle_tolerance=CIRCLE_TOL)
    chunks = list(stream)
    assert [c.source.tolist() for c in chunks] == [[2], [4, 5], [7]]
    assert [[(e.before, e.text) for e in c.events] for c in chunks] == [[(1, "A")], [(2, "B")], []]
    assert stream.summary is not None and stream.summary.counts.rows == 4


def test_the_unit_is_found_in_a_feed_record_continued_across_pieces(tmp_path: Path) -> None:
    path = tmp_path / "u.cls"
    path.write_text("RAPID\nGOTO/1,0,0\nFEDRAT/$\nIPM,$\n10\nGOTO/2,0,0\n")
    for piece_bytes in (3, 16, 1 << 20):
        cl = ClStream(str(path), tolerance=TOL, piece_bytes=piece_bytes, circle_tolerance=CIRCLE_TOL).whole()
        assert (cl.units, cl.toolpath.tip[:, 0].tolist(), cl.toolpath.feed.tolist()) == ("inch", [25.4, 50.8],
                                                                                        [0.0, 254.0])


def test_without_msys_the_points_stay_as_written() -> None:
    """humman_4 drills along local +z, which the flipped MSYS turns into part -z (from below): read as
    written, it is a plain drilling program from above."""
    cl = read_cl(str(CORPUS / "humman_4_SVERL_63_N2.cls"), tolerance=TOL, apply_msys=False, circle_tolerance=CIRCLE_TOL)
    tp = cl.toolpath
    assert cl.frames[0].line == 3                                    # still recorded
    assert_allclose(tp.tip[1], [1558.4057, -837.0281, 418.0], atol=0)
    assert np.array_equal(tp.axis, np.tile([0.0, 0.0, 1.0], (len(tp), 1)))
    applied = _read("humman_4_SVERL_63_N2.cls").toolpath
    assert_allclose(cl.frames[0].to_part(tp.tip), applied.tip, atol=1e-9)


@pytest.mark.parametrize(("text", "message"), [
    ("FEDRAT/100\nGOTO/0,0,0\nCIRCLE/0,0,0,0,0,1,0.005\nGOTO/0.005,0,0\n",
     "t.cls:4: arc start point lies on the axis of CIRCLE/ at line 3, where an arc has no direction; start and end "
     "must lie on the circle"),
    ("FEDRAT/100\nGOTO/1e6,0,0\nCIRCLE/0,0,0,0,0,1,1e6\nGOTO/0,1e6,0\n",
     "t.cls:4: the arc of CIRCLE/ at line 3 (radius 1e+06) needs 166,609 segments within 0.0001 mm, more than "
     "100,000: the circle is far larger than any part"),
    ("FEDRAT/100\nGOTO/1e9,0,0\nCIRCLE/0,0,0,0,0,1,1e9\nGOTO/0,1e9,0\n",
     "t.cls:2: GOTO/ value 1: '1e9' is out of range (allowed: within ±1e+06 mm; is the file in the right units?)"),
])
def test_degenerate_arcs_are_input_errors(text: str, message: str) -> None:
    with pytest.raises(InputError) as info:
        parse_cl(text, path="t.cls", tolerance=0.0001, circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == message


@pytest.mark.parametrize("speed", ["1e30", "1000001"])
def test_a_spindle_speed_beyond_any_spindle_is_an_input_error(speed: str) -> None:
    """SPINDL/ is bounded as the command line's --spindle is (it was emitted as S1000000000000000019884624838656)."""
    with pytest.raises(InputError) as info:
        parse_cl(f"SPINDL/RPM,{speed},CLW\nFEDRAT/100\nGOTO/0,0,0\n", path="t.cls", tolerance=0.0001,
                 circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == f"t.cls:1: SPINDL/ speed {speed} is more than 1e+06 rpm (allowed: 1 to 1e+06 rpm)"


def test_a_spindle_speed_that_prints_as_zero_is_an_input_error() -> None:
    """SPINDL/RPM,0.001 was a limit error (exit 1) in the emitter: "spindle_on event before row 0 ..."."""
    with pytest.raises(InputError) as info:
        parse_cl("SPINDL/RPM,0.001,CLW\nFEDRAT/100\nGOTO/0,0,0\n", path="t.cls", tolerance=0.0001,
                 circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == "t.cls:1: SPINDL/ speed 0.001 is less than 1 rpm (allowed: 1 to 1e+06 rpm)"



@pytest.mark.parametrize(("name", "origin", "rows"), [
    ("mech491_APT_Zig_Zag_Smoothed.cls", (-76.5, -80.8, -683.0), 729),
    ("mech491_APT_Variable_Axis.cls", (-68.5, -76.1, -716.2), 1338),     # 348 GOTOs, axis changes subdivided
    ("humman_standart_drill.clsf", (94.5, 0.0, -883.0), 6),
])
def test_corpus_toolpaths_post_process_and_replay_onto_the_cl_points(name: str, origin: tuple[float, float, float],
                                                                   rows: int) -> None:
    """The reader's rows go through the main pipeline as they are: every CL row is a program row, and
    FK of the program's joints lands on the intended tips and axes (before output rounding)."""
    from prs3_post.kinematics import forward
    from prs3_post.machine.loading import load_machine
    from prs3_post.part.setup_transform import Setup
    from prs3_post.post.pipeline import post_process

    machine, setup = load_machine("patel2020"), Setup(origin)
    cl = _read(name)
    post = post_process(machine, cl.toolpath, setup, tolerance=TOL, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert len(post.program) == rows
    fk = forward(machine.geometry, post.program.strokes, post.program.stage)
    assert_allclose(fk.tip, post.path.tip, atol=1e-9)
    assert_allclose(fk.axis, post.path.axis, atol=1e-12)
    want = setup.points_to_machine(cl.toolpath.tip)
    gap = np.linalg.norm(post.path.tip[:, None, :] - want[None, :, :], axis=2).min(axis=0)
    assert gap.max() == 0.0                                              # every CL row is there, exactly


def test_a_toolpath_past_the_tilt_limit_fails_at_its_first_bad_row_before_any_subdivision() -> None:
    """humman_ust_a tilts its tool up to 86° (the machine allows 45°) and spans 800 mm in y (the stage
    300 mm): post-processing names the first row outside a limit at once, where it used to bisect
    the moves through the singularity for minutes first; no part origin is offered (the tilt does
    not depend on where the part is), and automatic placement says the tilt cannot be kept."""
    from prs3_post.check.placement import place, suggest_origin
    from prs3_post.core.errors import LimitError
    from prs3_post.machine.loading import load_machine
    from prs3_post.part.setup_transform import Setup
    from prs3_post.post.pipeline import post_process

    name = "humman_ust_a_variable_contour.cls"
    machine = load_machine("patel2020")
    setup = Setup.resolve(machine)
    path = _read(name).toolpath
    with pytest.raises(LimitError) as caught:
        post_process(machine, path, setup, tolerance=TOL, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == (f"{CORPUS / name}:11: stage Y -1396.5000 mm is below the minimum -300.0000 mm by "
                                 "1096.5000 mm (546 points outside limits in all)")
    assert suggest_origin(machine, path, setup, tolerance=TOL, angle_tolerance=DEFAULT_ANGLE_TOLERANCE) is None
    # automatic placement evaluates the rows as given (no subdivision: no setup can run them)
    with pytest.raises(LimitError) as caught:
        place(machine, path, tolerance=TOL, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    where = f"{CORPUS / name}:261"
    clauses = str(caught.value).split("; ")
    assert clauses[0].startswith("no part origin and rotation about z puts every point inside the machine's limits: ")
    assert (f"the tilt is outside too, by 41.3459 deg there ({where}: tilt 86.3459 deg is above the maximum "
            "45.0000 deg by 41.3459 deg)") in clauses


def test_subdividing_a_move_through_the_singularity_stops_at_the_row_cap_naming_the_move() -> None:
    """The same file's move to line 177 turns the axis from 80.3° to 78.5° tilt, past the singularity:
    its joint-space line never comes within tolerance, and bisection stops (after 9 rounds, where the
    round limit alone would allow 16,000 rows per move) when the move would need more than its cap."""
    from dataclasses import replace

    from prs3_post.core.errors import LimitError
    from prs3_post.machine.loading import load_machine
    from prs3_post.part.setup_transform import Setup
    from prs3_post.post.linearize import MAX_INSERTED, subdivide_axis_changes
    from prs3_post.post.pipeline import place_toolpath

    name = "humman_ust_a_variable_contour.cls"
    machine = load_machine("patel2020")
    path = _read(name).toolpath
    placed = place_toolpath(path.take(path.source <= 177), Setup.resolve(machine))
    placed = replace(placed, axis=placed.axis / np.linalg.norm(placed.axis, axis=1, keepdims=True))
    with pytest.raises(LimitError) as caught:
        subdivide_axis_changes(machine.geometry, placed, tolerance=TOL, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert MAX_INSERTED == 1000
    assert str(caught.value) == (f"{CORPUS / name}:177: the joint-space move to this point would need more than 1000 "
                                 "inserted points: it still strays 134.6 mm / 42.32 deg from the intended one after 9 "
                                 "rounds of bisection (allowed: 0.002 mm, 0.01 deg); the tool axis may pass a "
                                 "singularity")


def test_plain_gotos_read_in_bulk_are_the_lines_the_pattern_matches():
    """The byte pass reads exactly the plain GOTO lines of at most 15 digits a number, each value
    float(text) to the bit; the rest (longer numbers, spaces, a second CR, 4 numbers) are left to the pattern."""
    from prs3_post.readers.cl.bulk import _PLAIN_GOTO, _plain_gotos

    lines = ["GOTO/1,-2.5,+.5", "GOTO/1.,2,3,0,0,1\r", "GOTO/-0,0.000,5,-0.6,0,0.8", "GOTO/1,2,3,4",
             "GOTO/1,2,3\r\r", "GOTO /1,2,3", "GOTO/1,2,-.", "GOTO/1.5.2,2,3", "FEDRAT/MMPM,600",
             "GOTO/1,2,1234567890123456", "GOTO/1,2,123456789012345", ""]
    values, read = _plain_gotos(lines)
    assert read.tolist() == [True, True, True, False, False, False, False, False, False, False, True, False]
    assert [_PLAIN_GOTO.match(line) is not None for line in lines][:10] == [True, True, True, False, False,
                                                                              False, False, False, False, True]
    expected = [[1, -2.5, 0.5], [1, 2, 3, 0, 0, 1], [-0.0, 0, 5, -0.6, 0, 0.8], [1, 2, 123456789012345]]
    for row, want in zip(values[read], expected, strict=True):
        want = np.array(want + [np.nan] * (6 - len(want)))
        np.testing.assert_array_equal(row, want)
        np.testing.assert_array_equal(np.signbit(row), np.signbit(want))
    assert np.isnan(values[~read]).all()


def test_a_goto_of_long_numbers_reads_as_one_of_short_ones():
    """A plain GOTO whose numbers have more than 15 digits goes through the pattern: the same rows."""
    head = "MULTAX\nFEDRAT/MMPM,600\nGOTO/0,0,0,0,0,1\n"
    long = parse_cl(head + "GOTO/1.0000000000000000,2,3,0.6000000000000000,0,0.8\n", path="a.cls", tolerance=0.002,
                    circle_tolerance=CIRCLE_TOL)
    short = parse_cl(head + "GOTO/1,2,3,0.6,0,0.8\n", path="a.cls", tolerance=0.002, circle_tolerance=CIRCLE_TOL)
    np.testing.assert_array_equal(long.toolpath.tip, short.toolpath.tip)
    np.testing.assert_array_equal(long.toolpath.axis, short.toolpath.axis)
    np.testing.assert_array_equal(long.toolpath.tip[-1], [1.0, 2.0, 3.0])


def test_repeated_fedrat_lines_keep_the_first_line_of_each_feed_unit():
    """The unit pre-pass leaves out FEDRAT/ lines that repeat one read before: the ambiguity names the
    first line of each unit all the same."""
    text = ("FEDRAT/MMPM,600\nGOTO/0,0,0\nFEDRAT/MMPM,600\nFEDRAT/IPM,20\nGOTO/1,0,0\nFEDRAT/IPM,20\n"
            "FEDRAT/MMPM,600\nGOTO/2,0,0\n")
    with pytest.raises(InputError) as caught:
        parse_cl(text, path="both.cls", tolerance=0.002, circle_tolerance=CIRCLE_TOL)
    assert str(caught.value) == ("both.cls: feeds in both MMPM/MMPR (line 1) and IPM/IPR (line 4) and no UNITS/ "
                                 "record: the length unit of the file is ambiguous; give it (mm or inch)")


def _runs_with_marks(gotos: int) -> str:
    """GOTO runs with plain PPRINT and FEDRAT lines among them (repeated, changed, per revolution), as
    CAM systems write them between passes."""
    lines = ["SPINDL/RPM,1000,CLW", "RAPID", "GOTO/0,0,5", "FEDRAT/MMPM,600.0000"]
    for i in range(gotos):
        lines.append(f"GOTO/{i % 13}.5,{-(i % 7)},{-(i % 3)}.25")
        if i % 9 == 4:
            lines.append(f"PPRINT/  pass {i} ")
        if i % 17 == 8:
            feeds = ("FEDRAT/MMPM,600.0000", "FEDRAT/500,MMPM", "FEDRAT/MMPR,0.2", "FEDRAT/MMPM,600.0000\r")
            lines.append(feeds[i % 4])
        if i % 23 == 0:
            lines.append("PPRINT/")
    return "\n".join(lines) + "\nPPRINT/last\nEND-OF-PATH\n"


@pytest.mark.parametrize("chunk_lines", [1, 7, 10_000])
def test_pprint_and_fedrat_lines_in_a_run_read_as_records_read_them(chunk_lines: int) -> None:
    """Plain PPRINT and FEDRAT lines among bulk GOTOs (the PPRINTs together, a FEDRAT read before taken
    again): the rows, feeds, events and counts of the record-by-record path (a space after GOTO/)."""
    text = _runs_with_marks(300)
    bulk = parse_cl(text, path="t.cls", tolerance=TOL, chunk_lines=chunk_lines, circle_tolerance=CIRCLE_TOL)
    _same(parse_cl(text.replace("GOTO/", "GOTO/ "), path="t.cls", tolerance=TOL, circle_tolerance=CIRCLE_TOL), bulk)
    comments = [(e.before, e.text) for e in bulk.toolpath.events if e.kind is EventKind.COMMENT]
    assert (len(comments), comments[:3], comments[-1]) == (48, [(2, ""), (6, "pass 4"), (15, "pass 13")], (301, "last"))
    assert sorted(set(bulk.toolpath.feed.tolist())) == [0.0, 200.0, 500.0, 600.0]
    assert dict(bulk.counts.by_word)["FEDRAT"] == 1 + 18


@pytest.mark.parametrize(("extra", "line", "message"), [
    ("FEDRAT/MMPM,0", 10, "FEDRAT/ must be > 0, got 0"),
    ("PPRINT/" + "x" * 70_000, 10, "a record of 70,007 characters or more: longer than any CL record may be (65,536 "
     "at most); found 'PPRINT/xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx...'"),
])
def test_a_bad_mark_in_a_run_is_refused_where_it_stands(extra: str, line: int, message: str) -> None:
    text = "RAPID\nGOTO/0,0,5\nFEDRAT/MMPM,600\n" + "".join(f"GOTO/{i},0,0\nPPRINT/p{i}\n" for i in range(3)) + (
        extra + "\nGOTO/9,0,0\nFEDRAT/MMPM,0\n")
    for careful in (False, True):
        with pytest.raises(InputError) as info:
            parse_cl(text.replace("GOTO/", "GOTO/ ") if careful else text, path="t.cls", tolerance=TOL,
                     circle_tolerance=CIRCLE_TOL)
        assert str(info.value) == f"t.cls:{line}: {message}"
