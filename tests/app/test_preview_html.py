"""`preview -o view.html`: the decimation, the part a header names, and the command's answers."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.app.preview_html import MAX_STOPS, decimate_path, header_part, path_points, stop_rows
from prs3_post.app.verify import open_program
from prs3_post.cli.main import main

pytest.importorskip("plotly")

REPO = Path(__file__).resolve().parents[2]
WEDGE = REPO / "postproc" / "parts" / "patel2020-wedge.stl"
JOB = REPO / "fixtures" / "jobs" / "example.toml"


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args])


def page_data(path: Path) -> dict:
    text = path.read_text(encoding="utf-8")
    return json.loads(re.search(r'<script id="prs3-data" type="application/json">(.*?)</script>', text,
                                re.DOTALL).group(1).replace("<\\/", "</"))


def test_stops_keep_every_extreme_of_a_long_program():
    rng = np.random.default_rng(3)
    joints = rng.normal(size=(100_000, 5))
    keep = np.array([12_345, 67_891])
    rows = stop_rows(joints, keep)
    assert MAX_STOPS <= len(rows) <= MAX_STOPS + 2 + 10
    assert {0, 99_999, 12_345, 67_891} <= set(rows.tolist())
    for column in joints.T:
        assert {int(column.argmin()), int(column.argmax())} <= set(rows.tolist())
    assert np.all(np.diff(rows) > 0)
    assert stop_rows(joints[:10], keep[:0]).tolist() == list(range(10))     # short: every line


def test_path_points_start_each_run_where_its_move_starts():
    # rows 0..4, two samples each; rows 1, 2 and 4 selected: two runs
    points = np.arange(30.0).reshape(10, 3)
    row_of = np.repeat(np.arange(5), 2)
    first, end = np.arange(0, 10, 2), np.arange(1, 10, 2)
    line = path_points(points, row_of, first, end, np.array([False, True, True, False, True]))
    assert line[:5, 0].tolist() == [3.0, 6.0, 9.0, 12.0, 15.0]                # from row 0's end through row 2
    assert np.isnan(line[5]).all()
    assert_allclose(line[6:9, 0], [21.0, 24.0, 27.0], atol=0)                  # row 4 from row 3's end
    assert np.isnan(line[9]).all() and len(line) == 10


def test_decimated_path_keeps_the_ends_of_every_piece():
    line = np.column_stack([np.arange(1000.0), np.zeros(1000), np.zeros(1000)])
    line[500] = np.nan
    kept = decimate_path(line, 100)
    assert len(kept) <= 110
    assert kept[0, 0] == 0.0 and kept[-1, 0] == 999.0
    gap = int(np.flatnonzero(np.isnan(kept[:, 0]))[0])
    assert (kept[gap - 1, 0], kept[gap + 1, 0]) == (499.0, 501.0)


def test_the_header_part_is_found_beside_the_program_or_shipped(tmp_path, monkeypatch):
    program = tmp_path / "sq.ngc"
    assert run("demo", "--profile", "square", "-o", program, "-q").exit_code == 0
    header = open_program(str(program)).header
    monkeypatch.chdir(tmp_path)
    assert header_part(str(program), header) == (str(REPO / "postproc" / "parts" / WEDGE.name), WEDGE.name)
    shutil.copy(WEDGE, tmp_path / WEDGE.name)
    assert header_part(str(program), header) == (str(tmp_path / WEDGE.name), WEDGE.name)
    (tmp_path / WEDGE.name).write_text("solid other\nendsolid other\n")    # another file by that name: not it
    assert header_part(str(program), header)[0] == str(REPO / "postproc" / "parts" / WEDGE.name)
    assert header_part(str(program), None) == (None, "")


def test_the_example_job_draws_both_faces_and_marks_both_operations(tmp_path):
    program, view = tmp_path / "example.ngc", tmp_path / "example.html"
    assert run("job", JOB, "-o", program, "-q").exit_code == 0
    result = run("preview", program, "-o", view, "--part", REPO / "fixtures" / "parts" / "twofaces.stl")
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {view}\n")
    data = page_data(view)
    names = [t["name"] for t in data["scene"]["data"]]
    assert names[:3] == ["part", "op 1: hole on face 5", "op 2: round on face 6"]
    assert {"op 1: G1", "op 1: G0", "op 2: G1", "op 2: G0"} <= set(names)
    assert any(n.startswith("closest: ") for n in names) and any(n.startswith("worst margin: ") for n in names)
    annotations = [a["text"] for a in data["plots"]["layout"]["annotations"]]
    assert {"op 1", "op 2", "T1", "T2"} <= set(annotations)
    context = open_program(str(program))
    assert len(data["stops"]["line"]) == len(context.program.moves)          # short: every line is a stop
    assert data["stops"]["line"] == context.program.moves.source.tolist()


def test_a_program_without_header_or_part_and_a_missing_header_part(tmp_path):
    program = tmp_path / "one.ngc"
    program.write_text("G0 X0 Y0 U300 V300 W300\nM2\n")
    view = tmp_path / "one.html"
    result = run("preview", program, "-o", view)
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {view}\n")
    data = page_data(view)
    assert data["stops"]["line"] == [1] and data["stops"]["text"] == ["G0 X0 Y0 U300 V300 W300"]
    assert not [t for t in data["scene"]["data"] if t["type"] == "mesh3d"]       # no part
    job = tmp_path / "job.ngc"
    assert run("job", JOB, "-o", job, "-q").exit_code == 0
    result = run("preview", job, "-o", view)
    assert result.exit_code == 0
    assert result.output == ("prs3-post: note: the part the header names (twofaces.stl) is not beside the program, "
                             "here or among the shipped parts: the view has no part (give it with --part)\n"
                             f"prs3-post: wrote {view}\n")


def test_the_view_refuses_to_overwrite_its_program_and_other_suffixes(tmp_path):
    program = tmp_path / "v.html"
    assert run("demo", "--profile", "hole", "-o", program, "-q").exit_code == 0
    before = program.read_bytes()
    result = run("preview", program, "-o", program)
    assert result.exit_code == 2
    assert result.output == (f"prs3-post: error: {program}: is also the input PROGRAM.ngc: writing --output would "
                             "destroy it (choose another file)\n")
    assert program.read_bytes() == before
    result = run("preview", program, "-o", tmp_path / "v.htm")
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == (
        f"Error: Invalid value for '-o' / '--output': the preview must end in .png, .svg or .html, "
        f"got '{tmp_path / 'v.htm'}'")


def test_without_plotly_the_command_says_how_to_install_it(tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_plotly(name, *args, **kwargs):
        if name.startswith("plotly"):
            raise ImportError(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_plotly)
    result = run("preview", REPO / "fixtures" / "verify" / "small.ngc", "-o", tmp_path / "v.html")
    assert (result.exit_code, result.output) == (
        2, "prs3-post: error: the HTML view needs plotly: pip install 'prs3-post[plot]'\n")
    assert list(tmp_path.iterdir()) == []


def test_a_decimated_view_stops_at_the_closest_approach_the_worst_margin_and_each_boundary(tmp_path, monkeypatch):
    import prs3_post.app.preview_html as preview_html

    monkeypatch.setattr(preview_html, "MAX_STOPS", 40)
    program, view = tmp_path / "example.ngc", tmp_path / "example.html"
    assert run("job", JOB, "-o", program, "-q").exit_code == 0
    result = run("preview", program, "-o", view, "--part", REPO / "fixtures" / "parts" / "twofaces.stl")
    assert result.exit_code == 0
    data = page_data(view)
    lines = data["stops"]["line"]
    assert 40 <= len(lines) < 60 and lines == sorted(lines)
    names = [t["name"] for t in data["scene"]["data"]]
    closest = next(n for n in names if n.startswith("closest: "))
    worst = next(n for n in names if n.startswith("worst margin: "))
    assert (closest, worst) == ("closest: tool over 3.182 mm clear, line 631",
                                "worst margin: stage X 18.5 % of its range, line 57")
    assert {631, 57} <= set(lines)
    moves = open_program(str(program)).program.moves.source.tolist()
    assert moves[0] in lines and moves[-1] in lines
    notes = re.findall(r"<div class='note'>(.*?)</div>", view.read_text(encoding="utf-8"))
    assert notes == [f"{len(moves)} moves: the slider stops at {len(lines)} of them (evenly spaced, with every "
                     "axis&#x27;s extremes, each operation&#x27;s and tool change&#x27;s first line, the worst margin "
                     "and the closest approach)"]


def test_a_line_where_the_head_does_not_assemble_has_no_machine(tmp_path):
    import base64

    program, view = tmp_path / "bad.ngc", tmp_path / "bad.html"
    program.write_text("G0 X0 Y0 U300 V300 W300\nG0 X0 Y0 U-900 V900 W300\nG0 X0 Y0 U250 V300 W300\nM2\n")
    result = run("preview", program, "-o", view)
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {view}\n")
    data = page_data(view)
    machine = data["machine"]
    rows = np.frombuffer(base64.b64decode(machine["points"]["bdata"]), dtype="<f4").reshape(3, -1, 3)
    assert machine["per_stop"] == rows.shape[1]
    assert np.isnan(rows[1]).all() and np.isfinite(rows[0]).all(axis=1).sum() > 20
    assert data["stops"]["line"] == [1, 2, 3]
    # the box that keeps plotly's camera finite when no machine point is
    assert data["machine_scene"]["data"][-1]["name"] == "box"
