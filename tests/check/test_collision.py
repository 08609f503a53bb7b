"""Tool, holder and spindle nose against the part (fixtures/parts/wall30.stl: a 30° face falling
towards a wall 5 mm thick that rises 40 mm above the face's low edge)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from prs3_post.check.collision import body_cylinders, clearance, inside, point_triangle_distance
from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_CLEARANCE_MIN, DEFAULT_TOLERANCE
from prs3_post.machine.loading import load_machine
from prs3_post.part.faces import find_faces, select_face
from prs3_post.part.stl import load_part

WALL = Path(__file__).resolve().parents[2] / "fixtures" / "parts" / "wall30.stl"
MACHINE = load_machine("patel2020")
MESH = load_part(str(WALL), units="mm")
TRIANGLES = np.asarray(MESH.triangles, dtype=np.float64)
FACE, _ = select_face(find_faces(MESH), None, min_width=6.0)
BODIES = body_cylinders(6.0, 55.0, MACHINE.holder)        # the machine's default tool: 55 mm below the gauge line


def test_hole_near_the_wall_is_refused_naming_the_step_body_and_depth(tmp_path):
    out = tmp_path / "near.ngc"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "30,0", "-o", str(out)])
    assert result.exit_code == 1
    assert result.output == ("prs3-post: error: hole 1 approach: the holder hits the part, 2.446 mm deep "
                             "(clearance min 1.000 mm); no setup changes that (the part and the tool axes move "
                             "together): try a longer tool (--tool-table), a shorter holder (the machine file's "
                             "[holder]), or another --at (or --face)\n")
    assert not out.exists()


def test_hole_forty_mm_from_the_wall_passes_and_the_header_says_the_clearances(tmp_path):
    out = tmp_path / "far.ngc"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "8.1,0", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert [ln for ln in out.read_text().split("\n") if ln.startswith("(collision:")] == [
        "(collision: clear of the part by at least 1.000 mm: tool over 11.000 mm, holder 8.635 mm, "
        "spindle nose over 11.000 mm)"]             # exact, as verify states it (the surface points alone: 8.637)


def test_no_collision_check_is_stated_in_the_header(tmp_path):
    out = tmp_path / "unchecked.ngc"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "30,0", "--no-collision-check",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert [ln for ln in out.read_text().split("\n") if ln.startswith("(collision:")] == [
        "(collision: not checked [asked not to])"]


def _sweep(height: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rapid from 10 mm above a hole at u = 30 on the face to a point beyond the wall, at z = height."""
    start = FACE.origin + 30.0 * FACE.u + 10.0 * FACE.normal
    start[2] = height
    end = np.array([80.0, start[1], height])
    tip = start + np.linspace(0.0, 1.0, 21)[:, None] * (end - start)
    features = np.array([FACE.origin + 30.0 * FACE.u, end - 10.0 * FACE.normal])
    return tip, np.tile(FACE.normal, (21, 1)), features


def test_a_rapid_through_the_wall_between_two_features_is_caught():
    tip, axis, features = _sweep(FACE.origin[2] + 30.0 * FACE.u[2] + 10.0 * FACE.normal[2])
    found = clearance(TRIANGLES, tip, axis, BODIES, FACE, features, refine_max=10**6,
                      clearance_min=DEFAULT_CLEARANCE_MIN)
    # the tool (radius 3) crosses the 5 mm wall: its deepest surface point is half the wall inside
    assert found.distance[0] == pytest.approx(-2.5, abs=0.02)
    assert found.distance[1] < 0 and found.exact.all()


def test_the_same_rapid_above_the_wall_clears_it_by_the_formula():
    tip, axis, features = _sweep(330.0)
    found = clearance(TRIANGLES, tip, axis, BODIES, FACE, features, refine_max=10**6,
                      clearance_min=DEFAULT_CLEARANCE_MIN)
    # the tool's low rim, tilted 30°: 330 − 3 sin 30° above the wall's top at z = 315
    assert found.distance[0] == pytest.approx(330.0 - 3.0 * math.sin(math.radians(30.0)) - 315.0, abs=1e-6)
    assert found.exact.all()


