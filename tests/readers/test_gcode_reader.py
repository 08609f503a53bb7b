"""The 3+2 G-code reader: G68.2 planes, work planes, arcs, cycles, the accounting, exact errors, the corpus refused."""

from __future__ import annotations

import math
import random
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from prs3_post.app.work_plane import work_plane_from_text
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.core.errors import FeatureError, InputError
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.part.faces import find_faces, select_face
from prs3_post.part.stl import load_part
from prs3_post.part.workplane import WorkPlane, WorkPlaneError, euler_zxz_deg, rotate_rows
from prs3_post.readers.detect import detect_format
from prs3_post.readers.gcode.reader import PECK_GAP_MM, GcodeFile, GcodeStream, parse_gcode, read_gcode

REPO = Path(__file__).resolve().parents[2]
PROGRAMS = REPO / "fixtures" / "gcode"
CORPUS = REPO.parent / "shared" / "corpus"
RS274_CHECK = REPO.parent / "shared" / "tools" / "rs274-check"
TOL = 0.002
R, F = int(MoveKind.RAPID), int(MoveKind.FEED)
S30, C30 = 0.5, math.sqrt(3.0) / 2.0


def _parse(text: str, **kwargs: object) -> GcodeFile:
    return parse_gcode(text, path="t.ngc", tolerance=TOL, **({"circle_tolerance": CIRCLE_TOL} | kwargs))  # type: ignore[arg-type]


def _segments(radius: float, sweep: float) -> int:
    """Equal segments of an arc whose sagitta r(1 − cos(Δ/2)) stays within TOL, at most a quarter turn each."""
    return max(math.ceil(sweep / (2.0 * math.acos(1.0 - TOL / radius))), math.ceil(sweep / (math.pi / 2)))


# --------------------------------------------------------------------------------------------
# G68.2: FANUC's Euler angles Z-X'-Z'' (FANUC Series 30i Descriptions B-63942EN/02 §5.44)
# --------------------------------------------------------------------------------------------
def test_euler_angles_of_g68_2_are_z_x_z_intrinsic() -> None:
    """I J K rotate about z, the new x, the new z: columns x, y, z written out from Rz(I)·Rx(J)·Rz(K)."""
    assert_allclose(euler_zxz_deg(0, 30, 0), [[1, 0, 0], [0, C30, -S30], [0, S30, C30]], atol=1e-15)
    i, j, k = (math.radians(a) for a in (40.0, 25.0, -70.0))
    si, ci, sj, cj, sk, ck = math.sin(i), math.cos(i), math.sin(j), math.cos(j), math.sin(k), math.cos(k)
    x = [ci * ck - si * cj * sk, si * ck + ci * cj * sk, sj * sk]
    y = [-ci * sk - si * cj * ck, -si * sk + ci * cj * ck, sj * ck]
    z = [si * sj, -ci * sj, cj]
    assert_allclose(euler_zxz_deg(40, 25, -70), np.column_stack([x, y, z]), atol=1e-15)


