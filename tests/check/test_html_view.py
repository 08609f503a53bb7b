"""The HTML view: its builders, and the page in a real browser (Debian's chromium through Playwright)."""

from __future__ import annotations

import io
import json
import re

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.app.verify import open_program
from prs3_post.check.html_view import (
    MACHINE_PIECES,
    PART_COLOUR,
    Stops,
    ViewData,
    machine_frames,
    render_view,
    surface_from_triangles,
)
from prs3_post.check.machine_pose import machine_pose
from prs3_post.cli.main import main
from prs3_post.kinematics.replay import joints_of
from prs3_post.machine.loading import load_machine

pytest.importorskip("plotly")

MACHINE = load_machine("patel2020")


def _rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])


def test_machine_frames_are_the_machine_pose_on_the_table():
    joints = np.array([[300.0, 300.0, 300.0], [250.0, 320.0, 280.0]])
    stage = np.array([[0.0, 0.0], [12.5, -4.0]])
    pose = machine_pose(MACHINE, joints, stage)
    points = machine_frames(pose).points
    assert points.shape == (2, sum(p[1] for p in MACHINE_PIECES), 3)
    names = [p[0] for p in MACHINE_PIECES]
    start = dict(zip(names, np.cumsum([0] + [p[1] for p in MACHINE_PIECES])[:-1].tolist(), strict=True))
    shift = np.array([12.5, -4.0, 0.0])
    # the tool: from its tip up its axis, the stage added; the sliders where the legs' strokes put them
    tool = points[1, start["tool"]:start["tool"] + 2]
    assert_allclose(tool[0], pose.tip[1] + shift, atol=1e-9)
    assert_allclose(points[1, start["sliders"]:start["sliders"] + 3], pose.sliders[1] + shift, atol=1e-9)
    assert_allclose(points[0, start["sliders"] + 2], [0.0, 392.013, -300.0], atol=1e-3)   # leg 3 at azimuth 90°
    links = points[1, start["links"]:start["links"] + 9].reshape(3, 3, 3)
    assert_allclose(links[:, 1], pose.spherical[1] + shift, atol=1e-9)
    assert np.isnan(links[:, 2]).all()                                   # a break between the links
    assert_allclose(np.linalg.norm(links[:, 1] - links[:, 0], axis=1), 482.0, atol=1e-6)   # U, the link length


def test_a_joint_row_without_a_pose_draws_nothing():
    pose = machine_pose(MACHINE, np.array([[300.0, 300.0, 300.0], [-900.0, 900.0, 300.0]]))
    points = machine_frames(pose).points
    assert np.isfinite(points[0]).all(axis=1).sum() > 20 and np.isnan(points[1]).all()


def test_surface_merges_shared_corners():
    square = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], dtype=float)
    s = surface_from_triangles("part", square, PART_COLOUR)
    assert s.vertices.shape == (4, 3) and s.triangles.tolist() == [[0, 2, 3], [0, 3, 1]]
    assert_allclose(s.vertices[s.triangles], square, atol=0)


def _tiny_view() -> ViewData:
    pose = machine_pose(MACHINE, np.array([[300.0, 300.0, 300.0]]))
    return ViewData(title="a <b> & c", machine=machine_frames(pose),
                    stops=Stops(line=np.array([7]), time=np.array([0.0]), text=("G0 </script> U300",),
                                value_names=("U",), values=np.array([[300.0]])))


def test_the_page_holds_plotly_and_its_data_and_nothing_ends_its_scripts_early():
    page = render_view(_tiny_view())
    assert page.count("</script>") == 3                                  # plotly.js, the data, the view's own
    assert "<title>a &lt;b&gt; &amp; c</title>" in page
    data = json.loads(re.search(r'<script id="prs3-data" type="application/json">(.*?)</script>', page,
                                re.DOTALL).group(1))
    assert data["stops"] == {"line": [7], "time": [0.0], "text": ["G0 </script> U300"], "names": ["U"],
                             "values": [[300.0]]}
    assert data["machine"]["per_stop"] == sum(p[1] for p in MACHINE_PIECES)
    assert "cdn.plot.ly" not in page.split("<script>")[-1]


def test_without_plotly_the_view_says_how_to_install_it(monkeypatch):
    import builtins

    from prs3_post.core.errors import MissingDependency

    real = builtins.__import__

    def no_plotly(name, *args, **kwargs):
        if name.startswith("plotly"):
            raise ImportError(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_plotly)
    with pytest.raises(MissingDependency) as caught:
        render_view(_tiny_view())
    assert str(caught.value) == "the HTML view needs plotly: pip install 'prs3-post[plot]'"