def test_lower_bound_never_exceeds_the_sampled_minimum():
    tip, axis, features = _sweep(320.0)
    quick = clearance(TRIANGLES, tip, axis, BODIES, FACE, features, clearance_min=DEFAULT_CLEARANCE_MIN)
    full = clearance(TRIANGLES, tip, axis, BODIES, FACE, features, refine_max=10**6,
                     clearance_min=DEFAULT_CLEARANCE_MIN)
    assert (quick.distance <= full.distance + 1e-12).all()
    assert full.exact.all()


def test_point_triangle_distance_and_inside_against_plain_cases():
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    points = np.array([[0.2, 0.2, 1.0], [-1.0, 0, 0], [1, 1, 0], [2, -1, 0], [0.5, -2, 0]])
    expected = [1.0, 1.0, math.sqrt(0.5), math.sqrt(2.0), 2.0]
    np.testing.assert_allclose(point_triangle_distance(points, tri)[:, 0], expected, atol=1e-12)
    assert inside(np.array([[0.0, 200.0, 100.0], [0.0, 200.0, 400.0], [52.0, 200.0, 310.0]]), TRIANGLES).tolist() == [
        True, False, True]


def test_a_rapid_given_by_its_end_poses_only_is_checked_along_its_length():
    # verify samples a move that translates the head at its end only: the motion between is bounded
    # (a slim holder and nose, so that the first pose, beside the wall, is clear of it)
    slim = np.array([[3.0, 0.0, 15.0], [4.0, 15.0, 20.0], [4.0, 20.0, 22.0]])
    tip, axis, features = _sweep(FACE.origin[2] + 30.0 * FACE.u[2] + 10.0 * FACE.normal[2])
    ends = [0, len(tip) - 1]
    alone = clearance(TRIANGLES, tip[ends], axis[ends], slim, FACE, features, refine_max=10,
                      clearance_min=DEFAULT_CLEARANCE_MIN)
    assert alone.distance.round(3).tolist() == [8.921, 5.555, 4.555] and alone.exact.all()
    moving = clearance(TRIANGLES, tip[ends], axis[ends], slim, FACE, features, connected=np.array([False, True]),
                       clearance_min=DEFAULT_CLEARANCE_MIN)
    assert moving.distance[0] == pytest.approx(-2.108, abs=1e-3) and moving.exact[0]   # through the 5 mm wall
    assert moving.sample[0] == 1                              # named by the pose the motion ends at


