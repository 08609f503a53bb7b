"""The Kinematics seam: a second, deliberately different kinematics registered by name runs the
main job, verify and ik, and every joint name and letter in their output is its own."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main
from prs3_post.core.errors import ConfigError
from prs3_post.core.types import FloatArray
from prs3_post.kinematics import AxisMemo, FKResult, IKModel, IKResult
from prs3_post.kinematics.protocol import LimitColumns, tilt_of
from prs3_post.kinematics.prs3.kinematics import Prs3Kinematics
from prs3_post.kinematics.registry import kinematics_of, register, unregister
from prs3_post.machine.loading import load_machine
from prs3_post.machine.model import Geometry, Limits

REPO = Path(__file__).resolve().parents[2]


@dataclass(frozen=True, slots=True)
class RamHead:
    """A toy: the 3-PRS head on a vertical ram, four joints. Legs L1..L3 slide on the ram, which
    slides R itself; the head's strokes are T_i = L_i + R − mean(L) (a common shift of all four
    joints moves the tool by the same along −z, as the protocol asks). Redundant: IK puts the ram at
    the mean stroke and the legs at their strokes less half of it."""

    geometry: Geometry
    name: ClassVar[str] = "ram-4"
    joint_names: ClassVar[tuple[str, ...]] = ("L1", "L2", "L3", "R")
    default_letters: ClassVar[tuple[str, ...]] = ("A", "B", "C", "Z")
    shift_direction: ClassVar[tuple[float, float, float] | None] = (0.0, 0.0, -1.0)

    @property
    def head(self) -> Prs3Kinematics:
        return Prs3Kinematics(self.geometry)

    @property
    def link_length(self) -> float:
        return self.geometry.link_length

    def inverse(self, tip: FloatArray, axis: FloatArray, *, model: IKModel = IKModel.EXACT,
                memo: AxisMemo | None = None) -> IKResult:
        ik = self.head.inverse(tip, axis, model=model, memo=memo)
        mean = ik.strokes.mean(axis=1, keepdims=True)
        joints = np.column_stack([ik.strokes - 0.5 * mean, mean])
        return IKResult(stage=ik.stage, strokes=joints, link_angle=ik.link_angle, condition=ik.condition,
                        reachable=ik.reachable)

    def forward(self, joints: FloatArray, stage: FloatArray | None = None) -> FKResult:
        joints = np.asarray(joints, dtype=np.float64).reshape(-1, 4)
        legs = joints[:, :3]
        strokes = legs + (joints[:, 3:] - legs.mean(axis=1, keepdims=True))
        return self.head.forward(strokes, stage)

    def condition(self, tip: FloatArray, axis: FloatArray) -> FloatArray:
        return self.head.condition(tip, axis)

    def limit_columns(self, limits: Limits, ik: IKResult, axis: FloatArray) -> LimitColumns:
        return [
            (tuple(f"{name} travel" for name in self.joint_names), "mm", -500.0, 500.0, ik.strokes),
            (("tilt",), "deg", -math.inf, limits.max_tilt, tilt_of(axis)[:, None]),
            (("condition number",), "", -math.inf, limits.max_condition, ik.condition[:, None]),
        ]


@pytest.fixture
def ram_machine(tmp_path: Path) -> Iterator[Path]:
    """A machine file naming the toy (the shipped machine with ``kinematics = "ram-4"``)."""
    register("ram-4", RamHead)
    text = (REPO / "postproc" / "machines" / "patel2020.toml").read_text(encoding="utf-8")
    path = tmp_path / "ram.toml"
    path.write_text(text.replace('kinematics = "3-prs"', 'kinematics = "ram-4"'), encoding="utf-8")
    yield path
    unregister("ram-4")


def run(*args: object) -> tuple[int, str]:
    result = CliRunner().invoke(main, [str(a) for a in args])
    return result.exit_code, result.output


def test_the_machine_file_names_its_kinematics(ram_machine: Path, tmp_path: Path) -> None:
    machine = load_machine(str(ram_machine))
    assert machine.kinematics == "ram-4" and isinstance(kinematics_of(machine), RamHead)
    assert load_machine("patel2020").kinematics == "3-prs"
    old = tmp_path / "old.toml"                       # a file written before the key: 3-PRS
    old.write_text(ram_machine.read_text(encoding="utf-8").replace('kinematics = "ram-4"\n', ""), encoding="utf-8")
    assert load_machine(str(old)).kinematics == "3-prs"
    bad = tmp_path / "bad.toml"
    bad.write_text(ram_machine.read_text(encoding="utf-8").replace('"ram-4"', '"6-sps"'), encoding="utf-8")
    with pytest.raises(ConfigError) as error:
        load_machine(str(bad))
    assert str(error.value).endswith("kinematics: unknown kinematics '6-sps' (known: 3-prs, 3-prs-general, ram-4)")


def test_the_main_job_and_verify_run_through_the_toy(ram_machine: Path, tmp_path: Path) -> None:
    out = tmp_path / "hole.ngc"
    code, text = run("demo", "--profile", "hole", "--machine", ram_machine, "-o", out)
    assert code == 0, text
    program = out.read_text(encoding="ascii")
    assert "(axes: X Y = stage X Y mm, A B C Z = actuator strokes L1 L2 L3 R mm)" in program
    moves = [line for line in program.splitlines() if line.startswith(("G0 ", "G1 ")) and " A" in line]
    assert moves and all(word[0] not in "UVW" for line in moves for word in line.split())
    first = {word[0]: float(word[1:]) for word in moves[0].split()[1:] if word[0] in "XYABCZ"}
    assert set(first) == set("XYABCZ")
    # the ram carries the mean stroke, the legs the rest: the head's strokes are the 3-PRS ones
    legs = np.array([first["A"], first["B"], first["C"]])
    assert first["Z"] == pytest.approx(2.0 * legs.mean(), abs=2e-3)

    code, text = run("verify", out, "--machine", ram_machine, "--json")
    report = json.loads(text)
    assert code == 0, text
    assert report["ok"] is True and report["problems"] == []
    assert [entry["limit"] for entry in report["limits"]] == ["L1 travel", "L2 travel", "L3 travel", "R travel",
                                                              "tilt", "condition number", "stage X", "stage Y"]
    row = report["moves_detail"][0]
    assert [row[name] for name in ("X", "L1", "L2", "L3", "R")] == [first[letter] for letter in "XABCZ"]
    assert "T1" not in row and report["axis_speed_max_axis"] == "stroke R"
    # the FK replay of the toy's joints round-trips to the straight hole: tip on the face origin's
    # normal, 5 mm deep below it at the bottom, to the tolerance
    assert report["straightness_mm"] < 1e-9 and report["implied_feed_min"] == pytest.approx(100.0, abs=1e-3)
    bottom = np.array(report["path"]["tip_part"][16])
    assert bottom == pytest.approx(np.array([0.0, 200.0, 300.0]) - 5.0 * np.array([0.447214, 0.0, 0.894427]),
                                   abs=2e-3)


def test_ik_batch_has_the_toys_columns(ram_machine: Path, tmp_path: Path) -> None:
    poses = tmp_path / "poses.csv"
    poses.write_text("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n-81.0264,21.2132,-679.4865,0.447214,0,0.894427\n",
                     encoding="ascii")
    out = tmp_path / "ik.csv"
    code, text = run("ik", "--batch", poses, "--machine", ram_machine, "-o", out)
    assert code == 0, text
    header, row = out.read_text(encoding="ascii").splitlines()
    assert header.split(",")[6:] == ["X", "Y", "L1", "L2", "L3", "R", "theta1_deg", "theta2_deg", "theta3_deg",
                                     "cond", "ok"]
    values = dict(zip(header.split(","), row.split(","), strict=True))
    strokes = np.array([36.2244, 170.3885, 88.9519])               # the exact 3-PRS strokes of case 2a
    ram = strokes.mean()
    assert float(values["R"]) == pytest.approx(ram, abs=1e-3)
    assert [float(values[f"L{i + 1}"]) for i in range(3)] == pytest.approx(strokes - 0.5 * ram, abs=1e-3)
    assert values["ok"] == "true"


def test_linuxcnc_config_of_the_toy(ram_machine: Path, tmp_path: Path) -> None:
    """A joint per axis whatever the kinematics; the vismach model draws only a 3-PRS head."""
    code, text = run("linuxcnc-config", "--machine", ram_machine, "-o", tmp_path / "sim")
    assert code == 2
    assert text == (f"prs3-post: error: {ram_machine}: kinematics: the vismach model draws a 3-PRS head (3-prs, "
                    "3-prs-general), not 'ram-4': leave it out (--no-vismach)\n")
    assert not (tmp_path / "sim").exists()
    code, text = run("linuxcnc-config", "--machine", ram_machine, "-o", tmp_path / "sim", "--no-vismach")
    assert code == 2                                  # its default letters are A B C Z: rotary to LinuxCNC
    assert text == ("prs3-post: error: dialects/linuxcnc.toml: axes: the dialect writes stroke L1 as 'A', which "
                    "LinuxCNC treats as a rotary axis in degrees: give a dialect that writes the stage and the strokes "
                    "with X Y Z U V W\n")
