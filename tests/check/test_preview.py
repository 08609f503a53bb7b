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
    from prs3_post.check.preview import FaceMark, render_preview

    program = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc"))
    mesh = load_part(WEDGE)
    face, _ = select_face(find_faces(mesh), None)
    report = verify_program(MACHINE, program.moves, setup=SETUP,
                            tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                            length_decimals=4, feed_decimals=4)
    figure = render_preview(report, MACHINE, mesh=mesh.triangles, faces=[FaceMark(face.triangles, "face 4", 0)],
                            rapid_rate=NOMINAL_RAPID_RATE)
    return program.moves, report, figure


def _pieces(data: np.ndarray) -> list[np.ndarray]:
    """A NaN-separated line's pieces."""
    breaks = np.flatnonzero(np.isnan(data[:, 0]))
    finite = [piece[np.isfinite(piece[:, 0])] for piece in np.split(data, breaks)]
    return [piece for piece in finite if len(piece)]


def _limit_lines(ax) -> list[tuple[str, str, float]]:
    """The horizontal lines across a plot (axhline: x 0..1 of the axes): label, colour, y."""
    return [(ln.get_label(), ln.get_color(), float(ln.get_ydata()[0])) for ln in ax.get_lines()
            if list(ln.get_xdata()) == [0, 1] and ln.get_ydata()[0] == ln.get_ydata()[1]]


def _runs(rows: list[int]) -> list[list[int]]:
    """Consecutive rows together."""
    runs: list[list[int]] = []
    for r in rows:
        if runs and runs[-1][-1] == r - 1:
            runs[-1].append(r)
        else:
            runs.append([r])
    return runs


@pytest.mark.parametrize(("gid", "kind"), [("feed 0", MoveKind.FEED), ("rapid 0", MoveKind.RAPID)])
def test_3d_path_is_the_fk_path_of_the_joint_interpolation(drawn, gid, kind):
    """Each run of moves of a kind is one piece; each move in it is FK of (1 - t) q_a + t q_b at evenly spaced
    t, in part coordinates (1e-9 mm)."""
    moves, report, figure = drawn
    line = next(ln for ln in figure.axes[1].get_lines() if ln.get_gid() == gid)
    pieces = _pieces(np.column_stack(line.get_data_3d()))
    joints = np.column_stack([moves.stage, moves.strokes])
    runs = _runs([r for r in np.flatnonzero(moves.kind == kind).tolist() if r > 0])
    assert len(pieces) == len(runs) >= 1
    for run, piece in zip(runs, pieces, strict=True):
        at = 0
        for r in run:
            n = report.replay.intervals[r]           # 8 or more; 1 where the head only translates
            t = np.linspace(0.0, 1.0, n + 1)[:, None]
            q = (1 - t) * joints[r - 1] + t * joints[r]
            fk = forward(MACHINE.geometry, q[:, 2:], q[:, :2])
            assert_allclose(piece[at:at + n + 1], fk.tip - SETUP.shift, atol=1e-9)
            at += n
        assert at + 1 == len(piece)


def test_the_panels_show_program_data_with_the_limits_in_view(drawn):
    from prs3_post.check.timeline import timeline_of

    moves, report, figure = drawn
    titles = [ax.get_title() for ax in figure.axes]
    assert titles[1:] == [
        "(b) tool path on the part by operation (FK replay, part coordinates)",
        "(c) strokes T1..T3 (limits -100..400 mm)", "(d) stage X, Y (limits -300..300 mm)",
        "(e) tool axis tilt (limits max 45°)", "(f) link angles (limits 30..85°)",
        "(g) axis speeds, % of each axis' top speed ([dynamics]: stage 10000, strokes 5000 mm/min)",
        "(h) closest approach to each limit"]
    assert titles[0].startswith("(a) the machine at the worst margin: ")
    _, ax_path, ax_t, ax_xy, ax_tilt, ax_link, ax_speed, ax_bar = figure.axes
    assert [c.get_label() for c in ax_path.collections] == ["face 4", "start", "worst margin, line 8"]
    timeline = timeline_of(report)
    rep = report.replay
    for leg, line in enumerate(ax_t.get_lines()[:3]):    # every sample at its time; each row's end: its words
        assert line.get_label() == f"T{leg + 1}"
        assert_allclose(line.get_xdata(), timeline.time, atol=0)
        assert_allclose(line.get_ydata()[rep.end], moves.strokes[:, leg], atol=0)
    _start, end = row_times(moves, dynamics=MACHINE.dynamics,     # the machine's cycle time, not a nominal rate
                            rapid_rate=NOMINAL_RAPID_RATE)
    assert_allclose(ax_t.get_lines()[0].get_xdata()[rep.end], end, atol=1e-12)
    limits = [(ln.get_label(), ln.get_color(), list(ln.get_ydata())) for ln in ax_t.get_lines()[3:]
              if ln.get_color() == "#d62728" and ln.get_linestyle() == "-"]
    assert limits == [("limit", "#d62728", [-100.0, -100.0]), ("_nolegend_", "#d62728", [400.0, 400.0])]
    low, high = ax_t.get_ylim()
    assert low < -100.0 and high > 400.0 and high - 400.0 == pytest.approx(0.06 * 500.0)
    assert [y for _, _, y in _limit_lines(ax_tilt)] == pytest.approx([45.0])
    assert [y for _, _, y in _limit_lines(ax_link)] == pytest.approx([30.0, 85.0])
    assert [ln.get_label() for ln in ax_speed.get_lines()[:5]] == ["stage X", "stage Y", "T1", "T2", "T3"]
    assert _limit_lines(ax_speed) == [("limit", "#d62728", 0.0), ("_nolegend_", "#d62728", 100.0)]
    assert ax_speed.get_xlabel() == "cycle time (min), the machine's [dynamics]; G0 shaded grey"
    x_line = ax_xy.get_lines()[0]
    assert x_line.get_label() == "stage X"
    assert_allclose(x_line.get_ydata()[rep.end], moves.stage[:, 0], atol=0)
    widths = [patch.get_width() for patch in ax_bar.patches]
    assert_allclose(widths, [c.fraction_of_range for c in report.closest], atol=0)
    assert [t.get_text() for t in ax_bar.get_yticklabels()] == [c.name for c in report.closest]