# ---------------------------------------------------------------------------- in a real browser


@pytest.fixture(scope="module")
def square_view(tmp_path_factory):
    """The demo's square, its view written by the command (its header's part found among the shipped ones)."""
    folder = tmp_path_factory.mktemp("view")
    program, view = folder / "sq.ngc", folder / "sq.html"
    for args in (("demo", "--profile", "square", "-o", program, "-q"), ("preview", program, "-o", view, "-q")):
        result = CliRunner().invoke(main, [str(a) for a in args])
        assert (result.exit_code, result.output) == (0, "")
    return program, view


def test_the_view_in_a_browser(chromium, square_view):
    """One page load: offline, no error, WebGL drawn, the machine moves with the slider to where our FK
    puts it, the plots' cursor follows, and the screenshot shows the part and the path."""
    program, view = square_view
    url = view.as_uri()
    page = chromium.new_page(viewport={"width": 1400, "height": 900})
    requests, problems = [], []
    page.on("request", lambda r: requests.append(r.url))
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    page.route("**/*", lambda route: route.continue_() if route.request.url == url else route.abort())
    try:
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=15000)
        assert "WebGL is not supported" not in page.inner_text("body")
        assert page.evaluate("document.querySelectorAll('#view-scene canvas').length") >= 1
        for scene in ("view-part", "view-machine"):     # the part's scene, and the machine's stacked on it
            assert page.evaluate(f"!!document.getElementById('{scene}')._fullLayout.scene._scene.glplot")

        read = ("(k) => { const t = document.getElementById('view-machine').data[k]; return [t.x, t.y, t.z]; }")
        tool = len(MACHINE_PIECES) - 1                   # the last machine trace: the tool
        before = np.array(page.evaluate(read, tool), dtype=float).T
        stops = page.evaluate("window.prs3View.stops")
        k = stops // 2
        page.locator("#slider").fill(str(k))
        after = np.array(page.evaluate(read, tool), dtype=float).T
        assert np.abs(after - before).max() > 1.0        # the tool moved
        # where our forward kinematics puts it at that line (float32 in the page)
        line = int(re.match(r"line (\d+)", page.inner_text("#info")).group(1))
        context = open_program(str(program))
        row = int(np.flatnonzero(context.program.moves.source == line)[0])
        joints = joints_of(context.program.moves)[row]
        expected = machine_frames(machine_pose(context.machine, joints[None, 2:], joints[None, :2])).points[0, -2:]
        assert_allclose(after, expected, atol=2e-3)
        cursor = page.evaluate("document.getElementById('view-plots').layout.shapes[0].x0")
        data = json.loads(page.evaluate("document.getElementById('prs3-data').textContent"))
        assert cursor == data["stops"]["time"][k] > 0.0    # the plots' cursor at that line's time
        page.locator("#slider").fill(str(stops - 3))
        page.click("#play")                                 # play runs on to the end, and stops
        assert page.inner_text("#play").endswith("pause")
        page.wait_for_function(f"document.getElementById('slider').value === '{stops - 1}' && "
                               "document.getElementById('play').textContent.endsWith('play')", timeout=10000)

        whole = page.locator("#view-scene").screenshot()   # the whole machine
        page.get_by_text("part", exact=True).last.click()   # frame the part and the path
        page.locator("#view-part g.traces", has_text="machine").locator(".legendtoggle").click()   # hide the machine
        page.wait_for_timeout(300)
        assert page.evaluate("document.getElementById('view-machine').style.visibility") == "hidden"
        picture = page.locator("#view-scene").screenshot()
    finally:
        page.close()
    assert problems == []
    assert requests == [url]                            # nothing but the file itself
    from PIL import Image

    pixels = np.asarray(Image.open(io.BytesIO(whole)).convert("RGB")).astype(int).reshape(-1, 3)
    links = np.abs(pixels - _rgb(MACHINE_PIECES[3][3])).max(axis=1) <= 12
    assert links.sum() > 300, links.sum()
    pixels = np.asarray(Image.open(io.BytesIO(picture)).convert("RGB")).astype(int).reshape(-1, 3)
    r, g, b = pixels.T
    path = (b - r >= 90) & (b >= 140) & (g < 140)        # the first operation's blue #1f5fbf, under its face
    tan = (r > g) & (g > b) & (r - b >= 20) & (r - b <= 90) & (r >= 120)     # the part's tan, shaded
    assert path.sum() > 200, path.sum()
    assert tan.sum() > 5000, tan.sum()
    assert len(np.unique(pixels, axis=0)) > 50           # not blank