def _round_pocket(depth: float):
    """The demo wedge's round profile (36 mm, 0.1 mm steps down): 24,027 rows at 2.5 mm deep."""
    from prs3_post.app.job import JobSpec, plan
    from prs3_post.machine.loading import load_dialect
    from prs3_post.part.setup_transform import Setup
    from prs3_post.post.pipeline import post_process
    from prs3_post.toolpaths import Coolant, Cutting, Direction, Entry, ProfileParams, RoundShape, Side
    from prs3_post.toolpaths.work import ProfileJob

    part = str(Path(__file__).resolve().parents[2] / "postproc" / "parts" / "patel2020-wedge.stl")
    work = ProfileJob(RoundShape(diameter=36.0), ProfileParams(
        side=Side.ON, depth=depth, step_down=0.1, direction=Direction.CLIMB, entry=Entry.RAMP,
        ramp_angle=np.radians(3.0), clearance=2.0, retract=10.0))
    spec = JobSpec(part=part, units="mm", face=None, work=work, at_uv=np.zeros((0, 2)), at_xyz=np.zeros((0, 3)),
                   cutting=Cutting(tool_diameter=6.0, feed=300.0, plunge_feed=100.0, spindle_rpm=3000.0,
                                   coolant=Coolant.FLOOD, tool_number=1),
                   machine=MACHINE, dialect=load_dialect("linuxcnc"), setup=Setup.resolve(MACHINE), tolerance=0.0001)
    mesh = load_part(part)
    face, _ = select_face(find_faces(mesh), None, min_width=6.0)
    post = post_process(MACHINE, plan(spec, face), spec.setup, tolerance=spec.tolerance, length_decimals=4,
                        angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    return post.program, spec.setup, np.asarray(mesh.triangles), face


def test_a_program_of_more_than_20000_poses_is_checked():
    from prs3_post.check.collision import check_program
    from prs3_post.core.errors import LimitError

    program, setup, triangles, face = _round_pocket(2.5)
    assert len(program) == 24027                              # once beyond the check's pose limit: 'not checked'
    assert check_program(MACHINE, program, setup, triangles, face, 6.0, clearance_min=DEFAULT_CLEARANCE_MIN) == (
        "clear of the part by at least 1.000 mm: tool over 11.000 mm, holder over 11.000 mm, "
        "spindle nose over 11.000 mm")
    # the holder's end is 20 − 2.5 mm above the face on the last pass: an 18 mm clearance refuses it there
    with pytest.raises(LimitError) as error:
        check_program(MACHINE, program, setup, triangles, face, 6.0, clearance_min=18.0)
    assert str(error.value) == ("round pass 25/25 lap: the holder comes within 17.500 mm of the part "
                                "(clearance min 18.000 mm)")


@pytest.mark.parametrize(("replay_rows", "group_rows"), [(65536, 64), (7, 64), (7, 7), (65536, 10**9)])
def test_the_streamed_check_gives_the_same_minima_and_messages_in_any_pieces(monkeypatch, replay_rows, group_rows):
    # 10**9 rows a group: no group is bounded as a whole, every row is replayed and checked in order
    import prs3_post.check.collision as collision
    import prs3_post.check.collision_scan as scan
    from prs3_post.core.errors import LimitError

    program, setup, triangles, face = _round_pocket(0.3)
    monkeypatch.setattr(collision, "REPLAY_ROWS", replay_rows)
    monkeypatch.setattr(scan, "GROUP_ROWS", group_rows)
    monkeypatch.setattr(scan, "SCAN_ROWS", 7 * group_rows if group_rows < 100 else 1 << 16)
    # the holder's end is 20 − 0.3 mm above the face at the bottom: within a 10 mm clearance's horizon
    found = collision.measure_program(MACHINE, program, setup, triangles, face, 6.0, clearance_min=10.0)
    assert found.entry(10.0) == ("clear of the part by at least 10.000 mm: tool over 20.000 mm, holder 19.700 mm, "
                                 "spindle nose over 20.000 mm")
    with pytest.raises(LimitError) as error:
        collision.check_program(MACHINE, program, setup, triangles, face, 6.0, clearance_min=19.75)
    assert str(error.value) == ("round pass 3/3 lap: the holder comes within 19.700 mm of the part "
                                "(clearance min 19.750 mm)")


def test_the_replay_in_pieces_gives_the_samples_of_one_replay(monkeypatch):
    import prs3_post.check.collision as collision
    from prs3_post.check.verify import replay
    from prs3_post.core.toolpath import MoveKind

    program = _round_pocket(0.5)[0]
    whole = replay(MACHINE, program, tolerance=DEFAULT_TOLERANCE)
    monkeypatch.setattr(collision, "REPLAY_ROWS", 1000)
    row, tip, axis, feed = collision._replayed(MACHINE, program)
    assert len(program) > 3000 and row.tolist() == whole.row.tolist()
    np.testing.assert_array_equal(tip, whole.tip)
    np.testing.assert_array_equal(axis, whole.axis)
    np.testing.assert_array_equal(feed, whole.tip[whole.end[program.kind == MoveKind.FEED]])


@pytest.mark.parametrize("rows", [1, 7, 1000])
def test_the_swept_region_drawn_in_pieces_is_the_region_drawn_at_once(monkeypatch, rows):
    # the main job draws its feed tips a piece at a time (memory), in the machine frame with the setup
    import prs3_post.check.collision_bodies as collision
    from prs3_post.check.verify import replay
    from prs3_post.core.toolpath import MoveKind

    program, setup, _, face = _round_pocket(0.5)
    whole = replay(MACHINE, program, tolerance=DEFAULT_TOLERANCE)
    tips = whole.tip[whole.end[program.kind == MoveKind.FEED]]          # machine frame
    at_once = collision.swept_region(face, collision._to_part(setup, tips), 3.0)
    assert len(tips) > 3000 and 0 < at_once.cells.sum() < at_once.cells.size
    monkeypatch.setattr(collision, "_SWEPT_ROWS", rows)
    in_part = collision._to_part(setup, tips)
    for pieces in (collision.swept_region(face, tips, 3.0, setup=setup), collision.swept_region(face, in_part, 3.0)):
        np.testing.assert_array_equal(pieces.low, at_once.low)
        np.testing.assert_array_equal(pieces.cells, at_once.cells)


def test_a_job_transition_through_the_part_is_refused(tmp_path):
    # a 20 mm block hangs 160 mm above the face's origin along its normal: beyond the nose over the
    # first hole, but in the way of the lift to the job's safe height (which it raises)
    import trimesh

    roof = trimesh.creation.box(extents=(20.0, 20.0, 10.0))
    roof.apply_translation((80.0, 200.0, 440.0))
    trimesh.util.concatenate([trimesh.load(str(WALL)), roof]).export(str(tmp_path / "roofed.stl"))
    origin = "-100,-200,-1000"
    for u in ("0", "-40"):                                    # each hole alone is clear
        alone = CliRunner().invoke(main, ["run", str(tmp_path / "roofed.stl"), "--profile", "hole", "--at", f"{u},0",
                                          "--depth", "3", "--part-origin", origin, "-o", str(tmp_path / f"{u}.ngc")])
        assert alone.exit_code == 0, alone.output
    (tmp_path / "job.toml").write_text(
        'part = "roofed.stl"\nunits = "mm"\n\n[setup]\npart_origin = [-100.0, -200.0, -1000.0]\n\n'
        '[[operation]]\nprofile = "hole"\nat = [[0.0, 0.0]]\ndepth = 3.0\n\n'
        '[[operation]]\nprofile = "hole"\nat = [[-40.0, 0.0]]\ndepth = 3.0\n', encoding="utf-8")
    out = tmp_path / "job.ngc"
    result = CliRunner().invoke(main, ["job", str(tmp_path / "job.toml"), "-o", str(out)])
    # the block is wholly inside the nose's cylinder at the lift's closest pose: its surface points missed it,
    # the solid test finds it (the message named the holder, 3.498 mm deep, the body its points did see)
    assert (result.exit_code, result.output) == (1, "prs3-post: error: operation 1 (hole on face 4), lift to the safe "
                                                    "height: the spindle nose hits the part, 19.968 mm deep "
                                                    "(clearance min 1.000 mm)\n")
    assert not out.exists()


SLOPE = Path(__file__).resolve().parents[3] / "shared" / "corpus" / "stl" / "ssg_slope.stl"
V_NOTCH = "prs3-post: error: hole 1 approach: the tool hits the part, 4.890 mm deep (clearance min 1.000 mm)"


@pytest.mark.skipif(not SLOPE.exists(), reason="the shared corpus is not here")
def test_a_collision_with_the_part_is_the_same_in_every_setup_and_auto_placement_says_so(tmp_path):
    # the tool axis is the face's normal and the part moves with the setup: the same depth everywhere
    for origin, rotation in (("-18,-10,-688", "0"), ("-30,20,-700", "0"), ("-10,-5,-680", "90"), ("auto", "45")):
        result = CliRunner().invoke(main, ["run", str(SLOPE), "--profile", "hole", "--part-origin", origin,
                                           "--part-rotation", rotation, "-o", str(tmp_path / "s.ngc")])
        assert result.exit_code == 1
        assert result.output.startswith(V_NOTCH)
    result = CliRunner().invoke(main, ["run", str(SLOPE), "--profile", "hole", "--part-origin", "auto",
                                       "-o", str(tmp_path / "s.ngc")])
    assert result.output == (
        f"{V_NOTCH}; the setup was chosen automatically, but no placement changes this: the tool axis is the "
        "face's normal and the part moves with the setup, so the tool and holder meet the part the same way in "
        "every setup (change the tool or the holder, or the feature or its face)\n")
    assert list(tmp_path.iterdir()) == []


def _convert(tmp_path: Path, x: str, *options: str) -> tuple[object, Path]:
    """A 3+2 G-code hole at X ``x`` in the 30° face's frame (the tool along its normal), converted."""
    source = tmp_path / f"hole{x}.ngc"
    source.write_text(f"G21 G90 G17\nG0 X{x} Y0 Z10\nG1 Z-3 F100\nG0 Z10\nM30\n", encoding="utf-8")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(source), "-d", str(out), "--work-plane", f"{WALL}:4",
                                       "--jobs", "1", *options])
    return result, out / source.name