def test_the_machine_is_drawn_at_the_worst_margins_joints(drawn):
    """Sliders, links, platform and tool of machine_pose at the worst sample's joints; the part moved by its stage."""
    from prs3_post.check.machine_pose import machine_pose
    from prs3_post.check.timeline import timeline_of

    _, report, figure = drawn
    timeline = timeline_of(report)
    worst = min(report.closest, key=lambda c: c.fraction_of_range)
    assert (timeline.worst_series, int(timeline.line[timeline.worst])) == (worst.name, worst.line) == ("T1 stroke", 8)
    joints = report.replay.joints[timeline.worst]
    pose = machine_pose(MACHINE, joints[2:][None], joints[:2][None])
    ax = figure.axes[0]
    assert figure.axes[0].get_title().replace("\n", " ") == (
        "(a) the machine at the worst margin: T1 stroke 24.9 % of its range at line 8 (machine frame: the base "
        "still, the part moved by the stage)")
    by_gid = {artist.get_gid(): artist for artist in ax.get_children() if artist.get_gid()}
    assert_allclose(np.column_stack(by_gid["sliders"]._offsets3d), pose.sliders[0], atol=1e-9)
    for leg in range(3):
        link = np.column_stack(by_gid[f"link {leg}"].get_data_3d())
        assert_allclose(link, [pose.sliders[0, leg], pose.spherical[0, leg]], atol=1e-9)
        assert_allclose(np.column_stack(by_gid[f"rail {leg}"].get_data_3d()), pose.rails[leg], atol=1e-9)
    assert_allclose(np.column_stack(by_gid["tool tip"]._offsets3d)[0], pose.tip[0], atol=1e-9)
    # the tip is where the replay puts it, less the stage: the part and the path move, the base stays
    shift = np.array([joints[0], joints[1], 0.0])
    assert_allclose(pose.tip[0], report.replay.tip[timeline.worst] - shift, atol=1e-6)
    path = np.column_stack(by_gid["tool path"].get_data_3d())
    assert_allclose(path, report.replay.tip - shift, atol=1e-9)
    assert {"base", "platform", "tool", "holder", "spindle nose", "part", "table"} <= set(by_gid)


def test_preview_png_is_a_real_picture(tmp_path):
    out = tmp_path / "small.png"
    result = run("preview", VERIFY / "small.ngc", "--part", WEDGE, "-o", out)
    assert result.exit_code == 0, result.output
    assert result.output == f"prs3-post: wrote {out}\n"
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) < 600_000
    image = matplotlib.image.imread(io.BytesIO(data))
    assert image.shape == (1250, 1700, 4)
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
    ax_xy = render_preview(report, machine, rapid_rate=NOMINAL_RAPID_RATE).axes[3]
    x_colour, y_colour = "#1f77b4", "#ff7f0e"           # each axis' own travel in its colour, dashed
    limit_lines = [(ln.get_label(), ln.get_color(), list(ln.get_ydata())) for ln in ax_xy.get_lines()[2:]
                   if ln.get_color() in (x_colour, y_colour)]
    assert limit_lines == [
        ("stage X limit", x_colour, [-300.0, -300.0]), ("_nolegend_", x_colour, [300.0, 300.0]),
        ("stage Y limit", y_colour, [-20.0, -20.0]), ("_nolegend_", y_colour, [20.0, 20.0]),
    ]
    # beyond each axis' travel is shaded in its colour, to the edge of the view
    low, high = ax_xy.get_ylim()
    bands = []
    for patch in ax_xy.patches:
        y = patch.get_patch_transform().transform(patch.get_path().vertices)[:, 1]
        bands.append((to_hex(patch.get_facecolor()), float(y.min()), float(y.max())))
    beyond = [band for band in bands if band[0] in (x_colour, y_colour)]
    assert beyond == [(x_colour, low, -300.0), (x_colour, 300.0, high),
                      (y_colour, low, -20.0), (y_colour, 20.0, high)]
    low, high = ax_xy.get_ylim()
    assert low < -300.0 < -24.1429 < -20.0 < 300.0 < high   # every limit in view, with the Y move beyond its own
    # out to Y −24 on line 12; line 13 comes back from there: its start is line 12's end point, reported
    # there, and the head only translates on it (stage and equal strokes), so it is sampled at its end
    assert [(p.line, p.kind) for p in report.problems] == [(12, "limit")]


