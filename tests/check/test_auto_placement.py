"""Automatic placement (issue 9 §3): `--part-origin auto` and `--part-rotation auto` choose the setup with
the largest worst-case margin, each limit's margin normalized by its range.

The chosen setup is checked against a brute-force oracle written here (every row's limits at every setup
of a coarse grid around it, through the pipeline's own placement and the exact IK), the program against
every limit (`verify`), and the messages and headers byte for byte.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from prs3_post.app.job import JobSpec, job_in_part_frame, run_job, run_operations
from prs3_post.check.placement import place
from prs3_post.cli.main import main
from prs3_post.cli.run import _job_specs
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import LimitError, ReachError
from prs3_post.core.toolpath import Toolpath
from prs3_post.emit.header_read import read_header
from prs3_post.kinematics import IKModel, inverse
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.machine.model import Machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.limits import check_limits
from prs3_post.post.pipeline import machine_path, place_toolpath
from prs3_post.readers.jobfile import read_job_file
from prs3_post.toolpaths import Coolant, Cutting, Direction, Entry, HoleParams, ProfileParams, RoundShape, Side
from prs3_post.toolpaths.work import HoleJob, ProfileJob

REPO = Path(__file__).resolve().parents[2]
WEDGE = str(REPO / "postproc" / "parts" / "patel2020-wedge.stl")
EXAMPLE_JOB = REPO / "fixtures" / "jobs" / "example.toml"
CORPUS = REPO.parent / "shared" / "corpus" / "stl"
SLOPE = str(CORPUS / "ssg_slope.stl")
ANGLE_BLOCK = str(CORPUS / "trimesh_angle_block.STL")
FEATURETYPE = str(CORPUS / "trimesh_featuretype.STL")
needs_corpus = pytest.mark.skipif(not CORPUS.is_dir() and not os.environ.get("CI"), reason=f"no corpus at {CORPUS}")
MACHINE = load_machine("patel2020")
#: The range a limit without a lower bound is normalized by starts here (the issue: "normalized by its range").
NATURAL_LOW = {"tilt": 0.0, "condition number": 1.0}


def invoke(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="prs3-post")


# ----------------------------------------------------------------------------- the brute-force oracle


def worst_margins(machine: Machine, pieces: list[Toolpath], lengths: list[float], rotation_deg: float,
                  origins: np.ndarray) -> np.ndarray:
    """(S,) — the smallest normalized margin over every row and every limit, for each part origin (S, 3)
    at ``rotation_deg``: each piece placed and subdivided as the pipeline does, all origins in one IK call."""
    worst = np.full(len(origins), np.inf)
    for piece, length in zip(pieces, lengths, strict=True):
        tooled = replace(machine, geometry=replace(machine.geometry, tool_length=length))
        path = machine_path(tooled, piece, Setup((0.0, 0.0, 0.0), rotation_deg),
                            tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
        n = len(path)
        tip = (path.tip[None, :, :] + origins[:, None, :]).reshape(-1, 3)
        axis = np.tile(path.axis, (len(origins), 1))
        report = check_limits(tooled, inverse(tooled.geometry, tip, axis, model=IKModel.EXACT), axis)
        natural = np.array([NATURAL_LOW.get(name, -math.inf) for name in report.names])
        span = report.high - np.where(np.isfinite(report.low), report.low, natural)
        normalized = np.nan_to_num(report.margin / span, nan=-np.inf).reshape(len(origins), n, -1)
        worst = np.minimum(worst, normalized.min(axis=(1, 2)))
    return worst


def assert_no_better_setup_nearby(machine: Machine, pieces: list[Toolpath], lengths: list[float], setup: Setup, *,
                                  turns: tuple[float, ...] = (0.0,)) -> float:
    """The chosen setup's worst normalized margin is at least that of every setup of a coarse grid around
    it: the origin ±10 mm along each axis (27 origins) at each rotation of ``turns`` (degrees) from it."""
    chosen = float(worst_margins(machine, pieces, lengths, setup.rotation_deg, np.array([setup.origin]))[0])
    steps = np.array(np.meshgrid(*[[-10.0, 0.0, 10.0]] * 3, indexing="ij")).reshape(3, -1).T
    for turn in turns:
        grid = worst_margins(machine, pieces, lengths, setup.rotation_deg + turn, np.array(setup.origin) + steps)
        assert grid.max() <= chosen + 1e-9, (turn, steps[int(np.argmax(grid))], grid.max(), chosen)
    return chosen


def hole_spec(part: str, **changes: object) -> JobSpec:
    spec = JobSpec(
        part=part, units="mm", face=None,
        work=HoleJob(HoleParams(depth=5.0, peck=0.0, dwell=0.0, clearance=2.0, retract=10.0, reapproach_gap=0.5)),
        at_uv=np.zeros((0, 2)), at_xyz=np.zeros((0, 3)),
        cutting=Cutting(tool_diameter=6.0, feed=300.0, plunge_feed=100.0, spindle_rpm=3000.0, coolant=Coolant.FLOOD,
                        tool_number=1),
        machine=MACHINE, dialect=load_dialect("linuxcnc"), setup=Setup.resolve(MACHINE), auto_origin=True)
    return replace(spec, **changes)


def round_spec() -> JobSpec:
    work = ProfileJob(RoundShape(diameter=30.0), ProfileParams(
        side=Side.ON, depth=2.0, step_down=1.0, direction=Direction.CLIMB, entry=Entry.RAMP,
        ramp_angle=math.radians(3.0), clearance=2.0, retract=10.0))
    return hole_spec(WEDGE, work=work, auto_rotation=True)


# ----------------------------------------------------------------------------- the demo wedge


def test_wedge_hole_origin_auto_is_the_best_on_the_grid_and_fits():
    result = run_job(hole_spec(WEDGE))
    assert result.setup == Setup((-79.4, -190.9, -1028.4), 0.0)
    assert result.post.limits.ok.all()
    worst = assert_no_better_setup_nearby(MACHINE, [result.path_part], [MACHINE.geometry.tool_length], result.setup)
    assert result.placement is not None
    assert result.placement.worst.normalized == pytest.approx(worst, abs=1e-12)
    assert [(m.name, m.column) for m in result.placement.margins] == [
        ("stroke", "T1 stroke"), ("link angle", "θ3 link angle"), ("tilt", "tilt"),
        ("condition number", "condition number"), ("stage X", "stage X"), ("stage Y", "stage Y")]


def test_wedge_round_origin_and_rotation_auto_is_the_best_on_the_grid():
    result = run_job(round_spec())
    assert result.setup == Setup((39.7, -207.4, -1050.8), 30.0)
    assert result.post.limits.ok.all()
    worst = assert_no_better_setup_nearby(MACHINE, [result.path_part], [MACHINE.geometry.tool_length], result.setup,
                                          turns=(-30.0, -5.0, 0.0, 5.0, 30.0))
    assert worst == pytest.approx(0.375937, abs=1e-6)
    # the rotation helps: at 0° the best origin leaves a smaller worst margin
    fixed = run_job(replace(round_spec(), auto_rotation=False))
    assert fixed.placement is not None and fixed.placement.worst.normalized < worst - 0.03


def test_the_header_and_the_summary_state_the_choice(tmp_path):
    out = tmp_path / "w.ngc"
    done = invoke("demo", "--profile", "hole", "--part-origin", "auto", "-o", out)
    assert done.exit_code == 0, done.stderr
    margins = ("stroke 176.1936 mm [0.352, leg 1], link angle 20.7846 deg [0.378, leg 3], tilt 18.4349 deg [0.410], "
               "condition number 7.9966 [0.889], stage X 296.6263 mm [0.494], stage Y 299.9571 mm [0.500]")
    choice = ("part origin chosen automatically for the largest worst-case margin, 0.352 of the range of the stroke "
              f"of leg 1. Margins [fraction of the range]: {margins}")
    setup = "part origin at machine [-79.4000, -190.9000, -1028.4000] mm, rotation 0.0000 deg about z"
    assert done.stderr.splitlines()[0] == f"prs3-post: setup: {setup}; {choice}"
    lines = out.read_text().splitlines()
    assert lines[5] == f"(setup: {setup})"
    assert lines[6] + lines[7] == ("(placement: part origin chosen automatically for the largest worst-case margin, "
                                   "0.352 of the range of the stroke of leg 1. Margins [fraction of the range]: "
                                   "stroke 176.1936 mm [0.352, leg 1], link angle 20.7846 deg [0.378, leg 3], tilt "
                                   "18.4349 deg)(  [0.410], condition number 7.9966 [0.889], stage X 296.6263 mm "
                                   "[0.494], stage Y 299.9571 mm [0.500])")
    header = read_header(str(out))
    assert header is not None and header.setup == Setup((-79.4, -190.9, -1028.4), 0.0)
    checked = invoke("verify", out, "--against", WEDGE)
    assert checked.exit_code == 0, checked.stdout


def test_same_input_same_program(tmp_path):
    texts = []
    for name in ("a.ngc", "b.ngc"):
        out = tmp_path / name
        done = invoke("demo", "--profile", "square", "--part-origin", "auto", "--part-rotation", "auto", "-o", out)
        assert done.exit_code == 0, done.stderr
        texts.append(out.read_text())
    assert texts[0] == texts[1]
    assert texts[0].splitlines()[5] == ("(setup: part origin at machine [40.7000, -207.4000, -1049.9000] mm, "
                                        "rotation 30.0000 deg about z)")


def test_rotation_auto_with_a_given_origin_keeps_the_origin():
    chosen = place(MACHINE, run_job(hole_spec(WEDGE)).path_part, origin=(-79.4, -190.9, -1028.4),
                   tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert chosen.setup.origin == (-79.4, -190.9, -1028.4)
    assert (chosen.origin_chosen, chosen.rotation_chosen) == (False, True)
    assert chosen.worst.margin > 0.0


# ----------------------------------------------------------------------------- no setup fits


def _machine_file(tmp_path: Path, old: str, new: str) -> Path:
    text = (REPO / "postproc" / "machines" / "patel2020.toml").read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "narrow.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def test_a_tilt_no_setup_can_keep_is_named_with_how_much_it_misses(tmp_path):
    machine = _machine_file(tmp_path, "max_tilt_deg = 45.0", "max_tilt_deg = 20.0")
    out = tmp_path / "w.ngc"
    done = invoke("demo", "--profile", "hole", "--part-origin", "auto", "--part-rotation", "auto",
                  "--machine", machine, "-o", out)
    assert (done.exit_code, done.stdout) == (1, "")
    assert done.stderr == (
        "prs3-post: error: no part origin and rotation about z puts every point inside the machine's limits: the "
        "tilt cannot be met, by 6.5651 deg at best (hole 1 approach: tilt 26.5651 deg is above the maximum 20.0000 "
        "deg by 6.5651 deg); the best setup found: part origin at machine [39.1725, -208.3239, -1050.0407] mm, "
        "rotation 30.0000 deg about z\n")
    assert not out.exists()


def test_a_stroke_range_no_origin_can_keep_says_so_and_that_turning_the_part_fits(tmp_path):
    machine = _machine_file(tmp_path, "stroke_mm = [-100.0, 400.0]", "stroke_mm = [0.0, 120.0]")
    out = tmp_path / "w.ngc"
    done = invoke("demo", "--profile", "hole", "--part-origin", "auto", "--machine", machine, "-o", out)
    assert (done.exit_code, done.stdout) == (1, "")
    assert done.stderr == (
        "prs3-post: error: no part origin puts every point inside the machine's limits: the stroke of leg 1 cannot "
        "be met, by 13.7902 mm at best (hole 1 approach: T1 stroke -13.7902 mm is below the minimum 0.0000 mm by "
        "13.7902 mm); the best setup found: part origin at machine [-79.3804, -190.8571, -938.4162] mm, rotation "
        "0.0000 deg about z; turning the part about z would fit: part origin at machine [39.2000, -208.3000, "
        "-960.0000] mm, rotation 30.0000 deg about z (worst margin 0.023 of the range of the stroke of leg 1)\n")
    assert not out.exists()
    done = invoke("demo", "--profile", "hole", "--part-origin", "auto", "--part-rotation", "auto",
                  "--machine", machine, "-o", out)
    assert done.exit_code == 0, done.stderr
    assert read_header(str(out)).setup == Setup((39.2, -208.3, -960.0), 30.0)


def test_the_library_raises_a_limit_error_with_the_same_message():
    narrow = replace(MACHINE, limits=replace(MACHINE.limits, max_tilt=math.radians(20.0)))
    path = run_job(hole_spec(WEDGE)).path_part
    with pytest.raises(LimitError) as caught:
        place(narrow, path, rotation_deg=0.0, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == (
        "no part origin puts every point inside the machine's limits: the tilt cannot be met, by 6.5651 deg at best "
        "(hole 1 approach: tilt 26.5651 deg is above the maximum 20.0000 deg by 6.5651 deg); the best setup found: "
        "part origin at machine [-79.3804, -190.8571, -1028.4162] mm, rotation 0.0000 deg about z")


@pytest.mark.parametrize(("rotation", "scope"), [(0.0, "this rotation about z, at any part origin"),
                                                  (None, "any rotation about z tried")])
def test_an_axis_the_head_cannot_reach_at_any_setup_is_a_reach_error(rotation, scope):
    """Links of 225 mm cannot reach a 30° tool axis (the guide radius is 392 mm), wherever the part is."""
    short = replace(MACHINE, geometry=replace(MACHINE.geometry, link_length=225.0))
    axis = np.array([math.sin(math.radians(30.0)), 0.0, math.cos(math.radians(30.0))])
    path = Toolpath(kind=np.array([0, 1]), tip=np.array([2.0 * axis, np.zeros(3)]), axis=np.tile(axis, (2, 1)),
                    feed=np.array([0.0, 100.0]), source=np.arange(2), source_labels=("clearance", "feed"))
    with pytest.raises(ReachError) as caught:
        place(short, path, rotation_deg=rotation, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == (f"clearance: the head cannot reach this tool axis at {scope} (a link cannot reach "
                                 "its joint; 2 points unreachable)")


# ----------------------------------------------------------------------------- options


def test_auto_is_for_making_a_program_not_for_reading_one(tmp_path):
    out = tmp_path / "w.ngc"
    assert invoke("demo", "--profile", "hole", "-o", out).exit_code == 0
    done = invoke("verify", out, "--part-origin", "auto")
    assert done.exit_code == 2
    assert done.stderr.splitlines()[-1] == (
        "Error: Invalid value for '--part-origin': auto chooses the setup when a program is made; a program is read "
        "with the setup its header states (or the one given as numbers)")
    done = invoke("demo", "--profile", "hole", "--part-origin", "automatic", "-o", out)
    assert done.exit_code == 2
    assert done.stderr.splitlines()[-1] == ("Error: Invalid value for '--part-origin': expected 3 plain decimal "
                                            "numbers X,Y,Z, got 'automatic'")


# ----------------------------------------------------------------------------- the corpus, `--part-origin auto` only


@needs_corpus
@pytest.mark.parametrize(("part", "options", "setup"), [
    (SLOPE, (), Setup((-106.5, 1.6, -728.4), 0.0)),
    (ANGLE_BLOCK, ("--part-units", "inch", "--up", "y", "--at", "5,0"), Setup((0.0, -70.5, -755.8), 0.0)),
])
def test_a_corpus_hole_works_with_part_origin_auto_and_nothing_else(tmp_path, part, options, setup):
    out = tmp_path / "h.ngc"
    done = invoke(part, "--profile", "hole", *options, "--part-origin", "auto", "--no-collision-check", "-o", out)
    assert done.exit_code == 0, done.stderr
    header = read_header(str(out))
    assert header is not None and header.setup == setup
    checked = invoke("verify", out, "--against", part, "--no-collision-check")   # made without it (the slope: a tunnel)
    assert checked.exit_code == 0, checked.stdout
    units = "inch" if "inch" in options else "mm"
    spec = hole_spec(part, units=units, up="y" if "y" in options else "z",
                     at_uv=np.array([[5.0, 0.0]]) if "--at" in options else np.zeros((0, 2)), collision_check=False)
    result = run_job(spec)
    assert result.setup == setup
    assert_no_better_setup_nearby(MACHINE, [result.path_part], [MACHINE.geometry.tool_length], setup)


@needs_corpus
def test_a_part_whose_only_face_faces_down_keeps_the_face_error(tmp_path):
    out = tmp_path / "f.ngc"
    plain = invoke(FEATURETYPE, "--part-units", "inch", "--profile", "hole", "-o", out)
    auto = invoke(FEATURETYPE, "--part-units", "inch", "--profile", "hole", "--part-origin", "auto",
                  "--part-rotation", "auto", "-o", out)
    assert (auto.exit_code, auto.stderr) == (plain.exit_code, plain.stderr) == (2, auto.stderr)
    assert "faces down" in auto.stderr
    assert not out.exists()


# ----------------------------------------------------------------------------- job files


def test_the_example_job_with_auto_setup_is_the_best_on_the_grid(tmp_path):
    text = EXAMPLE_JOB.read_text(encoding="utf-8")
    text = text.replace('"../parts/twofaces.stl"', f'"{REPO / "fixtures" / "parts" / "twofaces.stl"}"')
    text = text.replace('"tools.tbl"', f'"{EXAMPLE_JOB.parent / "tools.tbl"}"')
    text = text.replace("part_origin = [-100.0, -200.0, -970.0]", 'part_origin = "auto"')
    text = text.replace("part_rotation_deg = 0.0", 'part_rotation_deg = "auto"')
    job = tmp_path / "job.toml"
    job.write_text(text, encoding="utf-8")
    out = tmp_path / "job.ngc"
    done = invoke("job", job, "-o", out)
    assert done.exit_code == 0, done.stderr
    assert read_header(str(out)).setup == Setup((133.8, -160.9, -1038.5), 47.5)
    assert invoke("verify", out).exit_code == 0
    specs = _job_specs(read_job_file(str(job)))
    result = run_operations(specs)
    assert result.post.limits.ok.all()
    fixed = tuple(replace(s, setup=result.setup, auto_origin=False, auto_rotation=False) for s in specs)
    pieces, lengths = job_in_part_frame(fixed, list(result.operations), result.triangles)
    assert len(pieces) == 4                            # hole, lift, turn, round
    worst = assert_no_better_setup_nearby(MACHINE, pieces, lengths, result.setup, turns=(-5.0, 0.0, 5.0))
    assert worst == pytest.approx(1.0 / 3.0, abs=1e-6)   # the 30° face's tilt: 15° of 45° to spare (float32 STL)


def test_the_search_rows_hold_every_limit_extreme():
    """The rotation search evaluates only the rows that can hold a limit's extreme (per tool axis, the
    lowest and highest tip and the farthest along 36 horizontal directions): at a multiple of 10° their
    extremes are those of every row; between, the stage's are within 0.4 % of its spread."""
    from prs3_post.check.placement import _support

    rng = np.random.default_rng(7)
    tilt = np.radians(rng.choice([0.0, 20.0, 35.0], size=3000))
    azimuth = np.radians(rng.choice([0.0, 90.0, 200.0], size=3000))
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    around = rng.uniform(0.0, 2.0 * np.pi, 3000)                     # tips on a circle: no corner holds an extreme
    tips = np.column_stack([85.0 * np.cos(around), 85.0 * np.sin(around), rng.uniform(-30.0, 30.0, 3000)])
    path = Toolpath(kind=np.zeros(3000, dtype=np.int64), tip=tips, axis=axis,
                    feed=np.full(3000, 100.0), source=np.arange(3000))
    keep = _support(path)
    assert 20 < keep.sum() < 400
    for rotation, allowed in ((0.0, 0.0), (10.0, 0.0), (37.0, 0.004 * 170.0)):
        placed = place_toolpath(path, Setup((0.0, 0.0, -700.0), rotation))
        value = check_limits(MACHINE, inverse(MACHINE.geometry, placed.tip, placed.axis), placed.axis).value
        np.testing.assert_allclose(value[keep].max(axis=0), value.max(axis=0), atol=allowed + 1e-9)
        np.testing.assert_allclose(value[keep].min(axis=0), value.min(axis=0), atol=allowed + 1e-9)