def _collision_line(program: Path) -> list[str]:
    return [ln for ln in program.read_text(encoding="utf-8").split("\n") if ln.startswith("(collision:")]


def test_convert_with_part_checks_the_holder_and_nose_before_writing(tmp_path):
    result, program = _convert(tmp_path, "8.1", "--part", str(WALL))
    assert result.exit_code == 0, result.output
    assert _collision_line(program) == [
        "(collision: clear of the part by at least 1.000 mm: tool in rapids none to check [diameter unknown: its axis, "
        "0 mm radius], not in feeds [it cuts what the CAM program removes], holder 8.635 mm, spindle nose over "
        "11.000 mm)"]                               # its only rapid after the first move retracts along the axis


def test_convert_with_part_refuses_a_holder_in_the_wall_naming_file_line_body_and_depth(tmp_path):
    result, program = _convert(tmp_path, "30", "--part", str(WALL))
    assert result.exit_code == 1
    assert f"  {tmp_path / 'hole30.ngc'}:2: the holder hits the part, 2.446 mm deep (clearance min 1.000 mm)\n" in (
        result.output)
    assert not program.exists()
    result, program = _convert(tmp_path, "30", "--part", str(WALL), "--no-collision-check")
    assert result.exit_code == 0, result.output
    assert _collision_line(program) == ["(collision: not checked [asked not to])"]


