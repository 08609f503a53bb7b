"""Tool, holder and spindle nose against the part: a hole near a wall beside a 30° face is refused
(the holder hits the wall), the same hole 40 mm from the wall passes."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from prs3_post.cli import main

WALL = Path(__file__).resolve().parents[1] / "fixtures" / "parts" / "wall30.stl"


def test_hole_near_the_wall_is_refused_naming_the_step_body_and_depth(tmp_path):
    out = tmp_path / "near.ngc"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "30,0", "-o", str(out)])
    assert result.exit_code == 1
    assert result.output == ("prs3-post: error: hole 1 approach: the holder hits the part, 2.498 mm deep "
                             "(clearance min 1.000 mm)\n")
    assert not out.exists()


def test_hole_forty_mm_from_the_wall_passes_and_the_header_says_the_clearances(tmp_path):
    out = tmp_path / "far.ngc"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "8.1,0", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_text().split("\n")[12] == ("(collision: clear of the part by at least 1.000 mm: tool over 26.480 mm, "
                                               "holder over 3.978 mm, spindle nose 22.859 mm)")


def test_no_collision_check_is_stated_in_the_header(tmp_path):
    out = tmp_path / "unchecked.ngc"
    result = CliRunner().invoke(main, ["run", str(WALL), "--profile", "hole", "--at", "30,0", "--no-collision-check",
                                       "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_text().split("\n")[12] == "(collision: not checked [asked not to])"
