"""The machine's bodies at a pose: links keep their length, the platform its size, the tool its axis."""

import numpy as np
import pytest

from prs3_post.check.machine_pose import machine_pose
from prs3_post.machine.loading import load_machine

ROWS = np.array([[300.0, 300.0, 300.0], [250.0, 300.0, 350.0], [120.0, 180.0, 90.0]])


@pytest.mark.parametrize("name", ["patel2020", "fixtures/machines/patel2020-as-built.toml"])
def test_links_platform_and_tool_are_rigid(name: str) -> None:
    machine = load_machine(name)
    pose = machine_pose(machine, ROWS, np.array([[1.0, 2.0], [3.0, 4.0], [-5.0, 0.0]]))
    general = machine.geometry.general
    links = [leg.link_length for leg in general.legs] if general else [machine.geometry.link_length] * 3
    assert np.linalg.norm(pose.spherical - pose.sliders, axis=2) == pytest.approx(np.tile(links, (3, 1)), abs=1e-9)
    sides = np.linalg.norm(pose.spherical - np.roll(pose.spherical, 1, axis=1), axis=2)
    assert sides.std(axis=1).max() < 0.5   # as built, the platform's sides differ by its tolerances
    tool = pose.body_segments()[:, 0]
    assert tool[:, 0] == pytest.approx(pose.tip)
    assert np.linalg.norm(tool[:, 1] - tool[:, 0], axis=1) == pytest.approx(
        machine.geometry.tool_length - machine.geometry.gauge_offset - machine.holder.holder_length)
    assert pose.on_table(pose.tip)[:, :2] == pytest.approx(pose.tip[:, :2] + pose.stage)


def test_sliders_ride_their_rails_at_the_stroke() -> None:
    machine = load_machine("patel2020")
    pose = machine_pose(machine, ROWS)
    assert pose.sliders[:, :, 2] == pytest.approx(-ROWS)
    assert pose.rails[:, :, 2] == pytest.approx(np.tile(-np.array(machine.limits.stroke), (3, 1)))


def test_a_row_without_a_pose_is_all_nan() -> None:
    pose = machine_pose(load_machine("patel2020"), np.array([[300.0, 300.0, 300.0], [0.0, 0.0, 900.0]]))
    assert pose.converged.tolist() == [True, False]
    assert np.isnan(pose.sliders[1]).all() and np.isnan(pose.spherical[1]).all() and np.isnan(pose.tip[1]).all()