def test_convert_without_part_says_so(tmp_path):
    result, program = _convert(tmp_path, "30")
    assert result.exit_code == 0, result.output
    assert _collision_line(program) == ["(collision: not checked [no part given])"]


def _convert_text(tmp_path: Path, name: str, text: str, *options: str) -> tuple[object, Path]:
    """A 3+2 G-code program in the 30° face's frame (Z along its normal), converted against the part."""
    source = tmp_path / name
    source.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(source), "-d", str(out), "--work-plane", f"{WALL}:4",
                                       "--jobs", "1", "--part", str(WALL), *options])
    return result, out / source.name


#: Two holes 3 mm deep, 30 mm apart; between them the G0 of line 4 stays at the first one's depth (through the part).
THROUGH = "G21 G90 G17\nG0 X8.1 Y-15 Z10\nG1 Z-3 F100\nG0 Y15\nG1 Z-4 F100\nG0 Z10\nM30\n"
#: The same holes, the G0 between them above the face (line 5), after a retract along the tool axis (line 4).
ABOVE = "G21 G90 G17\nG0 X8.1 Y-15 Z10\nG1 Z-3 F100\nG0 Z10\nG0 Y15\nG1 Z-3 F100\nG0 Z10\nM30\n"


def test_convert_refuses_a_rapid_that_sweeps_the_tool_through_the_part(tmp_path):
    result, program = _convert_text(tmp_path, "through.ngc", THROUGH)
    assert result.exit_code == 1
    assert result.output.split("\n")[-2] == (
        f"  {tmp_path / 'through.ngc'}:4: the tool hits the part in a rapid, 3.000 mm deep (a rapid may touch the "
        "part, not cut it: 0.050 mm at most; diameter unknown: its axis, 0 mm radius)")
    assert not program.exists()
    assert not (tmp_path / "out").exists() or list((tmp_path / "out").iterdir()) == []