def test_g68_2_program_with_a_g83_peck_cycle_and_a_g2_arc_in_g18() -> None:
    """fixtures/gcode/g68-peck-arc.ngc, row by row: the plane I90 J30 K0 has x = (0, 1, 0),
    y = (−cos 30°, 0, sin 30°), z = (sin 30°, 0, cos 30°) (Rz(90°)·Rx(30°), multiplied out by hand)."""
    f = read_gcode(str(PROGRAMS / "g68-peck-arc.ngc"), tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    rotation = np.array([[0.0, -C30, S30], [1.0, 0.0, 0.0], [0.0, S30, C30]])
    origin = np.array([20.0, 10.0, 5.0])
    gap = 2 - 4 + PECK_GAP_MM                          # the rapid back stops 0.254 mm above the last depth

    def pecks(x: float, y: float) -> list[tuple[int, list[float]]]:     # after the rapid to R
        zs = [(F, -2), (R, 2), (R, gap), (F, -6), (R, 2), (R, gap - 4), (F, -10), (R, 2), (R, gap - 8), (F, -12),
              (R, 2)]
        return [(kind, [x, y, z]) for kind, z in zs]

    local = [(R, [0, 0, 20]), (R, [5, -5, 20]), (R, [5, -5, 2]), *pecks(5, -5), (R, [-5, 5, 2]), *pecks(-5, 5),
             (R, [10, 0, 12]), (F, [10, 0, 10])]
    n = _segments(10.0, math.pi)
    theta = np.arange(1, n + 1) * math.pi / n          # G2 in G18: clockwise seen from +Y, through z = 0
    arc = np.column_stack([20 - 10 * np.cos(theta), np.zeros(n), 10 - 10 * np.sin(theta)])
    local += [(F, p) for p in arc.tolist()] + [(R, [30, 0, 20])]
    tip_local = np.array([p for _, p in local])
    tp = f.toolpath
    assert tp.kind.tolist() == [R] + [k for k, _ in local]
    assert_allclose(tp.tip[0], [0, 0, 100], atol=1e-12)
    assert_allclose(tp.tip[1:], origin + tip_local @ rotation.T, atol=1e-9)
    assert_allclose(tp.axis, [[0, 0, 1]] + [[S30, 0, C30]] * len(local), atol=1e-15)
    feeds = [0.0] + [{R: 0.0, F: 150.0}[k] for k, _ in local[:26]] + [0.0, 300.0] + [300.0] * n + [0.0]
    assert_allclose(tp.feed, feeds, atol=0)
    assert tp.source.tolist() == [7, 10] + [11] * 13 + [12] * 12 + [14, 15] + [16] * n + [18]
    assert f.counts.arcs == 1 and f.counts.arc_segments == n == 79
    assert (f.counts.cycles, f.counts.cycle_holes, f.counts.cycle_rows, f.counts.moves) == (1, 2, 25, 5)
    assert (f.counts.records, f.counts.lines, f.counts.rows, f.counts.planes, f.counts.comments) == (20, 23, 109, 1, 1)
    assert f.counts.skipped == (("%", 2),) and (f.counts.comment_lines, f.counts.blank_lines) == (1, 0)
    assert [(p.line, p.words) for p in f.planes] == [(8, "G68.2 X20 Y10 Z5 I90 J30 K0")]
    assert [(c.line, c.code, c.holes) for c in f.cycles] == [(11, "G83", 2)]
    assert [(e.before, e.kind, e.value, e.text) for e in tp.events] == [
        (0, EventKind.COMMENT, 0.0, "3+2 program: a G68.2 tilted plane, a G83 peck cycle and a G2 arc in G18"),
        (0, EventKind.TOOL_CHANGE, 1.0, "tool 1"), (0, EventKind.SPINDLE_ON, 6000.0, ""),
        (0, EventKind.COOLANT_ON, 0.0, "flood"), (109, EventKind.COOLANT_OFF, 0.0, ""),
        (109, EventKind.SPINDLE_OFF, 0.0, "")]
    assert (f.units, f.end_lines) == ("mm", (22,))


def test_g68_2_two_vector_form_and_the_same_plane_by_euler_angles() -> None:
    """P3: Q1 origin and x direction, Q2 the normal; the x direction a hair off square is squared."""
    body = "G0 X1 Y2 Z3\nG1 X4 F100\nG69\nM30\n"
    p3 = _parse("G0 X0 Y0 Z50\nG68.2 P3 Q1 X20 Y10 Z5 I0 J1.0004 K0\nG68.2 P3 Q2 I.5 J0 K.8660254\nG53.1\n" + body)
    p0 = _parse("G0 X0 Y0 Z50\nG68.2 X20 Y10 Z5 I90 J30 K0 Q313\nG53.1\n" + body)
    assert_allclose(p3.toolpath.tip, p0.toolpath.tip, atol=1e-6)
    assert_allclose(p3.toolpath.axis, p0.toolpath.axis, atol=1e-7)
    assert p3.planes[0].line == 3
    assert p3.planes[0].words == "G68.2 P3 Q1 X20 Y10 Z5 I0 J1.0004 K0; G68.2 P3 Q2 I.5 J0 K.8660254"


def test_the_g68_2_origin_is_absolute_under_g91_and_in_program_units() -> None:
    f = _parse("G20 G91\nG68.2 X1 Y0 Z0 I0 J0 K90\nG53.1\nG90 G0 X1 Y0 Z0\nM30\n")
    assert_allclose(f.toolpath.tip, [[25.4, 25.4, 0]], atol=1e-12)     # K90: the plane's x is the part's +y


def test_the_position_is_kept_across_plane_changes_and_the_axis_follows_the_plane() -> None:
    f = _parse("G0 X0 Y0 Z10\nG68.2 X0 Y0 Z0 I0 J90 K0\nG53.1\nG91 G0 Z5\nG69\nG0 X1\nM30\n")
    # J90: the plane's z is (0, −1, 0): Z+5 there goes to −y; after G69 the axis is +z again
    assert_allclose(f.toolpath.tip, [[0, 0, 10], [0, -5, 10], [1, -5, 10]], atol=1e-12)
    assert_allclose(f.toolpath.axis, [[0, 0, 1], [0, -1, 0], [0, 0, 1]], atol=1e-15)


# --------------------------------------------------------------------------------------------
# Work planes: a 3-axis program on a face of the part, or on numbers
# --------------------------------------------------------------------------------------------
def test_3_axis_program_on_the_wedge_face_work_plane() -> None:
    """The wedge's top face (z = 300 − x/2, centroid (0, 200, 300)): u = (cos β, 0, −sin β) down the
    slope, v = (0, 1, 0), w = (sin β, 0, cos β), β = atan(1/2)."""
    face, _ = select_face(find_faces(load_part(str(REPO / "fixtures" / "parts" / "wedge.stl"))), None)
    plane = WorkPlane.from_face(face, name="face 4 of wedge.stl")
    f = read_gcode(str(PROGRAMS / "wedge-face-3axis.ngc"), tolerance=TOL, work_plane=plane, circle_tolerance=CIRCLE_TOL)
    sb, cb = 1 / math.sqrt(5), 2 / math.sqrt(5)
    u, v, w, origin = np.array([cb, 0, -sb]), np.array([0.0, 1, 0]), np.array([sb, 0, cb]), np.array([0.0, 200, 300])
    n = _segments(20.0, math.pi / 2)
    theta = np.arange(1, n + 1) * (math.pi / 2) / n    # G3 R20 from (20, 0) to (0, 20): centre (0, 0)
    local = np.vstack([[[0, 0, 10], [0, 0, -1], [20, 0, -1]],
                       np.column_stack([20 * np.cos(theta), 20 * np.sin(theta), np.full(n, -1.0)]),
                       [[-20, 20, -1], [-20, -20, -1], [-20, -20, 10],
                        [10, 10, 10], [10, 10, 1], [10, 10, -3], [10, 10, 10]]])     # G81, G98: back to Z10
    expected = origin + local[:, :1] * u + local[:, 1:2] * v + local[:, 2:] * w
    assert_allclose(f.toolpath.tip, expected, atol=1e-9)
    assert_allclose(f.toolpath.axis, np.tile(w, (len(local), 1)), atol=1e-15)
    assert f.toolpath.kind.tolist() == [R, F, F] + [F] * n + [F, F, R, R, R, F, R]
    assert f.toolpath.source.tolist() == [6, 7, 8] + [9] * n + [10, 11, 12, 13, 13, 13, 13]
    assert f.work_plane.name == "face 4 of wedge.stl"


def test_work_plane_from_numbers() -> None:
    plane = WorkPlane.from_values([1, 2, 3, 0, 0, 2])
    assert_allclose(plane.rotation, np.eye(3), atol=0)
    assert plane.name == "work plane 1,2,3,0,0,2"
    tilted = WorkPlane.from_values([0, 0, 0, 0, -1, 1, 2, 0, 0])
    s = 1 / math.sqrt(2)
    assert_allclose(tilted.rotation, [[1, 0, 0], [0, s, -s], [0, s, s]], atol=1e-15)
    # without an x direction, the face frame's: u down the slope
    assert_allclose(WorkPlane.from_values([0, 0, 0, 3, 0, 4]).rotation[:, 0], [0.8, 0, -0.6], atol=1e-15)


def test_rotated_rows_are_the_same_bits_in_any_chunk() -> None:
    """The frames of both CAM readers turn rows element by element: a row's bits do not depend on its chunk."""
    rng = np.random.default_rng(7)
    rows = rng.uniform(-500, 500, (5000, 3))
    rotation = euler_zxz_deg(37.1, 23.9, -61.3)
    whole = rotate_rows(rows, rotation)
    assert all(np.array_equal(rotate_rows(rows[i:i + 7], rotation), whole[i:i + 7]) for i in range(0, 5000, 7))
    assert np.array_equal(rotate_rows(rows[1234], rotation)[0], whole[1234])
    assert_allclose(whole, rows @ rotation.T, atol=1e-12)


def test_work_plane_from_text_a_part_and_face_or_numbers() -> None:
    wedge = str(REPO / "fixtures" / "parts" / "wedge.stl")
    auto, note = work_plane_from_text(wedge)
    chosen, _ = work_plane_from_text(f"{wedge}:4")
    sb, cb = 1 / math.sqrt(5), 2 / math.sqrt(5)
    for plane in (auto, chosen):
        assert_allclose(plane.rotation, [[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]], atol=1e-12)
        assert_allclose(plane.origin, [0, 200, 300], atol=1e-9)
        assert plane.name == "face 4 of wedge.stl"
    assert note.startswith("auto: face 4 is the largest upward-facing inclined face")
    numbers, said = work_plane_from_text("1,2,3,0,0,1,0,1,0")
    assert_allclose(numbers.rotation, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=0)
    assert said == "work plane 1,2,3,0,0,1,0,1,0: origin (1, 2, 3) mm, normal (0, 0, 1)"
    with pytest.raises(FeatureError, match="face 5 does not face up"):
        work_plane_from_text(f"{wedge}:5")
    with pytest.raises(InputError, match="file not found"):
        work_plane_from_text("nowhere.stl:2")


@pytest.mark.parametrize(("values", "message"), [
    ([0, 0, 0, 0, 0, 0], "work plane: the normal (0, 0, 0) is not a direction (it must be a non-zero vector, the "
                         "tool axis from the tip toward the spindle)"),
    ([0, 0, 0, 0, 0, 1, 1, 0, 0.1], "work plane: the x direction (1, 0, 0.1) is at 84.289° to the normal (0, 0, 1); "
                                    "it must be perpendicular to it (90° within 0.06°)"),
    ([0, 0, 0, 0, 0, 1, 0, 0, 0], "work plane: the x direction (0, 0, 0) is not a direction (it must be a non-zero "
                                  "vector)"),
    ([0, 0, 0, 0, 1], "work plane: expected 6 numbers (origin x,y,z and normal x,y,z) or 9 (and the x direction), "
                      "got 5"),
    ([math.nan, 0, 0, 0, 0, 1], "work plane: the origin must be finite numbers within ±100000 mm, got (nan, 0, 0)"),
])
def test_work_plane_errors(values: list[float], message: str) -> None:
    with pytest.raises(WorkPlaneError) as info:
        WorkPlane.from_values(values)
    assert str(info.value) == message and info.value.exit_code == 2


def test_a_work_plane_of_huge_direction_numbers_is_its_direction(recwarn: pytest.WarningsRecorder) -> None:
    """np.linalg.norm of (0, 0, 1e308) overflowed: a RuntimeWarning on standard error and 'is not a direction'."""
    plane = WorkPlane.from_values([0, 0, 0, 0, 1e308, 1e308, 1e308, 0, 0])
    assert_allclose(plane.normal, [0.0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-15)
    assert_allclose(plane.rotation[:, 0], [1.0, 0.0, 0.0], atol=0)
    assert [str(w.message) for w in recwarn] == []


@pytest.mark.parametrize("face", ["-1", "4x", "", " "])
def test_a_work_plane_face_that_is_no_number_is_named(face: str) -> None:
    """`--work-plane wedge.stl:-1` said 'file not found' of a file that is there."""
    wedge = str(REPO / "fixtures" / "parts" / "wedge.stl")
    with pytest.raises(InputError) as info:
        work_plane_from_text(f"{wedge}:{face}")
    assert str(info.value) == (f"{wedge}:{face}: the face after ':' must be a face number (0, 1, ... as `prs3-post "
                               f"faces` lists them), got {face!r}")


# --------------------------------------------------------------------------------------------
# Motion, arcs, cycles, units, events
# --------------------------------------------------------------------------------------------
def test_arcs_r_forms_full_circle_helix_turns_and_planes() -> None:
    f = _parse("G0 X10 Y0 Z0\nG1 G91.1 F60\nG2 X-10 Y0 R-10\nG3 X-10 Y0 I10 J0 Z-2\nG19 G3 Y0 Z-2 J0 K2 P2\nM30\n")
    tp = f.toolpath
    lines = tp.source
    half = tp.tip[lines == 3]                          # G2 R−10 over a diameter: a half turn, clockwise through −y
    assert_allclose(half[-1], [-10, 0, 0], atol=1e-12)
    assert np.all(half[:-1, 1] < 0)
    helix = tp.tip[lines == 4]                         # a full turn down 2 mm around (0, 0)
    assert_allclose(np.hypot(helix[:, 0], helix[:, 1]), 10, atol=1e-12)
    assert_allclose(helix[-1], [-10, 0, -2], atol=1e-12)
    assert len(helix) == _segments(10, 2 * math.pi)
    twice = tp.tip[lines == 5]                         # G19 (YZ): two full turns of radius 2 around Y0 Z0
    assert_allclose(twice[-1], [-10, 0, -2], atol=1e-12)
    assert len(twice) == _segments(2, 4 * math.pi)
    assert_allclose(np.hypot(twice[:, 1], twice[:, 2]), 2, atol=1e-12)
    assert f.counts.arcs == 3


def test_g2_r_short_arc_turns_clockwise() -> None:
    f = _parse("G0 X0 Y0 Z0\nG2 X10 Y0 R5 F100\nG3 X20 Y0 R5\nM30\n")
    first, second = f.toolpath.tip[f.toolpath.source == 2], f.toolpath.tip[f.toolpath.source == 3]
    assert np.all(first[:-1, 1] > 0) and np.all(second[:-1, 1] < 0)   # G2 over the top, G3 under
    assert_allclose(np.hypot(first[:, 0] - 5, first[:, 1]), 5, atol=1e-12)


def test_inches_incremental_and_merged_start_rapids() -> None:
    f = _parse("G20\nG0 Z2\nG0 X1 Y1\nG91 G1 X.5 F10\nG90 G81 X2 Y2 Z-.1 R.1\nX3\nG80\nM30\n")
    tp = f.toolpath
    assert_allclose(tp.tip / 25.4, [[1, 1, 2], [1.5, 1, 2], [2, 2, 2], [2, 2, .1], [2, 2, -.1], [2, 2, 2],
                                     [3, 2, 2], [3, 2, .1], [3, 2, -.1], [3, 2, 2]], atol=1e-12)
    assert_allclose(tp.feed[tp.kind == F], 254.0, atol=1e-12)
    assert (f.counts.start_rapids, f.counts.moves, f.units) == (1, 2, "inch")
    assert tp.source.tolist() == [3, 4, 5, 5, 5, 5, 6, 6, 6, 6]


def test_g82_dwell_g73_chip_break_g4_and_events() -> None:
    f = _parse("T3 M6\nS1000 M4\nM7\nG0 X0 Y0 Z5\nG98 G82 X0 Y0 Z-1 R1 P.5 F50\nG73 X1 Z-2 R1 Q1.5\nG80\n"
               "G4 P2\nS2000\nM0\nM1\nM9 M5\nM2\n")
    tp = f.toolpath
    # G82 from (0, 0, 5): already above the hole, so down to R1; G73 (no G80 between: the G98 level stays 5)
    assert_allclose(tp.tip[:, 2], [5, 1, -1, 5, 5, 1, -0.5, -0.5 + PECK_GAP_MM, -2, 5], atol=1e-12)
    assert_allclose(tp.tip[4:, 0], 1, atol=0)
    assert [(e.before, e.kind, e.value, e.text) for e in tp.events] == [
        (0, EventKind.TOOL_CHANGE, 3.0, "tool 3"), (0, EventKind.SPINDLE_ON_CCW, 1000.0, ""),
        (0, EventKind.COOLANT_ON, 0.0, "mist"), (3, EventKind.DWELL, 0.5, ""), (10, EventKind.DWELL, 2.0, ""),
        (10, EventKind.SPINDLE_ON_CCW, 2000.0, ""), (10, EventKind.STOP, 0.0, ""),
        (10, EventKind.OPTIONAL_STOP, 0.0, ""), (10, EventKind.SPINDLE_OFF, 0.0, ""),
        (10, EventKind.COOLANT_OFF, 0.0, "")]


def test_g93_inverse_time_feeds_become_mm_per_minute() -> None:
    f = _parse("G0 X0 Y0 Z0\nG93 G1 X30 F2\nG2 X-30 Y0 I-30 J0 F.5\nG94 G1 X0 F100\nM30\n")
    feed = f.toolpath.feed
    assert_allclose(feed[:2], [0.0, 60.0], atol=1e-12)                 # 30 mm in 1/2 min
    assert_allclose(feed[2:-1], 0.5 * 30 * math.pi, atol=1e-9)         # half a circle of radius 30 in 2 min
    assert_allclose(feed[-1], 100.0, atol=0)


# --------------------------------------------------------------------------------------------
# Streaming: chunks of any size, bulk and careful paths give the same rows
# --------------------------------------------------------------------------------------------
def _program(lines: int) -> str:
    rows = [f"G1 X{i % 97 * 0.5:.3f} Y{i % 89 * 0.25:.3f} Z{-(i % 7):d}" + ("\n(pass 1)  ; pass" * (i % 50 == 7))
            + "\n" * (i % 61 == 0) for i in range(lines)]
    head = "%\nG21 G90 G94\nG0 X0 Y0 Z10\nG68.2 X5 Y5 Z0 I15 J20 K-10\nG53.1\nG1 Z5 F500\n"
    middle = "\n(half way)\nG0 X1 Y0 Z0\nG18 G3 X-1 Z0 I-1 K0 F200\nG17 G0 Z5\n"
    return head + "\n".join(rows[:lines // 2]) + middle + "\n".join(rows[lines // 2:]) + "\nG69\nM30\n%\n"


def _same(a: GcodeFile, b: GcodeFile) -> None:
    for name in ("kind", "tip", "axis", "feed", "source"):
        assert np.array_equal(getattr(a.toolpath, name), getattr(b.toolpath, name)), name
    assert a.toolpath.events == b.toolpath.events
    assert (a.counts, a.cycles, a.end_lines) == (b.counts, b.cycles, b.end_lines)
    assert [(p.line, p.words) for p in a.planes] == [(p.line, p.words) for p in b.planes]
    for p, q in zip(a.planes, b.planes, strict=True):
        assert np.array_equal(p.plane.origin, q.plane.origin) and np.array_equal(p.plane.rotation, q.plane.rotation)


@pytest.mark.parametrize("chunk_lines", [1, 7, 10_000])
def test_chunks_of_any_size_give_the_same_rows(chunk_lines: int) -> None:
    text = _program(300)
    read = parse_gcode(text, path="t", tolerance=TOL, chunk_lines=chunk_lines, circle_tolerance=CIRCLE_TOL)
    _same(read, _parse(text))
    counts = read.counts                                 # every line is accounted for, once
    assert counts.lines == counts.records + counts.comment_lines + counts.blank_lines + dict(counts.skipped)["%"]
    assert (counts.lines, counts.comment_lines, counts.blank_lines) == (len(text.splitlines()), 7, 5)


def test_bulk_lines_read_as_the_careful_reader_reads_them() -> None:
    text = _program(300)
    careful = text.replace("G1 X", "G1 X ")             # a space inside a word: not the regular shape
    assert careful != text
    _same(_parse(careful), _parse(text))


def test_the_stream_reads_a_file_in_pieces(tmp_path: Path) -> None:
    path = tmp_path / "p.ngc"
    path.write_text(_program(50).replace("\n", "\r\n"))
    stream = GcodeStream(str(path), tolerance=TOL, chunk_lines=4, piece_bytes=9, circle_tolerance=CIRCLE_TOL)
    chunks = list(stream)
    assert len(chunks) > 5 and stream.summary is not None
    _same(GcodeStream(str(path), tolerance=TOL, piece_bytes=9,
                      circle_tolerance=CIRCLE_TOL).whole(), _parse(_program(50)))


# --------------------------------------------------------------------------------------------
# Bad input: each with its exact message and line
# --------------------------------------------------------------------------------------------
BAD = [
    ("G0 X0 Y0 Z0\nG1 X1 U2 F1\n", 2, "word 'U2' is not read by the 3+2 G-code reader (words read: G M N X Y Z I J K R "
     "P Q F S T H; O alone on its line)"),
    ("G0 X0 Y0 Z0\nG43.4 H1\n", 2, "code G43.4 is not read by the 3+2 G-code reader: tool centre point control "
     "belongs to 5-axis programs (codes read: G0 G1 G2 G3 G4 G17 "
     "G18 G19 G20 G21 G40 G43 G49 G53.1 G54 G68.2 G69 G73 G80 G81 G82 G83 G90 G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 "
     "M4 M5 M6 M7 M8 M9 M30)"),
    ("G0 X0 Y0 Z0\nG93\nG1 X5\n", 3, "G1 under G93 (inverse time) without F: every feed move under G93 needs its own "
     "F (1/minute)"),
    ("G0 X0 Y0 Z0\nG1 X1e-05 F100\n", 2, "word 'E-05' is not G-code: E is not read here, and a number with an "
     "exponent (1e-05) must be written as a plain decimal (0.00001)"),
    ("G0 X0 Y0 Z0\nG1 Xnan F100\n", 2, "column 4: word 'X' has no plain decimal number: found 'Xnan F100' (a number "
     "is -12.5, .5 or 5.; no '+', no exponent)"),
    ("G0 X[1+2] Y0 Z0\n", 1, "column 5: '[' starts an expression ([1+2], LinuxCNC's arithmetic), which is not read "
     "here: use plain numbers"),
    ("G0 X#1 Y0 Z0\n", 1, "column 5: '#' is a parameter (#1, #<name>), which is not read here: use plain numbers"),
    ("G0 X0 Y0 Z9\nG68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG68.2 P3 Q2 I0 J0 K0\n", 3, "G68.2 P3 Q2: the normal I J K is the "
     "zero vector (it must be the plane's z direction, the tool axis)"),
    ("G0 X0 Y0 Z0\nG68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG68.2 P3 Q2 I1 J0 K1\n", 3, "G68.2 P3: the x direction (line 2) and "
     "the normal are 45.00° apart; they must be perpendicular (85° to 95°)"),
    ("G0 X0 Y0 Z0\nG2 X10 Y1 I5 J0 F100\n", 2, "G2 end point (X10.0000 Y1.0000 Z0.0000) is 0.0990 mm outside the "
     "circle through its start (radius 5.0000); the end must lie on the circle within 0.01 mm"),
    ("G0 X0 Y0 Z0\nG2 X20 Y0 R5 F100\n", 2, "G2 end point is 20.0000 mm from its start, more than the diameter "
     "10.0000 of R5: the end is not on a circle of that radius"),
    ("G0 X0 Y0 Z0\nG68.2 X0 Y0 Z0 I0 J30 K0\nG1 X1 F100\n", 3, "a move in the tilted plane of G68.2 (line 2) before "
     "G53.1: give G53.1 first, which turns the tool axis to the plane's normal"),
    ("G68.2 X0 Y0 Z0 J30\nG53.1\nG68.2 X0 Y0 Z0 J20\n", 3, "G68.2 while the tilted plane of line 1 is active: cancel "
     "it with G69 first"),
    ("G53.1\n", 1, "G53.1 without a tilted plane: G53.1 turns the tool axis to the plane of a G68.2, which must come "
     "first"),
    ("G68.2 P1 X0 Y0 Z0 I0 J30 K0\n", 1, "G68.2 P1 is not read: the reader reads P0 (Euler angles X Y Z I J K, the "
     "default) and P3 (two vectors: Q1 X Y Z I J K, then Q2 I J K)"),
    ("G0 X0 Y0 Z0\nG1 X1\n", 2, "G1 before any F: the feed rate is unknown (give F, in units per minute)"),
    ("G0 Z5\nG1 X1 F100\n", 2, "G1 while the position is not fully known: the first moves must give X, Y and Z (a "
     "rapid may give them over several lines)"),
    ("X1\n", 1, "axis words without a motion mode: give G0, G1, G2, G3 or a canned cycle"),
    ("G0 X0 Y0 Z0\nG0 G1 X1\n", 2, "G0 and G1 on one line: both are G codes of the motion group (one per line)"),
    ("G0 X0 X1\n", 1, "X0 and X1 on one line: a word may appear once"),
    ("G0 X0 Y0 Z0\nG0 X1 R2\n", 2, "word 'R2' is not used by any code on this line (R goes with G2/G3 or a canned "
     "cycle)"),
    ("G0 X0 Y0 Z0\nG83 X1 Y1 Z-5 R1 F100\n", 2, "G83 needs Q > 0, the depth of each peck"),
    ("G0 X0 Y0 Z5\nG83 X0 Y0 Z-5 R2 Q0.000000001 F100\n", 2, "G83 Q1e-09 would drill 7 from R to Z in "
     "7,000,000,000 pecks, more than 10,000: use a larger Q"),
    ("G0 X0 Y0 Z5\nG2 X0 Y0 I10 P100000000 F100\n", 2, "G2 (radius 10, 100000000 turns) needs 15,707,701,462 "
     "segments within 0.002 mm, more than 100,000"),
    ("G0 X0 Y0 Z0\nG81 X1 Y1 Z5 R1 F100\n", 2, "G81 bottom Z 5 is not below the retract plane R 1: the hole goes down "
     "the tool axis, from R to Z"),
    ("G0 X0 Y0 Z0\nG17 G2 X1 Y1 I1 K1 F100\n", 2, "K1 in G17: the arc centre's offsets in G17 are I and J"),
    ("M6\n", 1, "M6 without a tool number: give T on this line or before"),
    ("M3\n", 1, "M3 without a spindle speed: give S (rpm) on this line or before"),
    ("G0 X0 Y0 Z0\nM30\nG0 X1\n", 3, "code after the program end (M2/M30 at line 2): 'G0 X1'"),
    ("G0 X0 Y0 Z0 N5\n", 1, "the line number N5 must be the first word of the line"),
    ("G0 X0 Y0 Z0\nO100 G1\n", 2, "an O word (program number) must be alone on its line, found 'O100 G1'"),
    ("G0 X0 Y0 Z0 (open\n", 1, "comment opened with '(' at column 13 is not closed with ')'"),
    ("G0 X0 Y0 Z0\nG68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG0 X1\n", 3, "G68.2 P3 Q1 at line 2 must be followed by its G68.2 P3 "
     "Q2 line (the normal, I J K)"),
    ("G0 X0 Y0 Z0\nG93 G81 X1 Y1 Z-1 R1 F1\n", 2, "G81 under G93 (inverse time): canned cycles need a feed per minute "
     "(G94)"),
    ("G1 F0\n", 1, "F must be > 0, got F0"),
    ("G20\nG0 X0 Y0 Z1\nG1 Z0 F50000\n", 3, "F50000 is 1.27e+06 mm/min, more than 1e+06 mm/min"),
    ("G0 X0 Y0 Z1\nG1 Z0 F100000000\nG1 X1\n", 2, "F100000000 is 1e+08 mm/min, more than 1e+06 mm/min"),
    ("G0 X0 Y0 Z1\nS99999999999999999999999 M3\n", 2, "S99999999999999999999999 is more than 1e+06 rpm (allowed: "
     "0, or 1 to 1e+06 rpm)"),
    # it was a limit error (exit 1) in the emitter: "spindle_on event before row 0 ...", printed as S0
    ("G0 X0 Y0 Z1\nS0.001 M3\n", 2, "S0.001 is less than 1 rpm (allowed: 0, or 1 to 1e+06 rpm)"),
    ("G68.2 X0 Y0 Z0 I10 J20 K0 Q121\n", 1, "G68.2 Q121: the Euler angles are read in the order Z-X-Z only (Q313, "
     "the default)"),
    ("G64 P0.01\n", 1, "code G64 is not read by the 3+2 G-code reader (codes read: G0 G1 G2 G3 G4 G17 G18 G19 G20 G21 "
     "G40 G43 G49 G53.1 G54 G68.2 G69 G73 G80 G81 G82 G83 G90 G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 "
     "M9 M30)"),
    ("G28 G91 Z0.\n", 1, "code G28 is not read by the 3+2 G-code reader: a return to the machine's reference point "
     "is no position on the part; leave it out (the converted program starts and ends at the machine's safe position) "
     "(codes read: G0 G1 G2 G3 G4 G17 G18 G19 G20 G21 G40 G43 G49 G53.1 G54 G68.2 G69 G73 G80 G81 G82 G83 G90 G91 "
     "G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 M9 M30)"),
    ("G90.1\n", 1, "code G90.1 is not read by the 3+2 G-code reader: absolute arc centres: have the CAM system write "
     "I J K relative to the start (G91.1) (codes read: G0 G1 G2 G3 G4 G17 G18 G19 G20 G21 "
     "G40 G43 G49 G53.1 G54 G68.2 G69 G73 G80 G81 G82 G83 G90 G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 "
     "M9 M30)"),
    ("G0 X0 Y0 Z9\nG18 G81 X1 Y1 Z-1 R1 F100\n", 2, "G81 in G18: canned cycles are read in G17 only, where the hole "
     "goes along Z, the tool axis (in G18/G19 it would go sideways)"),
]


@pytest.mark.parametrize(("text", "line", "message"), BAD, ids=[m[:40] for _, _, m in BAD])
def test_bad_input_names_the_line_and_what_is_valid(text: str, line: int, message: str) -> None:
    with pytest.raises(InputError) as info:
        _parse(text)
    assert (info.value.path, info.value.line, info.value.args[0]) == ("t.ngc", line, message)
    assert str(info.value) == f"t.ngc:{line}: {message}"


@pytest.mark.parametrize("name", sorted(p.name for p in (REPO / "fixtures" / "bad" / "gcode").glob("*.ngc")))
def test_bad_gcode_files_give_their_exact_message(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """fixtures/bad/gcode: the first line is the expected message (for convert's tests too: exit code 2)."""
    monkeypatch.chdir(REPO)
    path = f"fixtures/bad/gcode/{name}"
    first = (REPO / path).read_text().splitlines()[0]
    assert first.startswith("; expect: ")
    with pytest.raises(InputError) as info:
        read_gcode(path, tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == first.removeprefix("; expect: ")
    assert info.value.exit_code == 2


@pytest.mark.parametrize(("text", "message"), [
    ("", "not a G-code program: the file is empty"),
    ("(only a comment)\n%\n", "not a G-code program: no code (only comments, blank lines or '%')"),
    ("G0 X1\x1a\n", "not a G-code program: binary data (byte 0x1a at offset 5)"),
])
def test_not_a_program(text: str, message: str) -> None:
    with pytest.raises(InputError) as info:
        _parse(text)
    assert str(info.value) == f"t.ngc: {message}"


# --------------------------------------------------------------------------------------------
# The corpus G-code files are 5-axis programs (issue 11): refused, naming the first rotary word
# --------------------------------------------------------------------------------------------
ROTARY = {
    "linuxcnc_boat-xyzac.ngc": (13, "A0."),
    "linuxcnc_impeller-7bl-xyzac.ngc": (8, "A-71.841"),
    "linuxcnc_xyzab-tdr-demo.ngc": (6, "A0"),
    "mech491_PostProcessed_Variable_Axis_haas_umc750.nc": (21, "B0.0"),
}


@pytest.mark.skipif(not (CORPUS / "gcode").is_dir(), reason="../shared/corpus is not there")
@pytest.mark.parametrize("name", sorted(ROTARY))
def test_corpus_5_axis_programs_are_refused_at_their_first_rotary_word(name: str) -> None:
    assert sorted(p.name for p in (CORPUS / "gcode").iterdir()) == sorted(ROTARY)
    line, word = ROTARY[name]
    path = str(CORPUS / "gcode" / name)
    with pytest.raises(InputError) as info:
        read_gcode(path, tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert str(info.value) == (
        f"{path}:{line}: 5-axis program: rotary word '{word}' (A, B and C words turn rotary axes); the 3+2 reader "
        "reads programs whose tool axis is set by G68.2/G53.1 or by the work plane, so it refuses this program "
        "rather than misread it; a 5-axis program under TCP converts when source names the machine it was written "
        "for (prs3-post sources lists them)")


def test_a_rotary_word_in_a_comment_or_a_parameter_name_is_not_one() -> None:
    f = _parse("(A1 B2 C3)\nG0 X0 Y0 Z0 ; C5\nM30\n")
    assert len(f.toolpath) == 1


# --------------------------------------------------------------------------------------------
# Format detection by content
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("head", "expected"), [
    (b"TOOL PATH/DRILLING,TOOL,D6\nTLDATA/DRILL,6.0\nGOTO/1,2,3\n", "cl"),
    (b"$$ comment\nFROM/0,0,100\n", "cl"),
    (b"\n\nRAPID\nGOTO/1,2,3", "cl"),
    (b"%\nO1000\n(a/b comment)\nG0 X1\n", "gcode"),
    (b"N10 G1 X1 (a/b)\nGOTO/1,2,3\n", "gcode"),
    (b"g0 x1 y2\n", "gcode"),
    (b"\xef\xbb\xbfGOTO/1,2,3\n", "cl"),
    (b"", "gcode"),
    (b"\xff\xfe garbage", "gcode"),
])
def test_detect_format_by_content(head: bytes, expected: str) -> None:
    assert detect_format(head) == expected


@pytest.mark.skipif(not CORPUS.is_dir(), reason="../shared/corpus is not there")
def test_detect_format_on_the_corpus() -> None:
    found = {p.name: detect_format(p.read_bytes()[:65536]) for p in sorted((CORPUS / "cl").iterdir())
             if p.suffix in (".cls", ".clsf")}
    found |= {p.name: detect_format(p.read_bytes()[:65536]) for p in sorted((CORPUS / "gcode").iterdir())}
    assert found == {name: "cl" if name.endswith((".cls", ".clsf")) else "gcode" for name in found}


# --------------------------------------------------------------------------------------------
# LinuxCNC's interpreter as the reference of the 3-axis reading (no G68.2: LinuxCNC has none)
# --------------------------------------------------------------------------------------------
def _linuxcnc_moves(programs: list[Path]) -> dict[str, list[tuple[int, str, list[float], float]]]:
    """LinuxCNC's canonical moves of each program (one rs274-check run for all): line, call, end point (mm),
    feed (mm/min; 0 for rapids); moves that go nowhere left out, as the reader leaves them out of cycles."""
    canon = programs[0].parent / "all.canon"
    done = subprocess.run([str(RS274_CHECK), "-a", "XYZ", "--canon", str(canon), *map(str, programs)],
                          capture_output=True, text=True, timeout=120, check=False)
    if "not installed" in done.stdout + done.stderr:
        pytest.skip("linuxcnc-uspace is not installed")
    assert done.returncode == 0, done.stdout + done.stderr
    moves: dict[str, list[tuple[int, str, list[float], float]]] = {}
    current: list[tuple[int, str, list[float], float]] = []
    for row in canon.read_text().splitlines():
        fields = row.split()
        if row.startswith("# FILE "):
            current = moves.setdefault(fields[2], [])
        elif len(fields) > 2 and fields[1] in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED"):
            values = dict(f.split("=") for f in fields[2:] if "=" in f)
            point = [float(values[a]) for a in "XYZ"]
            if not current or point != current[-1][2]:
                current.append((int(fields[0]), fields[1], point, float(values.get("F", 0.0))))
    return moves


def _assert_same_moves(text: str, theirs: list[tuple[int, str, list[float], float]]) -> None:
    """Every LinuxCNC end point is a row of ours, in order, with its feed; between an arc's start and end,
    only that arc's rows (an arc is one call there and many rows here)."""
    ours = _parse(text).toolpath
    position = 0
    for line, call, point, feed in theirs:
        if call == "ARC_FEED":
            while position + 1 < len(ours) and ours.source[position + 1] == line:
                position += 1
        assert ours.source[position] == line, (line, point, ours.source[position])
        assert_allclose(ours.tip[position], point, atol=1e-5, err_msg=f"line {line}")
        assert_allclose(ours.feed[position], feed if call != "STRAIGHT_TRAVERSE" else 0.0, atol=1e-5,
                        err_msg=f"line {line}")
        assert ours.kind[position] == (R if call == "STRAIGHT_TRAVERSE" else F), line
        position += 1
    assert position == len(ours)


def _random_program(seed: int) -> str:
    """A 3-axis program of every kind of move the reader and LinuxCNC both read, with random numbers."""
    rng = random.Random(seed)
    inch = rng.random() < 0.3
    unit = 1 / 25.4 if inch else 1.0

    def num(low: float, high: float) -> str:
        return f"{rng.uniform(low, high) * unit:.4f}"

    lines = ["G20" if inch else "G21", "G90 G94 G17 G99", f"G0 X{num(-50, 50)} Y{num(-50, 50)} Z{num(5, 20)}",
             f"F{num(50, 500)}"]
    for _ in range(25):
        choice = rng.randrange(6)
        if choice <= 1:
            words = [f"{a}{num(-50, 50)}" for a in "XYZ" if rng.random() < 0.7] or ["X1"]
            lines.append(f"{rng.choice(['G0', 'G1', ''])} {' '.join(words)}".strip() if lines[-1][:2] in ("G0", "G1")
                         else f"{rng.choice(['G0', 'G1'])} {' '.join(words)}")
        elif choice == 2:
            lines.append(f"G91 G{rng.choice([0, 1])} X{num(-10, 10)} Y{num(-10, 10)} Z{num(-3, 3)}")
            lines.append("G90")
        elif choice == 3:                                  # an arc, in any plane, I J K or R, sometimes a helix
            plane = rng.choice([17, 18, 19])
            first, second = {17: "XY", 18: "ZX", 19: "YZ"}[plane]
            offsets = {"X": "I", "Y": "J", "Z": "K"}
            radius, start, turn = rng.uniform(2, 20), rng.uniform(0, 2 * math.pi), rng.uniform(0.3, 6.0)
            a, b = -radius * math.cos(start), -radius * math.sin(start)       # centre from the start
            end_angle = start + rng.choice([turn, -turn])
            da, db = a + radius * math.cos(end_angle), b + radius * math.sin(end_angle)
            code = rng.choice(["G2", "G3"])
            lift = f" {({17: 'Z', 18: 'Y', 19: 'X'})[plane]}{num(-3, 3)}" if rng.random() < 0.3 else ""
            end = f"{first}{da * unit:.4f} {second}{db * unit:.4f}"
            if rng.random() < 0.5:
                centre = f"{offsets[first]}{a * unit:.4f} {offsets[second]}{b * unit:.4f}"
            else:
                centre = f"R{radius * unit * rng.choice([1, -1]):.4f}"
            lines.append(f"G{plane} G91 {code} {end}{lift} {centre}")
            lines.append("G90 G17")
        elif choice == 4:                                  # a cycle, two holes, either return level
            code = rng.choice(["G81", "G82 P0.2", "G83 Q" + num(0.5, 3), "G73 Q" + num(0.5, 3)])
            lines.append(f"{rng.choice(['G98', 'G99'])} {code} X{num(-40, 40)} Y{num(-40, 40)} Z{num(-8, -1)} "
                         f"R{num(0.5, 3)}")
            lines.append(f"X{num(-40, 40)}")
            lines.append("G80")
        else:
            lines.append(f"F{num(50, 500)}")
    return "\n".join([*lines, "M2", ""])


@pytest.mark.skipif(not RS274_CHECK.exists() or shutil.which("python3") is None, reason="rs274-check missing")
def test_move_end_points_agree_with_linuxcnc(tmp_path: Path) -> None:
    """The wedge program with more cycles and arcs, and random programs: every end point and feed LinuxCNC's
    interpreter reports is a row of ours, in order."""
    texts = [(PROGRAMS / "wedge-face-3axis.ngc").read_text().replace("G81 X10 Y10", "G99 G83 X10 Y10 Q1.5").replace(
        "G80", "X0 Y5\nG98 G73 X4 Z-2 R2 Q1\nG80\nG18 G2 X-10 Z10 I-7 K0\nG17 G91 G3 X4 Y4 R-4\nG90")]
    texts += [_random_program(seed) for seed in range(8)]
    paths = []
    for index, text in enumerate(texts):
        paths.append(tmp_path / f"p{index}.ngc")
        paths[-1].write_text(text)
    theirs = _linuxcnc_moves(paths)
    for path, text in zip(paths, texts, strict=True):
        _assert_same_moves(text, theirs[str(path)])


def test_comment_lines_of_every_shape_read_in_bulk_as_line_by_line() -> None:
    """Between bulk moves: the usual comment lines (found by the lexer, not decoded) and every other
    blank or comment-only line give the events and counts the careful reader gives (a CR on every
    line sends the whole text through it)."""
    quiet = ["( pass 1 )", "\t(tabbed)  ", "()", "(   )", "(a)(b)", "(a\tb)", "(Ø 6)", ";end", "(a) ;b", "", "  ",
             "\t", "( ;x )"]
    moves = [f"G1 X{i}.5 Y-{i} Z{i % 3}" for i in range(len(quiet) + 1)]
    body = [line for pair in zip(moves, [*quiet, ""], strict=True) for line in pair]
    text = "G0 X0 Y0 Z5\nG1 Z0 F300\n" + "\n".join(body) + "\nM30\n"
    bulk, careful = _parse(text), _parse(text.replace("\n", "\r\n"))
    _same(bulk, careful)
    assert [(e.before, e.text) for e in bulk.toolpath.events] == [
        (3, "pass 1"), (4, "tabbed"), (5, ""), (6, ""), (7, "a"), (7, "b"), (8, "a\tb"), (9, "Ø 6"), (10, "end"),
        (11, "a"), (11, "b"), (15, ";x")]
    assert (bulk.counts.comment_lines, bulk.counts.blank_lines, bulk.counts.comments) == (10, 4, 12)


@pytest.mark.parametrize(("content", "message"), [
    (b"G0 X0 Y0 Z0\nG1 A5 F100\n" + b"G0 X1\n" * 40 + b"G0 X1\x1a\n", "t.ngc:2: 5-axis program: rotary word 'A5'"),
    (b"G0 X0 Y0 Z0\nG1 A5 F100\n" + b"G0 X1\n" * 40 + b"G0 X1\x1a\n", "t.ngc: not a G-code program: binary data "
     "(byte 0x1a at offset 268)"),
    (b"G0 X1\x1a\n" + b"G0 X1\n" * 40 + b"G1 A5\n", "t.ngc: not a G-code program: binary data (byte 0x1a at offset 5)"),
    (b"G0 X0\nG1 X1 Y2\n" * 30 + b"B -.5\n" + b"G0 X1\n" * 40, "t.ngc:61: 5-axis program: rotary word 'B-.5'"),
    (b"G0 X0 (\xc3\xa9) Y0 Z0\nG1 Z1\n" * 8 + b"G1 C 7\n", "t.ngc:17: 5-axis program: rotary word 'C7'"),
    (b" \n\x0c\n" + b"\n" * 80, "t.ngc: not a G-code program: the file is empty"),
    (b" \n\x0c\n" + b"\n" * 80 + b"G0 X1\n", "t.ngc: not a G-code program: binary data (byte 0x0c at offset 2)"),
    (b"\n" * 80 + b"G0 X1\xe9\n", "t.ngc: not a G-code program: not UTF-8 text (byte 0xe9 at offset 85)"),
    (b"\xef\xbb\xbf\n" + b"G0 X1\x1a\n", "t.ngc: starts with a UTF-8 byte-order mark, which LinuxCNC rejects "
     "('Bad character')"),
])
def test_the_whole_file_is_checked_in_pieces_first_problem_first(tmp_path: Path, content: bytes, message: str) -> None:
    """The checks before reading, file by pieces: blank, then the mark, then each piece's bytes (control,
    UTF-8) and its rotary words, the piece nearest the start first: in pieces of 16 bytes (the first
    case), a rotary word before a binary byte is reported first; in one piece (the second), the bytes."""
    path = tmp_path / "t.ngc"
    path.write_bytes(content)
    whole = "offset 268" in message
    with pytest.raises(InputError) as info:
        list(GcodeStream(str(path), tolerance=TOL, piece_bytes=1 << 20 if whole else 16, circle_tolerance=CIRCLE_TOL))
    shown = str(info.value).replace(str(path), "t.ngc")
    assert shown.split(" (A, B and C")[0] == message
    if not whole and not content.startswith(b"G0 X0 Y0 Z0\nG1 A5"):       # the others: the same in one piece
        with pytest.raises(InputError) as info:
            list(GcodeStream(str(path), tolerance=TOL, piece_bytes=1 << 20, circle_tolerance=CIRCLE_TOL))
        assert str(info.value).replace(str(path), "t.ngc").split(" (A, B and C")[0] == message


def test_runs_of_blank_and_comment_lines_are_read_in_bulk_as_one_by_one(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """QA: 4.5 M blank lines took 9.4 s (each through the careful reader). A run of blank and usual
    comment lines with no move is now read in bulk: the same rows, events and counts as when the
    careful reader reads them one by one; an unusual comment line among them sends the run there."""
    from prs3_post.readers.gcode import reader as gcode

    text = ("%\nG21 G90\nG0 X0 Y0 Z5\n" + "\n" * 500 + "(a comment)\n" * 3 + "\n(two) (comments)\n\n"
            + "G1 X1 Y2 Z-1 F100\n" + "\n(last)\n" * 200 + "M30\n%\n" + "\n" * 20)
    path = tmp_path / "quiet.ngc"
    path.write_text(text)
    from_file = GcodeStream(str(path), tolerance=TOL, chunk_lines=97, circle_tolerance=CIRCLE_TOL).whole()
    monkeypatch.setattr(gcode.LineReader, "quiet_lines", lambda self, lines: False)
    from_text = GcodeStream(str(path), tolerance=TOL, chunk_lines=97, circle_tolerance=CIRCLE_TOL).whole()
    assert from_file.counts == from_text.counts
    assert from_file.counts.blank_lines == 500 + 1 + 1 + 200 + 20
    assert from_file.counts.comments == 3 + 2 + 200
    assert from_file.toolpath.events == from_text.toolpath.events
    assert np.array_equal(from_file.toolpath.tip, from_text.toolpath.tip)