def test_without_dynamics_the_time_axis_says_its_nominal_rapid_rate(drawn):
    from prs3_post.check.preview import render_preview

    moves, report, _ = drawn
    plain = dataclasses.replace(MACHINE, dynamics=None)
    figure = render_preview(dataclasses.replace(report, dynamics=None), plain, rapid_rate=2500.0)
    ax_speed = figure.axes[6]
    assert ax_speed.get_xlabel() == "program time (min), G1 1/F, G0 at 2500 mm/min (no [dynamics]); G0 shaded grey"
    assert ax_speed.get_title() == "(g) axis speeds (no [dynamics]: no top speed)"
    _start, end = row_times(moves, rapid_rate=2500.0)
    assert_allclose(figure.axes[2].get_lines()[0].get_xdata()[report.replay.end], end, atol=1e-12)
    assert end[-1] != row_times(moves, dynamics=MACHINE.dynamics, rapid_rate=NOMINAL_RAPID_RATE)[1][-1]


def test_rapid_rate_is_refused_on_a_machine_with_dynamics(tmp_path):
    result = run("preview", VERIFY / "small.ngc", "-o", tmp_path / "s.png", "--rapid-rate", "3000")
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == ("Error: Invalid value for '--rapid-rate': machine patel2020 has "
                                             "[dynamics]: the time axis shows its cycle time (each axis's top "
                                             "speed); leave it out")
    assert not (tmp_path / "s.png").exists()


def test_a_margin_far_outside_keeps_the_margin_panel_readable(tmp_path):
    from prs3_post.check.preview import render_preview

    program = tmp_path / "far.ngc"                   # T3 at 9999 mm: 1920 % of its range outside
    program.write_text("G93\nG0 X0 Y0 U300 V300 W300\nG1 X1 Y0 U300 V300 W9999 F100\nM2\n")
    moves = load_program(str(program), load_dialect("linuxcnc")).moves
    report = verify_program(MACHINE, moves, setup=SETUP, tolerance=DEFAULT_TOLERANCE,
                            axis_tolerance=DEFAULT_ANGLE_TOLERANCE, length_decimals=4, feed_decimals=4)
    figure = render_preview(report, MACHINE, rapid_rate=NOMINAL_RAPID_RATE)
    ax = next(a for a in figure.axes if a.get_title() == "(h) closest approach to each limit")
    assert ax.get_xlim() == (-1.05, 1.3)
    assert list(ax.get_xticks()) == [-1.0, -0.5, 0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    names = [t.get_text() for t in ax.get_yticklabels()]
    bar = ax.patches[names.index("T3 stroke")]               # one bar per limit, in the labels' order
    assert bar.get_width() == -1.0
    assert "-1919.8 % (line 3)" in [t.get_text() for t in ax.texts]


def test_a_one_line_program_shows_its_one_sample(tmp_path):
    from prs3_post.check.preview import render_preview

    program = tmp_path / "one.ngc"
    program.write_text("G0 X0 Y0 U300 V300 W300\nM2\n")
    moves = load_program(str(program), load_dialect("linuxcnc")).moves
    report = verify_program(MACHINE, moves, setup=SETUP, tolerance=DEFAULT_TOLERANCE,
                            axis_tolerance=DEFAULT_ANGLE_TOLERANCE, length_decimals=4, feed_decimals=4)
    figure = render_preview(report, MACHINE, rapid_rate=NOMINAL_RAPID_RATE)
    ax = next(a for a in figure.axes if a.get_title().startswith("(c) strokes"))
    t1 = next(line for line in ax.get_lines() if line.get_label() == "T1")
    assert (t1.get_marker(), list(t1.get_ydata())) == ("o", [300.0])   # a line through one point draws nothing