def test_convert_passes_the_rapid_above_the_part_and_states_the_tool_clearance_in_rapids(tmp_path):
    result, program = _convert_text(tmp_path, "above.ngc", ABOVE)
    assert result.exit_code == 0, result.output
    assert _collision_line(program) == [
        "(collision: clear of the part by at least 1.000 mm: tool in rapids 10.000 mm [diameter unknown: its axis, "
        "0 mm radius], not in feeds [it cuts what the CAM program removes], holder 8.635 mm, spindle nose over "
        "11.000 mm)"]


def _cl(points: list[tuple[str, float, float]]) -> str:
    """A CL file in the part's frame, the tool along the 30° face's normal: each point (RAPID or FEED,
    v, height above the face) at u = 8.1 (40 mm from the wall)."""
    lines = ["UNITS/MM", "MULTAX/ON", "TLDATA/MILL,6.0000,0.0000,50.0000,0.0000,0.0000", "LOAD/TOOL,1"]
    for kind, v, height in points:
        tip = FACE.origin + 8.1 * FACE.u + v * FACE.v + height * FACE.normal
        lines += ["RAPID"] if kind == "RAPID" else ["FEDRAT/MMPM,100.0000"]
        lines.append("GOTO/" + ",".join(f"{c:.4f}" for c in tip) + "," + ",".join(f"{c:.7f}" for c in FACE.normal))
    return "\n".join([*lines, "FINI", ""])


@pytest.mark.parametrize("diameter", ["6.0000", "6.0E+00", "+6"])
def test_convert_of_cl_checks_the_rapids_with_the_tldata_diameter(tmp_path, diameter):
    """A TLDATA/ diameter with an exponent (as every CL number may have) was passed over: the tool was then
    checked as its axis ('diameter unknown')."""
    through = _cl([("RAPID", -15, 10), ("FEED", -15, -3), ("RAPID", 15, -3), ("FEED", 15, -4), ("RAPID", 15, 10)])
    through = through.replace("TLDATA/MILL,6.0000,", f"TLDATA/MILL,{diameter},")
    source = tmp_path / "through.cls"
    source.write_text(through, encoding="utf-8")
    result = CliRunner().invoke(main, ["convert", str(source), "-d", str(tmp_path / "out"), "--jobs", "1",
                                       "--part", str(WALL)])
    assert result.exit_code == 1, result.output
    assert result.output.split("\n")[-2] == (
        f"  {source}:10: the tool hits the part in a rapid, 3.000 mm deep (a rapid may touch the part, not cut it: "
        "0.050 mm at most; 6.000 mm diameter)")
    assert not (tmp_path / "out" / "through.ngc").exists()
    above = _cl([("RAPID", -15, 10), ("FEED", -15, -3), ("RAPID", -15, 10), ("RAPID", 15, 10), ("FEED", 15, -3),
                 ("RAPID", 15, 10)])
    source = tmp_path / "above.cls"
    source.write_text(above, encoding="utf-8")
    result = CliRunner().invoke(main, ["convert", str(source), "-d", str(tmp_path / "out"), "--jobs", "1",
                                       "--part", str(WALL)])
    assert result.exit_code == 0, result.output
    assert _collision_line(tmp_path / "out" / "above.ngc") == [
        "(collision: clear of the part by at least 1.000 mm: tool in rapids 10.000 mm [6.000 mm diameter], "
        "not in feeds [it cuts what the CAM program removes], holder 8.635 mm, spindle nose over 11.000 mm)"]


