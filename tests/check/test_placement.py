"""A limit or reach error of the main job says the setup and, where a translation fits, a part origin
that was checked to work (issue 7 §6, first bullet)."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

import prs3_post.app.job as job_module
from prs3_post.app.job import JobSpec, check_job, run_job
from prs3_post.check.placement import PlacementLimitError, shift_ranges, suggest_origin
from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import LimitError
from prs3_post.core.toolpath import MoveKind, Toolpath
from prs3_post.kinematics import IKModel
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.limits import check_limits, within_limits
from prs3_post.post.pipeline import machine_path, post_process
from prs3_post.toolpaths import Coolant, Cutting, HoleParams
from prs3_post.toolpaths.work import HoleJob

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus" / "stl"
SLOPE = str(CORPUS / "ssg_slope.stl")
MACHINE = load_machine("patel2020")
DEFAULT = Setup.resolve(MACHINE)


def invoke(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="prs3-post")


def _drill(axis: np.ndarray, at: np.ndarray) -> Toolpath:
    """A 3-row drilling path along ``axis`` into ``at`` (part coordinates)."""
    tips = np.array([at + 10 * axis, at + 2 * axis, at])
    return Toolpath(kind=np.array([MoveKind.RAPID, MoveKind.RAPID, MoveKind.FEED]), tip=tips,
                    axis=np.tile(axis, (3, 1)), feed=np.array([0.0, 0.0, 100.0]), source=np.arange(3), events=(),
                    source_labels=("approach", "clearance", "feed"))


@pytest.mark.skipif(not CORPUS.is_dir() and not os.environ.get("CI"), reason=f"no corpus at {CORPUS}")
def test_slope_part_fails_with_the_default_setup_and_works_with_the_suggested_origin(tmp_path):
    """Without the collision check (the slope is in a tunnel: below) the origin that keeps every limit works."""
    out = tmp_path / "h.ngc"
    failed = invoke(SLOPE, "--profile", "hole", "--no-collision-check", "-o", out)
    assert failed.exit_code == 1
    message = failed.stderr.strip()
    assert message.startswith("prs3-post: error: hole 1 approach: T2 stroke 460.0985 mm is above the maximum "
                              "400.0000 mm by 60.0985 mm (5 points outside limits in all); setup: part origin at "
                              "machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z; a part "
                              "origin at machine [")
    suggested = re.fullmatch(r".*: (--part-origin=\S+)", message)
    assert suggested is not None, message
    assert not out.exists()
    # a tunnel: no holder enters it
    again = invoke(SLOPE, "--profile", "hole", suggested.group(1), "--no-collision-check", "-o", out)
    assert again.exit_code == 0, again.stderr
    assert invoke("verify", out, "--against", SLOPE, "--no-collision-check").exit_code == 0


@pytest.mark.skipif(not CORPUS.is_dir() and not os.environ.get("CI"), reason=f"no corpus at {CORPUS}")
def test_no_origin_is_suggested_where_the_collision_check_fails_there(tmp_path):
    """Issue 20 §3: the origin that keeps every limit was suggested, and following it gave "the tool hits the
    part, 4.890 mm deep" with no next step. A translation cannot change a collision: the message says which
    check fails at that origin and what to change instead, and offers no --part-origin."""
    out = tmp_path / "h.ngc"
    failed = invoke(SLOPE, "--profile", "hole", "-o", out)
    assert (failed.exit_code, failed.stderr) == (1, (
        "prs3-post: error: hole 1 approach: T2 stroke 460.0985 mm is above the maximum 400.0000 mm by 60.0985 mm "
        "(5 points outside limits in all); setup: part origin at machine [-100.0000, -200.0000, -970.0000] mm, "
        "rotation 0.0000 deg about z; a part origin at machine [-106.5, 1.6, -728.4] mm puts every point inside "
        "the machine's limits, but the collision check fails there: hole 1 approach: the tool hits the part, "
        "4.890 mm deep (clearance min 1.000 mm); no setup changes that (the part and the tool axes move "
        "together): try another --at (or --face), or a smaller --tool-diameter\n"))
    assert not out.exists()
    # there, the collision itself says the same next step
    there = invoke(SLOPE, "--profile", "hole", "--part-origin=-106.5,1.6,-728.4", "-o", out)
    assert (there.exit_code, there.stderr) == (1, (
        "prs3-post: error: hole 1 approach: the tool hits the part, 4.890 mm deep (clearance min 1.000 mm); no "
        "setup changes that (the part and the tool axes move together): try another --at (or --face), or a "
        "smaller --tool-diameter\n"))
    assert not out.exists()


def test_the_suggestion_is_the_centre_of_the_allowed_shifts():
    axis = np.array([math.sin(math.radians(30.0)), 0.0, math.cos(math.radians(30.0))])
    part_path = _drill(axis, np.array([0.0, 0.0, 600.0]))       # 600 mm too high: strokes far below their minimum
    with pytest.raises(LimitError) as caught:
        post_process(MACHINE, part_path, DEFAULT, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert "stroke" in str(caught.value)
    texts = suggest_origin(MACHINE, part_path, DEFAULT, tolerance=0.002, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert texts is not None
    origin = tuple(float(t) for t in texts)
    assert texts == tuple(f"{v:.1f}" for v in origin)            # 0.1 mm steps where they pass
    placed = Setup(origin)
    post_process(MACHINE, part_path, placed, tolerance=DEFAULT_TOLERANCE,
                 angle_tolerance=DEFAULT_ANGLE_TOLERANCE)                                 # passes: no exception
    ranges = shift_ranges(MACHINE, machine_path(MACHINE, part_path, placed,
                                                tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE))
    assert ranges is not None
    assert_allclose(ranges.sum(axis=1), 0.0, atol=0.2)            # centred, up to the 0.1 mm rounding


def test_no_suggestion_where_the_tool_axis_breaks_a_limit():
    """A 50° tilt breaks max_tilt (45°) wherever the part is: no origin is offered."""
    axis = np.array([math.sin(math.radians(50.0)), 0.0, math.cos(math.radians(50.0))])
    part_path = _drill(axis, np.array([0.0, 200.0, 300.0]))
    assert suggest_origin(MACHINE, part_path, DEFAULT, tolerance=0.002, angle_tolerance=DEFAULT_ANGLE_TOLERANCE) is None


def test_a_tilt_at_the_limit_to_the_last_bit_is_not_a_violation():
    """[1, 0, 1]/√2 is 45° (max_tilt) to the last bit, but its arccos is 1.1e-16 rad more: it was refused,
    "above the maximum 45.0000 deg by 0.0000 deg". Limits are compared with LIMIT_TOLERANCE."""
    axis = np.array([[1.0, 0.0, 1.0]]) / math.sqrt(2.0)
    ik = kinematics_of(MACHINE).inverse(np.array([[0.0, 0.0, -700.0]]), axis, model=IKModel.EXACT)
    report = check_limits(MACHINE, ik, axis)
    tilt = report.names.index("tilt")
    assert report.value[0, tilt] > MACHINE.limits.max_tilt            # the float noise is there ...
    assert report.ok.all() and report.margin[0, tilt] == 0.0         # ... and within the limit
    assert within_limits(MACHINE, ik, axis)
    beyond = np.array([[math.sin(math.radians(45.001)), 0.0, math.cos(math.radians(45.001))]])
    ik = kinematics_of(MACHINE).inverse(np.array([[0.0, 0.0, -700.0]]), beyond, model=IKModel.EXACT)
    assert not check_limits(MACHINE, ik, beyond).ok.any() and not within_limits(MACHINE, ik, beyond)


def _wedge_hole_at_the_machine_origin() -> JobSpec:
    return JobSpec(
        part=str(REPO / "fixtures" / "parts" / "wedge.stl"), units="mm", face=None,
        work=HoleJob(HoleParams(depth=5.0, peck=0.0, dwell=0.0, clearance=2.0, retract=10.0, reapproach_gap=0.5)),
        at_uv=np.zeros((0, 2)), at_xyz=np.zeros((0, 3)),
        cutting=Cutting(tool_diameter=6.0, feed=300.0, plunge_feed=100.0, spindle_rpm=3000.0, coolant=Coolant.FLOOD,
                        tool_number=1),
        machine=MACHINE, dialect=load_dialect("linuxcnc"), setup=Setup((0.0, 0.0, 0.0)))


def test_run_job_raises_the_suggestion_as_data():
    spec = _wedge_hole_at_the_machine_origin()
    with pytest.raises(PlacementLimitError) as caught:
        run_job(spec)
    assert caught.value.setup == Setup((0.0, 0.0, 0.0))
    assert caught.value.suggested_origin == ("-79.4", "-190.9", "-1028.4")
    assert str(caught.value).endswith("; a part origin at machine [-79.4, -190.9, -1028.4] mm puts every point "
                                      "inside the machine's limits")


def test_a_job_checked_in_chunks_fails_with_the_whole_paths_error(monkeypatch):
    """check_job posts the toolpath POST_ROWS rows at a time; the error of a chunk is the one
    run_job raises for the whole path (its count of bad points is of every row, not of those so far)."""
    spec = _wedge_hole_at_the_machine_origin()
    with pytest.raises(PlacementLimitError) as whole:
        run_job(spec)
    monkeypatch.setattr(job_module, "POST_ROWS", 2)
    with pytest.raises(PlacementLimitError) as chunked:
        check_job(spec)
    assert str(chunked.value) == str(whole.value)
    assert re.search(r"\(\d+ points outside limits in all\)", str(chunked.value))


def test_the_suggestion_subdivides_with_the_runs_angle_tolerance(monkeypatch):
    """convert --angle-tolerance: the origin suggested after a limit error is checked on the path subdivided as
    the run subdivides it (it used the default angle tolerance whatever the run's was)."""
    import prs3_post.check.placement as placement

    seen: list[float] = []
    real = placement.post_process

    def spy(*args, **kwargs):
        seen.append(kwargs["angle_tolerance"])
        return real(*args, **kwargs)

    monkeypatch.setattr(placement, "post_process", spy)
    axis = np.array([math.sin(math.radians(30.0)), 0.0, math.cos(math.radians(30.0))])
    part_path = _drill(axis, np.array([0.0, 0.0, 600.0]))
    assert suggest_origin(MACHINE, part_path, DEFAULT, tolerance=0.002, angle_tolerance=math.radians(0.5)) is not None
    assert seen == [math.radians(0.5)]
