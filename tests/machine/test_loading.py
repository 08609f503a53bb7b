"""Machine files: the shipped ones load with the paper's numbers; every bad file gets its exact message."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.cli.main import main
from prs3_post.core.errors import ConfigError
from prs3_post.machine.loading import load_machine, postproc_dir, shipped_names
from prs3_post.machine.model import general_from_ideal

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


def test_a_head_described_leg_by_leg(tmp_path: Path) -> None:
    """[[legs]] and [platform] of kinematics "3-prs-general": directions scaled to unit length, every key
    left out the ideal head's value; a file with today's keys only has no per-leg geometry at all."""
    assert load_machine("patel2020").geometry.general is None
    machine = load_machine(str(BAD.parent / "machines" / "patel2020-as-built.toml"))
    general = machine.geometry.general
    assert machine.kinematics == "3-prs-general" and general is not None
    assert general.legs[0].rail_point == (-339.2, -196.1, 0.2)
    assert general.legs[0].rail_direction == pytest.approx((0.0, 0.0017 / math.sqrt(1 + 0.0017**2),
                                                            -1.0 / math.sqrt(1 + 0.0017**2)), abs=1e-16)
    assert (general.legs[1].link_length, general.legs[1].stroke_offset) == (481.8, 0.4)
    assert general.tool_tip == (0.1, -0.2, -175.3)
    text = (postproc_dir() / "machines" / "patel2020.toml").read_text().replace(
        'kinematics = "3-prs"', 'kinematics = "3-prs-general"')
    path = tmp_path / "partial.toml"
    path.write_text(text + "\n[[legs]]\n[[legs]]\nstroke_offset_mm = 0.25\n[[legs]]\n")
    partial = load_machine(str(path)).geometry
    ideal = general_from_ideal(partial)
    assert partial.general is not None
    assert partial.general.legs[0] == ideal.legs[0] and partial.general.tool_tip == ideal.tool_tip
    assert partial.general.legs[1] == dataclasses.replace(ideal.legs[1], stroke_offset=0.25)
    # no [[legs]] at all: the ideal head, solved by the general kinematics
    path.write_text(text)
    assert load_machine(str(path)).geometry.general == general_from_ideal(partial)


def test_a_bool_where_a_number_goes_is_spelled_as_toml_spells_it(tmp_path):
    """It said "legs[3].link_length_mm: expected a number in mm, got True" (Python's spelling)."""
    text = (Path(__file__).resolve().parents[2] / "fixtures" / "machines" / "patel2020-as-built.toml").read_text()
    path = tmp_path / "bool.toml"
    path.write_text(text.replace("link_length_mm = 481.8", "link_length_mm = true", 1))
    with pytest.raises(ConfigError) as error:
        load_machine(str(path))
    assert str(error.value).endswith("link_length_mm: expected a number in mm, got true")
