"""The preview of real programs: every operation's face and path in its colour, the tool changes on the time
axis, coinciding strokes told apart, the tilt of a variable-axis file, no label cut off, long programs decimated."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_hex

from prs3_post.app.preview import preview_figure, preview_part
from prs3_post.app.verify import open_program, tool_lengths_of

pytest.importorskip("matplotlib")

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "golden"


def _figure(name: str, part: str | None = None, **options):
    context = open_program(str(GOLDEN / name))
    mesh, faces = (None, ())
    if part is not None:
        mesh, faces = preview_part(str(REPO / "fixtures" / "parts" / part), context.header, None, units="mm", up="z")
    figure = preview_figure(context.program, context.machine, context.setup, dialect=context.dialect, mesh=mesh,
                            faces=faces, rapid_rate=5000.0, tool_lengths=tool_lengths_of(context.header),
                            header=context.header, **options)
    return context, mesh, faces, figure


@pytest.fixture(scope="module")
def job():
    """The two-face example job: drill (T1) on face 5, round (T2) on face 6."""
    return _figure("twofaces-job-example.ngc", "twofaces.stl")


def test_every_operations_face_is_highlighted_in_its_colour(job):
    _, _, faces, figure = job
    ax = figure.axes[1]
    drawn = {c.get_gid(): c for c in ax.collections if (c.get_gid() or "").startswith("face")}
    assert [f.index for f in faces] == [5, 6]
    assert sorted(drawn) == ["face 0", "face 1"]
    assert [drawn[f"face {k}"].get_label() for k in range(2)] == ["face 5 (20.00°), op 1", "face 6 (30.00°), op 2"]
    assert [to_hex(drawn[f"face {k}"].get_facecolor()[0]) for k in range(2)] == ["#1f5fbf", "#2ca02c"]
    figure.canvas.draw()
    for k, face in enumerate(faces):                    # each face's own triangles, a polygon each
        assert len(drawn[f"face {k}"].get_paths()) == len(face.triangles) > 0
    paths = {ln.get_gid(): to_hex(ln.get_color()) for ln in ax.get_lines() if ln.get_gid()}
    assert paths == {"feed 0": "#1f5fbf", "rapid 0": "#1f5fbf", "feed 1": "#2ca02c", "rapid 1": "#2ca02c"}
    labels = [ln.get_label() for ln in ax.get_lines() if ln.get_gid() in ("feed 0", "feed 1")]
    assert labels == ["1: drill 2 holes D6.000 on face 5",
                      "2: round D20.000 mm at [u 0.000, v 0.000] with tool D8.000…"]


def test_tool_changes_and_operations_are_marked_on_the_time_axis(job):
    """Operation boundaries solid, tool changes dashed, at the time the second operation's first move starts,
    labelled with their lines (58 and 60 for the round and its T2)."""
    context, _, _, figure = job
    ax = figure.axes[2]
    vertical = [(float(ln.get_xdata()[0]), ln.get_linestyle()) for ln in ax.get_lines()
                if ln.get_color() == "#333333"]
    from prs3_post.check.verify import row_times

    moves = context.program.moves
    _, end = row_times(moves, rapid_rate=5000.0, dynamics=context.machine.dynamics)
    assert vertical == [(0.0, "-"), (0.0, "--"), (pytest.approx(end[22]), "-"), (pytest.approx(end[22]), "--")]
    texts = [t.get_text() for t in ax.texts]
    assert texts[:2] == [" op 1 line 25, T1 line 27 ", " op 2 line 58, T2 line 60 "]
    for panel in figure.axes[2:7]:                      # every plot over time has them
        assert sum(ln.get_color() == "#333333" for ln in panel.get_lines()) == 4


def test_no_label_is_cut_off(job):
    """Every text drawn (titles, legends, tick labels in view, the boundary and margin labels) lies inside the
    figure, and inside its plot where it is clipped to it."""
    for figure in (job[3], _figure("convert-mech491_APT_Variable_Axis.ngc")[3]):
        _assert_nothing_cut(figure)


def _assert_nothing_cut(figure) -> None:
    from matplotlib.text import Text

    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    hidden = set()                                      # tick labels outside their axis' view are not drawn
    for ax in figure.axes:
        for axis in [ax.xaxis, ax.yaxis, *([ax.zaxis] if hasattr(ax, "zaxis") else [])]:
            low, high = sorted(axis.get_view_interval())
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not low - 1e-9 <= tick.get_loc() <= high + 1e-9:
                    hidden |= {id(tick.label1), id(tick.label2)}
    width, height = figure.bbox.width, figure.bbox.height
    cut = []
    for text in figure.findobj(Text):
        if id(text) in hidden or not text.get_visible() or not text.get_text().strip():
            continue
        box = text.get_window_extent(renderer)
        outside = box.x0 < -1 or box.y0 < -1 or box.x1 > width + 1 or box.y1 > height + 1
        if text.get_clip_on() and text.get_clip_box() is not None and text.axes is not None:
            frame = text.axes.bbox
            outside |= box.x0 < frame.x0 - 1 or box.x1 > frame.x1 + 1 or box.y1 > frame.y1 + 1
        if outside:
            cut.append(text.get_text())
    assert cut == []


def test_coinciding_strokes_are_told_apart_and_a_constant_stays_flat():
    """A 3-axis program (vertical tool): T1 = T2 = T3 on every line, drawn thick to thin in three styles, said
    equal in the legend; the y axis spans the stroke limits, not the few mm the strokes move."""
    _, _, _, figure = _figure("convert-mech491_APT_SimpleMillPlane.ngc")
    ax = figure.axes[2]
    t1, t2, t3 = ax.get_lines()[:3]
    assert np.array_equal(t1.get_ydata(), t2.get_ydata()) and np.array_equal(t1.get_ydata(), t3.get_ydata())
    assert [ln.get_label() for ln in (t1, t2, t3)] == ["T1", "T2 (= T1)", "T3 (= T1)"]
    assert [ln.get_linewidth() for ln in (t1, t2, t3)] == [2.6, 1.8, 1.4]      # thick to thin
    assert t1.get_linestyle() == "-" and t2.get_linestyle() == t3.get_linestyle() == "--"  # solid, dashed, dotted
    assert t2._unscaled_dash_pattern != t3._unscaled_dash_pattern
    low, high = ax.get_ylim()
    assert low < -100.0 and high > 400.0


def test_a_variable_axis_file_has_its_tilt_and_link_angles_over_time():
    """Variable_Axis (NX, a varying tool axis): the tilt goes up to 22.5° against the 45° limit."""
    _, _, _, figure = _figure("convert-mech491_APT_Variable_Axis.ngc")
    tilt, link = figure.axes[4], figure.axes[5]
    values = tilt.get_lines()[0].get_ydata()
    assert float(np.nanmax(values)) == pytest.approx(22.5, abs=0.5) and float(np.nanmin(values)) < 1.0
    assert tilt.get_ylim()[1] > 45.0
    assert [ln.get_label() for ln in link.get_lines()[:3]] == ["θ1", "θ2", "θ3"]


def test_a_long_program_is_drawn_from_its_decimated_samples(job):
    """With at most 200 samples per plot, the strokes keep their extremes (each one's min and max)."""
    from prs3_post.app.verify import verify_loaded
    from prs3_post.check.preview import render_preview

    context, _, _, full = job
    report = verify_loaded(context.program, context.machine, context.setup, context.dialect, tolerance=0.002,
                           tool_lengths=tool_lengths_of(context.header))
    small = render_preview(report, context.machine, rapid_rate=5000.0, max_samples=200)
    for whole, thin in zip(full.axes[2].get_lines()[:3], small.axes[2].get_lines()[:3], strict=True):
        assert len(thin.get_ydata()) <= 200 < len(whole.get_ydata()) == 1852
        assert thin.get_ydata().max() == whole.get_ydata().max()
        assert thin.get_ydata().min() == whole.get_ydata().min()
