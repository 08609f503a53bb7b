"""Machine files: the shipped ones load with the paper's numbers; every bad file gets its exact message."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.cli.main import main
from prs3_post.core.errors import ConfigError
from prs3_post.machine.loading import load_machine, postproc_dir, shipped_names

BAD = Path(__file__).resolve().parents[2] / "fixtures" / "bad"
BAD_MACHINES = sorted((BAD / "machines").glob("*.toml"))


def test_shipped_machines():
    assert shipped_names("machines") == ("patel2020", "patel2020-head")
    machine = load_machine("patel2020")
    geo = machine.geometry
    assert_allclose(
        [geo.guide_radius, geo.link_length, geo.platform_radius * math.sqrt(3), geo.tool_length],
        [392.013, 482.0, 300.0, 175.0], atol=1e-12,
    )
    assert_allclose([math.degrees(a) for a in geo.leg_azimuth], [210.0, 330.0, 90.0], atol=1e-12)
    assert machine.limits.stroke == (-100.0, 400.0)
    assert_allclose([math.degrees(a) for a in machine.limits.link_angle], [30.0, 85.0], atol=1e-12)
    assert_allclose([math.degrees(machine.limits.max_tilt), machine.limits.max_condition], [45.0, 10.0], atol=1e-12)
    assert machine.stage.present and machine.stage.travel_x == (-300.0, 300.0)
    assert machine.part_origin == (-100.0, -200.0, -970.0)
    assert machine.source == "machines/patel2020.toml"
    head = load_machine("patel2020-head")
    assert not head.stage.present and head.geometry == geo


def test_machine_by_path_and_postproc_found():
    path = postproc_dir() / "machines" / "patel2020.toml"
    assert load_machine(str(path)).geometry == load_machine("patel2020").geometry


def test_unknown_machine_name():
    with pytest.raises(ConfigError) as caught:
        load_machine("nope")
    assert str(caught.value) == "nope: no such machine file or shipped name (shipped: patel2020, patel2020-head)"


@pytest.mark.parametrize("path", BAD_MACHINES, ids=lambda p: p.stem)
def test_bad_machine_file_message(path, monkeypatch):
    expected = path.read_text(encoding="utf-8").splitlines()[0].removeprefix("# expect: ")
    monkeypatch.chdir(BAD)
    with pytest.raises(ConfigError) as caught:
        load_machine(f"machines/{path.name}")
    assert str(caught.value) == expected


@pytest.mark.parametrize("path", BAD_MACHINES[:3], ids=lambda p: p.stem)
def test_bad_machine_file_cli_exit_2(path, monkeypatch):
    expected = path.read_text(encoding="utf-8").splitlines()[0].removeprefix("# expect: ")
    monkeypatch.chdir(BAD)
    result = CliRunner().invoke(main, ["fk", "--strokes", "0,0,0", "--machine", f"machines/{path.name}"])
    assert result.exit_code == 2
    assert result.output == f"prs3-post: error: {expected}\n"


@pytest.mark.parametrize("kind", ["machine", "job"])
def test_toml_nested_too_deeply_is_a_config_error(tmp_path: Path, kind: str) -> None:
    """tomllib recurses per nesting level: 500 nested arrays were a RecursionError traceback."""
    path = tmp_path / f"{kind}.toml"
    path.write_text("x = " + "[" * 500 + "]" * 500 + "\n", encoding="utf-8")
    args = ["demo", "--profile", "hole", "--machine", str(path)] if kind == "machine" else ["job", str(path)]
    result = CliRunner().invoke(main, [*args, "-o", str(tmp_path / "p.ngc")], prog_name="prs3-post")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {path}: not valid TOML here: arrays or inline tables nested too "
                             "deeply\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