@pytest.mark.parametrize(("diameter", "shown"), [("600", "600"), ("0.001", "0.001"), ("5E+02", "500")])
def test_a_tldata_diameter_outside_the_tools_range_is_bad_input(tmp_path, diameter, shown):
    """TLDATA/MILL,600 (or 0.001) was taken as the tool of the rapid check, though --tool-diameter is held to
    0.01..500 mm (500 itself is within it)."""
    text = _cl([("RAPID", -15, 10), ("FEED", -15, -3), ("RAPID", -15, 10)])
    text = text.replace("TLDATA/MILL,6.0000,", f"TLDATA/MILL,{diameter},")
    source = tmp_path / "big.cls"
    source.write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["convert", str(source), "-d", str(tmp_path / "out"), "--jobs", "1",
                                       "--part", str(WALL)])
    if shown == "500":                                 # taken (its rapids only retract along the tool axis)
        assert result.exit_code == 0, result.output
        assert "[500.000 mm diameter]" in _collision_line(tmp_path / "out" / "big.ngc")[0]
        return
    assert result.exit_code == 2, result.output
    assert result.output.split("\n")[-2] == (
        f"  {source}:3: TLDATA/ states a tool diameter of {shown} mm: a tool for the check in the rapids must be "
        "0.01 to 500 mm")
    assert not (tmp_path / "out" / "big.ngc").exists()


def test_convert_lets_a_rapid_leave_the_face_the_tool_touches_and_states_zero(tmp_path):
    # line 3 leaves the tool's tip on the face; the rapid of line 4 moves it up and sideways from there
    result, program = _convert_text(tmp_path, "touch.ngc", "G21 G90 G17\nG0 X8.1 Y-15 Z10\nG1 Z0 F100\nG0 Y-5 Z5\n"
                                                           "G0 Z10\nM30\n")
    assert result.exit_code == 0, result.output
    assert _collision_line(program) == [
        "(collision: clear of the part by at least 1.000 mm: tool in rapids 0.000 mm [diameter unknown: its axis, "
        "0 mm radius], not in feeds [it cuts what the CAM program removes], holder 8.635 mm, spindle nose over "
        "11.000 mm)"]


def test_the_main_jobs_preview_marks_the_closest_approach_its_check_found(tmp_path):
    pytest.importorskip("matplotlib")
    out, image = tmp_path / "far.ngc", tmp_path / "far.svg"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "8.1,0", "-o", str(out),
                                       "--preview", str(image)])
    assert result.exit_code == 0, result.output
    assert _collision_line(out) == ["(collision: clear of the part by at least 1.000 mm: tool over 11.000 mm, "
                                    "holder 8.635 mm, spindle nose over 11.000 mm)"]
    assert out.read_text(encoding="utf-8").split("\n")[26] == "G1 X-7.9852 U31.1204 V181.1204 W87.7686 F14.2857"
    # the SVG's text is drawn as paths, each with its words in a comment: the header's minimum, its line 24
    assert re.findall(r"<!-- (closest: [^>]*) -->", image.read_text(encoding="utf-8")) == [
        "closest: holder 8.635 mm clear, line 24"]


def test_a_thin_wall_between_the_samples_of_a_long_feed_move_is_caught(tmp_path):
    # a plate 2 mm thick across the holder's way, 40 mm up the tool axis over the face at u = 8.1: the
    # G1 of line 4 translates the head 60 mm along v (verify samples it at its ends, the holder 3.549 mm
    # from the plate at each); the bound |Δtip| + ρθ between them halves the move until the holder is seen at the plate
    import trimesh

    plate = trimesh.creation.box(extents=(10.0, 2.0, 10.0))
    plate.apply_translation(FACE.origin + 8.1 * FACE.u + 40.0 * FACE.normal)
    trimesh.util.concatenate([trimesh.load(str(WALL)), plate]).export(str(tmp_path / "plate.stl"))
    source = tmp_path / "long.ngc"
    source.write_text("G21 G90 G17\nG0 X8.1 Y-30 Z10\nG1 Z5 F100\nG1 Y30 F300\nG0 Z10\nM30\n", encoding="utf-8")
    convert = ["convert", str(source), "--work-plane", f"{WALL}:4", "--jobs", "1"]
    result = CliRunner().invoke(main, [*convert, "-d", str(tmp_path / "out"), "--part", str(tmp_path / "plate.stl")])
    assert result.exit_code == 1, result.output
    # the plate crosses the holder's axis: it is 15 mm (the holder's radius) inside it, which its surface
    # points, straddling the 2 mm plate, saw as 'comes within 0.500 mm'
    assert result.output.split("\n")[-2] == (
        f"  {source}:4: the holder hits the part, 15.000 mm deep (clearance min 1.000 mm)")
    assert not (tmp_path / "out" / "long.ngc").exists()
    samples = np.array([FACE.origin + 8.1 * FACE.u + v * FACE.v + 5.0 * FACE.normal for v in (-30.0, 30.0)])
    ends = clearance(np.asarray(trimesh.load(str(tmp_path / "plate.stl")).triangles), samples,
                     np.tile(FACE.normal, (2, 1)), BODIES, None, np.zeros((0, 3)), clearance_min=DEFAULT_CLEARANCE_MIN)
    assert ends.distance[1] == pytest.approx(3.549, abs=1e-3)       # the two samples alone: clear
    # made without the check, verify finds it on the program's line of that move (line 20: the header has 11 lines)
    result = CliRunner().invoke(main, [*convert, "-d", str(tmp_path / "unchecked"), "--no-collision-check"])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(main, ["verify", str(tmp_path / "unchecked" / "long.ngc"), "--against",
                                       str(tmp_path / "plate.stl")])
    assert result.exit_code == 1
    assert result.output.splitlines()[-1] == "  line 20: the holder hits the part, 15.000 mm deep (clearance min " \
                                              "1.000 mm)"


