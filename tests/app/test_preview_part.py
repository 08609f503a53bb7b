"""The `preview` use case: which part a program is drawn on (app.preview.program_part), in the picture too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from prs3_post.app.preview import program_part
from prs3_post.app.verify import open_program
from prs3_post.cli.main import main

pytest.importorskip("matplotlib")

REPO = Path(__file__).resolve().parents[2]
WEDGE = REPO / "postproc" / "parts" / "patel2020-wedge.stl"


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_the_given_part_wins_else_the_headers_is_looked_for(tmp_path, monkeypatch):
    program = tmp_path / "sq.ngc"
    assert run("demo", "--profile", "square", "-o", program, "-q").exit_code == 0
    header = open_program(str(program)).header
    monkeypatch.chdir(tmp_path)
    assert program_part(str(program), "other.stl", header) == ("other.stl", "")
    assert program_part(str(program), None, header) == (str(WEDGE), WEDGE.name)
    assert program_part(str(program), None, None) == (None, "")


def test_the_picture_of_a_demo_program_without_its_part_beside_it_draws_the_shipped_part(tmp_path, monkeypatch):
    import prs3_post.check.preview as drawing

    program, picture = tmp_path / "demo.ngc", tmp_path / "demo.png"
    assert run("demo", "--profile", "square", "-o", program, "-q").exit_code == 0
    assert not (tmp_path / WEDGE.name).exists()
    monkeypatch.chdir(tmp_path)
    drawn = []
    real = drawing.figure_bytes

    def keep(figure, fmt):
        drawn.append(figure)
        return real(figure, fmt)

    monkeypatch.setattr(drawing, "figure_bytes", keep)
    result = run("preview", program, "-o", picture)
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {picture}\n")
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    figure = drawn[0]
    assert figure._suptitle.get_text() == "patel2020-wedge.stl: demo.ngc, machine patel2020, 20 moves (ok)"
    panel = next(ax for ax in figure.axes if ax.get_title().startswith("(b) tool path on the part"))
    edges = next(ln for ln in panel.get_lines() if ln.get_label() == "part edges")
    x = np.asarray(edges.get_data_3d()[0], dtype=float)
    assert np.isfinite(x).sum() >= 12                 # the wedge's outline, not an empty line
    assert np.nanmax(x) - np.nanmin(x) == pytest.approx(100.0)  # the wedge is 100 mm long in x
    assert next(c.get_label() for c in panel.collections) == "face 4 (26.57°)"


CLS = REPO / "fixtures" / "cam" / "mech491_APT_SimpleMillPlane.cls"
BRACKET = REPO / "fixtures" / "parts" / "bracket.stl"


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    """A program converted from a CL file onto the bracket (its header records the setup, not a part's SHA-256)."""
    out = tmp_path_factory.mktemp("converted") / "smp.ngc"
    result = run("convert", CLS, "-o", out, "--part-origin", "auto", "--part", BRACKET, "-q")
    assert result.exit_code == 0, result.output
    return out


def test_a_converted_program_is_drawn_on_the_part_given_at_its_setup_with_verifys_closest_approach(converted):
    from prs3_post.app.preview import preview_part_of
    from prs3_post.app.verify import CamPart

    context = open_program(str(converted))
    drawn = preview_part_of(context, str(BRACKET), face=None, units="mm", up="z", given={}, html=False)
    assert (drawn.path, drawn.named, drawn.from_header, drawn.faces) == (str(BRACKET), "", False, ())
    assert isinstance(drawn.against, CamPart) and drawn.against.setup == context.setup
    assert drawn.mesh is not None and drawn.mesh.shape == (12, 3, 3)     # the bracket's 12 triangles
    verified = run("verify", converted, "--part", BRACKET)
    assert verified.exit_code == 0
    assert "    holder         over 7.984 mm  line 57\n" in verified.output
    face = preview_part_of(context, str(BRACKET), face=3, units="mm", up="z", given={}, html=False)
    assert [f.index for f in face.faces] == [3]


def test_the_picture_of_a_converted_program_draws_the_part_and_the_holders_closest_approach(converted, tmp_path,
                                                                                            monkeypatch):
    import prs3_post.check.preview as drawing

    drawn = []
    real = drawing.figure_bytes

    def keep(figure, fmt):
        drawn.append(figure)
        return real(figure, fmt)

    monkeypatch.setattr(drawing, "figure_bytes", keep)
    picture = tmp_path / "smp.png"
    result = run("preview", converted, "--part", BRACKET, "-o", picture)
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {picture}\n")
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    figure = drawn[0]
    assert figure._suptitle.get_text() == "bracket.stl: smp.ngc, machine patel2020, 103 moves (ok)"
    panel = next(ax for ax in figure.axes if ax.get_title().startswith("(b) tool path on the part"))
    assert "closest: holder over 7.984 mm clear, line 57" in [c.get_label() for c in panel.collections]
    edges = next(ln for ln in panel.get_lines() if ln.get_label() == "part edges")
    assert np.isfinite(np.asarray(edges.get_data_3d()[0], dtype=float)).sum() >= 12   # the bracket's outline
    assert not [c for c in panel.collections if c.get_label().startswith("face ")]     # no face asked for


def test_the_view_of_a_converted_program_has_the_parts_triangles_and_the_closest_approach(converted, tmp_path):
    import base64
    import json
    import re

    pytest.importorskip("plotly")
    view = tmp_path / "smp.html"
    result = run("preview", converted, "--part", BRACKET, "-o", view)
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {view}\n")
    text = view.read_text(encoding="utf-8")
    data = json.loads(re.search(r'<script id="prs3-data" type="application/json">(.*?)</script>', text,
                                re.DOTALL).group(1).replace("<\\/", "</"))
    traces = data["scene"]["data"]
    part = next(t for t in traces if t["name"] == "part")
    assert part["type"] == "mesh3d"
    assert len(np.frombuffer(base64.b64decode(part["i"]["bdata"]), dtype="<i4")) == 12   # the bracket's triangles
    assert [t["name"] for t in traces if t["type"] == "mesh3d"] == ["part"]              # no face highlighted
    assert "closest: holder over 7.984 mm clear, line 57" in [t["name"] for t in traces]


def test_a_main_jobs_program_keeps_its_part_check(tmp_path):
    program = tmp_path / "sq.ngc"
    assert run("demo", "--profile", "square", "-o", program, "-q").exit_code == 0
    result = run("preview", program, "--part", BRACKET, "-o", tmp_path / "sq.png")
    assert result.exit_code == 2
    assert result.output == (
        f"prs3-post: error: {program}:4: --part: {BRACKET} (SHA-256 "
        "9b364a1df781be05d7324fb17e0b772b8f94e195297681438a6f364bfa8da9bf) is not the part the program was made "
        "from: its header names patel2020-wedge.stl (SHA-256 "
        "2e6933ec5ebd47f6b894d89f5b6cd77bf2854fed2465f0679a3f148e80163537)\n")
    assert not (tmp_path / "sq.png").exists()
    wrong = run("preview", program, "--part", WEDGE, "--face", "3", "--part-units", "inch", "-o", tmp_path / "sq.png")
    assert wrong.exit_code == 2
    assert wrong.output.endswith("Error: --face (header: auto), --part-units (header: mm): contradict the program's "
                                 "header; leave them out to use the header's values\n")
    assert not (tmp_path / "sq.png").exists()


def test_a_one_line_program_is_one_move_in_both_titles(tmp_path, monkeypatch):
    import prs3_post.check.preview as drawing

    program = tmp_path / "one.ngc"
    program.write_text("G0 X0 Y0 U300 V300 W300\nM2\n")
    drawn = []
    monkeypatch.setattr(drawing, "figure_bytes", lambda figure, fmt: drawn.append(figure) or b"")
    assert run("preview", program, "-o", tmp_path / "one.png", "-q").exit_code == 0
    assert drawn[0]._suptitle.get_text() == "one.ngc, machine patel2020, 1 move (ok)"
    pytest.importorskip("plotly")
    assert run("preview", program, "-o", tmp_path / "one.html", "-q").exit_code == 0
    assert "<title>one.ngc: machine patel2020, 1 move</title>" in (tmp_path / "one.html").read_text(encoding="utf-8")


def test_a_program_without_a_header_is_drawn_on_any_part_with_no_face_unless_asked(tmp_path):
    program, picture = tmp_path / "one.ngc", tmp_path / "one.png"
    program.write_text("G0 X0 Y0 U300 V300 W300\nM2\n")      # the bracket has no face the main job would take
    result = run("preview", program, "--part", BRACKET, "-o", picture)
    assert (result.exit_code, result.output) == (0, f"prs3-post: wrote {picture}\n")
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from prs3_post.app.preview import preview_part_of

    context = open_program(str(program))
    drawn = preview_part_of(context, str(BRACKET), face=None, units="mm", up="z", given={}, html=False)
    assert (drawn.faces, drawn.against, drawn.mesh.shape) == ((), None, (12, 3, 3))
    asked = preview_part_of(context, str(BRACKET), face=3, units="mm", up="z", given={}, html=False)
    assert [f.index for f in asked.faces] == [3]
