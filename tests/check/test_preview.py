"""prs3-post preview and --preview: the figure shows the FK path, the image is a real picture, errors are clear."""

from __future__ import annotations

import dataclasses
import io
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.check.verify import row_times, verify_program
from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE, NOMINAL_RAPID_RATE
from prs3_post.core.errors import Prs3Error
from prs3_post.core.toolpath import MoveKind
from prs3_post.kinematics import forward
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.faces import find_faces, select_face
from prs3_post.part.setup_transform import Setup
from prs3_post.part.stl import load_part
from prs3_post.readers.program import load_program

matplotlib = pytest.importorskip("matplotlib")

REPO = Path(__file__).resolve().parents[2]
VERIFY = REPO / "fixtures" / "verify"
WEDGE = REPO / "postproc" / "parts" / "patel2020-wedge.stl"
MACHINE = load_machine("patel2020")
SETUP = Setup.resolve(MACHINE)


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def drawn():
    """The small fixture program replayed and drawn on the wedge with its automatic face."""
    from prs3_post.check.preview import render_preview

    program = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc"))
    mesh = load_part(WEDGE)
    face, _ = select_face(find_faces(mesh), None)
    report = verify_program(MACHINE, program.moves, setup=SETUP,
                            tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                            length_decimals=4, feed_decimals=4)
    figure = render_preview(report, MACHINE, mesh=mesh.triangles, face_triangles=face.triangles, face_label="face 4",
                            rapid_rate=NOMINAL_RAPID_RATE)
    return program.moves, report, figure


def _pieces(data: np.ndarray) -> list[np.ndarray]:
    """A NaN-separated line's pieces."""
    breaks = np.flatnonzero(np.isnan(data[:, 0]))
    finite = [piece[np.isfinite(piece[:, 0])] for piece in np.split(data, breaks)]
    return [piece for piece in finite if len(piece)]


@pytest.mark.parametrize(("label", "kind"), [("G1 (feed)", MoveKind.FEED), ("G0 (rapid)", MoveKind.RAPID)])
def test_3d_path_is_the_fk_path_of_the_joint_interpolation(drawn, label, kind):
    """Each move's piece is FK of (1 - t) q_a + t q_b at evenly spaced t, in part coordinates (1e-9 mm)."""
    moves, report, figure = drawn
    line = next(ln for ln in figure.axes[0].get_lines() if ln.get_label() == label)
    pieces = _pieces(np.column_stack(line.get_data_3d()))
    joints = np.column_stack([moves.stage, moves.strokes])
    rows = [r for r in np.flatnonzero(moves.kind == kind).tolist() if r > 0]
    assert len(pieces) == len(rows)
    for r, piece in zip(rows, pieces, strict=True):
        t = np.linspace(0.0, 1.0, len(piece))[:, None]
        q = (1 - t) * joints[r - 1] + t * joints[r]
        fk = forward(MACHINE.geometry, q[:, 2:], q[:, :2])
        assert_allclose(piece, fk.tip - SETUP.shift, atol=1e-9)
        assert len(piece) == report.replay.intervals[r] + 1   # 8 or more; 1 where the head only translates


def test_the_other_panels_show_program_data(drawn):
    moves, report, figure = drawn
    ax3d, ax_t, ax_xy, ax_bar = figure.axes
    assert [c.get_label() for c in ax3d.collections] == ["face 4", "start"]
    assert [ln.get_label() for ln in ax3d.get_lines()] == ["part edges", "G1 (feed)", "G0 (rapid)", "tool axis"]
    _start, end = row_times(moves, dynamics=MACHINE.dynamics,     # the machine's cycle time, not a nominal rate
                            rapid_rate=NOMINAL_RAPID_RATE)
    for leg, line in enumerate(ax_t.get_lines()[:3]):
        assert line.get_label() == f"T{leg + 1}"
        assert_allclose(line.get_xdata()[1::2], end, atol=0)
        assert_allclose(line.get_ydata()[1::2], moves.strokes[:, leg], atol=0)
    assert ax_xy.get_xlabel() == "cycle time (min), the machine's [dynamics]; G0 shaded grey"
    x_line = ax_xy.get_lines()[0]
    assert x_line.get_label() == "X"
    assert_allclose(x_line.get_ydata()[1::2], moves.stage[:, 0], atol=0)
    widths = [patch.get_width() for patch in ax_bar.patches]
    assert_allclose(widths, [c.fraction_of_range for c in report.closest], atol=0)
    assert [t.get_text() for t in ax_bar.get_yticklabels()] == [c.name for c in report.closest]