def test_convert_tool_diameter_gives_a_g_code_tool_its_diameter_and_verify_reads_it_back(tmp_path):
    result, program = _convert_text(tmp_path, "above.ngc", ABOVE, "--tool-diameter", "6")
    assert result.exit_code == 0, result.output
    assert _collision_line(program) == [
        "(collision: clear of the part by at least 1.000 mm: tool in rapids 10.000 mm [6.000 mm diameter], "
        "not in feeds [it cuts what the CAM program removes], holder 8.635 mm, spindle nose over 11.000 mm)"]
    result, program = _convert_text(tmp_path, "through.ngc", THROUGH, "--tool-diameter", "6")
    assert result.exit_code == 1
    assert result.output.split("\n")[-2] == (
        f"  {tmp_path / 'through.ngc'}:4: the tool hits the part in a rapid, 3.000 mm deep (a rapid may touch the "
        "part, not cut it: 0.050 mm at most; 6.000 mm diameter)")
    result, _ = _convert_text(tmp_path, "above.ngc", ABOVE, "--tool-diameter", "600")
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == ("Error: Invalid value for '--tool-diameter': must be from 0.01 to 500 "
                                              "mm (got 600)")


def _tetrahedron(corner: tuple[float, float, float], size: float) -> np.ndarray:
    v = np.array([[0, 0, 0], [size, 0, 0], [0, size, 0], [0, 0, size]], dtype=float) + np.array(corner)
    return np.array([[v[0], v[2], v[1]], [v[0], v[1], v[3]], [v[0], v[3], v[2]], [v[1], v[2], v[3]]])


@pytest.mark.parametrize(("corner", "size", "holder"), [
    ((0.0, 0.0, 70.0), 0.5, -15.0),        # wholly inside, on the axis: its points saw nothing ('3 mm', a bound)
    ((14.0, 0.3, 70.0), 0.8, -0.99679),    # inside the wall, between the surface points (they said 0.361 mm)
    ((2.0, 2.0, 99.5), 0.8, -0.5),          # through the holder's end, 0.5 mm in
    ((16.0, 0.0, 70.0), 0.8, 1.0),          # 1 mm outside: measured on the points, as before
])
def test_a_solid_smaller_than_the_points_spacing_inside_a_body_is_found(corner, size, holder):
    """A feature the surface points straddle, or one wholly inside the body, was missed or understated: the
    solid cylinder's test (collision.cylinder_penetration) finds it wherever the points say clear."""
    bodies = np.array([[3.0, 0.0, 40.0], [15.0, 40.0, 100.0], [40.0, 100.0, 200.0]])
    found = clearance(_tetrahedron(corner, size), np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), bodies, None,
                      np.zeros((0, 3)), clearance_min=1.0, refine_max=4)
    assert found.distance[1] == pytest.approx(holder, abs=1e-5)
    assert found.exact[1]
