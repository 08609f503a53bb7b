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