def test_preview_png_is_a_real_picture(tmp_path):
    out = tmp_path / "small.png"
    result = run("preview", VERIFY / "small.ngc", "--part", WEDGE, "-o", out)
    assert result.exit_code == 0, result.output
    assert result.output == f"prs3-post: wrote {out}\n"
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) < 300_000
    image = matplotlib.image.imread(io.BytesIO(data))
    assert image.shape == (800, 1300, 4)
    grey = image[..., :3].mean(axis=2)
    assert grey.std() > 0.1                             # not blank: white background, dark lines, coloured areas
    colours = np.unique((image[..., :3] * 255).round().astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 500
    assert [p for p in tmp_path.iterdir()] == [out]     # no temp file left behind
    again = tmp_path / "again.png"
    assert run("preview", VERIFY / "small.ngc", "--part", WEDGE, "-o", again).exit_code == 0
    assert again.read_bytes() == data                   # deterministic: no time stamp, no version


def test_main_job_writes_program_and_svg_preview_in_one_step(tmp_path):
    program, image = tmp_path / "hole.ngc", tmp_path / "hole.svg"
    result = run("demo", "--profile", "hole", "--peck", "2", "-o", program, "--preview", image)
    assert result.exit_code == 0, result.output
    assert result.output.splitlines()[-1] == f"prs3-post: wrote {image}"
    svg = image.read_text()
    assert svg.startswith("<?xml") and "<dc:date>" not in svg and "Matplotlib v" not in svg
    assert run("verify", program).exit_code == 0


def test_preview_without_matplotlib_is_a_clear_error(tmp_path, monkeypatch):
    from prs3_post.check.preview import render_preview

    for name in [n for n in sys.modules if n.split(".")[0] in ("matplotlib", "mpl_toolkits")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    program = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc"))
    with pytest.raises(Prs3Error) as caught:
        render_preview(verify_program(MACHINE, program.moves, setup=SETUP,
                                      tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                                      length_decimals=4, feed_decimals=4), MACHINE, rapid_rate=NOMINAL_RAPID_RATE)
    assert str(caught.value) == "preview needs matplotlib: pip install 'prs3-post[plot]'"
    out, ngc = tmp_path / "p.png", tmp_path / "p.ngc"
    for args in (("preview", VERIFY / "small.ngc", "-o", out),
                 ("demo", "--profile", "square", "-o", ngc, "--preview", out)):
        result = run(*args)
        assert (result.exit_code, result.output) == (      # a missing optional dependency: 2 (issue 20)
            2, "prs3-post: error: preview needs matplotlib: pip install 'prs3-post[plot]'\n")
    assert list(tmp_path.iterdir()) == []               # neither the image nor the program


def test_preview_refuses_other_image_types_and_bad_programs(tmp_path):
    result = run("preview", VERIFY / "small.ngc", "-o", tmp_path / "p.jpg")
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == (
        f"Error: Invalid value for '-o' / '--output': the preview must end in .png, .svg or .html, "
        f"got '{tmp_path / 'p.jpg'}'")
    result = run("demo", "--profile", "hole", "-o", tmp_path / "p.ngc", "--preview", tmp_path / "p.txt")
    assert result.exit_code == 2                       # both named '-o' / '--preview': the main job's -o is the program
    assert result.output.splitlines()[-1] == (
        f"Error: Invalid value for '--preview': the image must end in .png or .svg, got '{tmp_path / 'p.txt'}'")
    bad = VERIFY / "bad" / "z_word.ngc"
    result = run("preview", bad, "-o", tmp_path / "p.png")
    assert (result.exit_code, result.output) == (
        2, f"prs3-post: error: {bad}:12: word 'Z' is not an axis of dialect linuxcnc (axes: X Y U V W)\n")
    assert list(tmp_path.iterdir()) == []


def test_preview_help_has_an_example():
    text = run("preview", "--help").output
    assert "  prs3-post preview sq.ngc --part postproc/parts/patel2020-wedge.stl -o sq.png" in text
    assert "'prs3-post[plot]'" in text


def test_stage_panel_draws_each_axis_travel_in_its_own_colour(tmp_path):
    """A Y travel tighter than X's (−20..20 mm, where small.ngc goes to Y −24.1429) is drawn at its own bounds."""
    from matplotlib.colors import to_hex

    from prs3_post.check.preview import render_preview

    text = (REPO / "postproc" / "machines" / "patel2020.toml").read_text()
    assert text.count("travel_y_mm = [-300.0, 300.0]") == 1
    path = tmp_path / "narrow-y.toml"
    path.write_text(text.replace("travel_y_mm = [-300.0, 300.0]", "travel_y_mm = [-20.0, 20.0]"))
    machine = load_machine(str(path))
    program = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc"))
    report = verify_program(machine, program.moves, setup=SETUP,
                            tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                            length_decimals=4, feed_decimals=4)
    ax_xy = render_preview(report, machine, rapid_rate=NOMINAL_RAPID_RATE).axes[2]
    x_colour, y_colour = "#9467bd", "#8c564b"
    limit_lines = [(ln.get_label(), ln.get_color(), ln.get_linestyle(), list(ln.get_ydata()))
                   for ln in ax_xy.get_lines()[2:]]
    assert limit_lines == [
        ("X travel", x_colour, ":", [-300.0, -300.0]), ("_nolegend_", x_colour, ":", [300.0, 300.0]),
        ("Y travel", y_colour, ":", [-20.0, -20.0]), ("_nolegend_", y_colour, ":", [20.0, 20.0]),
    ]
    # beyond each axis' travel is shaded in its colour (y in data units; the bands reach 1e6 mm on)
    bands = []
    for patch in ax_xy.patches:
        y = patch.get_patch_transform().transform(patch.get_path().vertices)[:, 1]
        bands.append((to_hex(patch.get_facecolor()), float(y.min()), float(y.max())))
    beyond = [band for band in bands if band[0] in (x_colour, y_colour)]
    assert beyond == [(x_colour, 300.0, 300.0 + 1e6), (x_colour, -300.0 - 1e6, -300.0),
                      (y_colour, 20.0, 20.0 + 1e6), (y_colour, -20.0 - 1e6, -20.0)]
    low, high = ax_xy.get_ylim()
    assert low < -24.1429 < -20.0 < high                # the Y limit is in view, with the Y move beyond it
    # out to Y −24 on line 12; line 13 comes back from there: its start is line 12's end point, reported
    # there, and the head only translates on it (stage and equal strokes), so it is sampled at its end
    assert [(p.line, p.kind) for p in report.problems] == [(12, "limit")]


def test_without_dynamics_the_time_axis_says_its_nominal_rapid_rate(drawn):
    from prs3_post.check.preview import render_preview

    moves, report, _ = drawn
    plain = dataclasses.replace(MACHINE, dynamics=None)
    figure = render_preview(dataclasses.replace(report, dynamics=None), plain, rapid_rate=2500.0)
    ax_xy = figure.axes[2]
    assert ax_xy.get_xlabel() == "program time (min), G1 1/F, G0 at 2500 mm/min (no [dynamics]); G0 shaded grey"
    _start, end = row_times(moves, rapid_rate=2500.0)
    assert_allclose(ax_xy.get_lines()[0].get_xdata()[1::2], end, atol=0)
    assert end[-1] != row_times(moves, dynamics=MACHINE.dynamics, rapid_rate=NOMINAL_RAPID_RATE)[1][-1]


def test_rapid_rate_is_refused_on_a_machine_with_dynamics(tmp_path):
    result = run("preview", VERIFY / "small.ngc", "-o", tmp_path / "s.png", "--rapid-rate", "3000")
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == ("Error: Invalid value for '--rapid-rate': machine patel2020 has "
                                             "[dynamics]: the time axis shows its cycle time (each axis's top "
                                             "speed); leave it out")
    assert not (tmp_path / "s.png").exists()
