"""Axis speeds: feed clamping (exactly to the limit, replayed through FK), cycle time (the trapezoid
formula, and a brute-force integration of the golden programs), the machine file's [dynamics]."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import LimitError
from prs3_post.core.toolpath import EventKind, JointProgram, MoveKind, Toolpath
from prs3_post.kinematics.prs3.forward import forward
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.machine.model import Dynamics, Holder
from prs3_post.part.setup_transform import Setup
from prs3_post.post.dynamics import (
    DynamicsTally,
    _any_over,
    clamp_feeds,
    joint_columns,
    joint_deltas,
    move_times,
    program_time,
    trapezoid_time,
)
from prs3_post.post.pipeline import post_process
from prs3_post.readers.program import load_program

REPO = Path(__file__).resolve().parents[2]
GOLDEN = sorted((REPO / "fixtures" / "golden").iterdir())
MACHINE = load_machine("patel2020")
DYN = MACHINE.dynamics
SETUP = Setup((-100.0, -200.0, -970.0), 0.0)
TILT = math.radians(44.0)                              # 1° inside the machine's 45° tilt limit
AXIS = np.array([math.sin(TILT), 0.0, math.cos(TILT)])


def plunge(feed: float) -> Toolpath:
    """A rapid to a point above the wedge, then a 5 mm feed down the tilted tool axis."""
    start = np.array([0.0, 200.0, 300.0])
    return Toolpath(kind=[MoveKind.RAPID, MoveKind.FEED], tip=[start, start - 5.0 * AXIS], axis=[AXIS, AXIS],
                    feed=[0.0, feed], source=[1, 2])


def test_machine_file_dynamics_and_holder():
    assert DYN == Dynamics(stroke_speed=5000.0, stroke_accel=500.0, stage_speed=10000.0, stage_accel=1000.0)
    assert DYN.speeds() == (10000.0, 10000.0, 5000.0, 5000.0, 5000.0)
    assert DYN.accels() == (3.6e6, 3.6e6, 1.8e6, 1.8e6, 1.8e6)
    assert MACHINE.holder == Holder(holder_diameter=42.0, holder_length=35.0, nose_diameter=80.0, nose_length=60.0)


def test_feed_needing_three_times_a_stroke_speed_is_clamped_to_exactly_the_limit():
    free = post_process(replace(MACHINE, dynamics=None), plunge(300.0), SETUP,
                        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    deltas = joint_deltas(joint_columns(free.program.stage, free.program.strokes))
    need = float(deltas[1, 2:].max() * free.program.inverse_time[1])       # mm/min, the fastest stroke
    slow = replace(MACHINE, dynamics=replace(DYN, stroke_speed=need / 3.0))
    post = post_process(slow, plunge(300.0), SETUP,
                        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert post.dynamics is not None and post.dynamics.clamped == 1
    assert post.dynamics.worst_ratio == pytest.approx(3.0, rel=1e-12)
    assert post.dynamics.worst_where == "line 2" and post.dynamics.worst_axis.startswith("stroke")
    f = post.program.inverse_time[1]
    assert f == (need / 3.0) / deltas[1, 2:].max()                          # the fastest stroke at its top speed
    assert_allclose(deltas[1, 2:].max() * f, need / 3.0, rtol=1e-15)
    fk = forward(MACHINE.geometry, post.program.strokes, post.program.stage)
    assert fk.converged.all()
    tip_feed = np.linalg.norm(fk.tip[1] - fk.tip[0]) * f                   # FK-replayed tip feed, mm/min
    assert_allclose(tip_feed, 100.0, rtol=1e-9)                             # 300 mm/min slowed 3×
    assert_allclose(post.path.feed[1], 100.0, rtol=1e-12)                   # the path says so too
    rounded = round(f, 4)                                                   # the F word as emitted
    assert_allclose(np.linalg.norm(fk.tip[1] - fk.tip[0]) * rounded, 100.0, rtol=0.5e-4 / f)


def test_no_clamp_names_the_line():
    free = post_process(replace(MACHINE, dynamics=None), plunge(300.0), SETUP,
                        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    deltas = joint_deltas(joint_columns(free.program.stage, free.program.strokes))
    need = float(deltas[1, 2:].max() * free.program.inverse_time[1])
    slow = replace(MACHINE, dynamics=replace(DYN, stroke_speed=need / 3.0))
    with pytest.raises(LimitError) as caught:
        post_process(slow, plunge(300.0), SETUP, clamp=False,
                     tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    axis = int(np.argmax(deltas[1, 2:])) + 1
    assert str(caught.value) == (f"line 2: the feed needs stroke T{axis} at {need:.1f} mm/min, 3.00 x its top speed "
                                 f"{need / 3:.1f} mm/min (slow the feed, or let it be clamped)")


def test_machine_without_dynamics_clamps_nothing():
    tally = DynamicsTally(replace(MACHINE, dynamics=None))
    post = post_process(replace(MACHINE, dynamics=None), plunge(1e6), SETUP,
                        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert post.program.inverse_time[1] == pytest.approx(1e6 / 5.0, rel=1e-12)   # not clamped
    assert tally.feed(post.program) is post.program.inverse_time
    assert (tally.clamped, tally.worst_ratio, tally.worst_where) == (0, 1.0, "")


def _program(kind: list[int], joints: list[list[float]], f: list[float]) -> JointProgram:
    q = np.array(joints, dtype=np.float64)
    return JointProgram(kind=kind, stage=q[:, :2], strokes=q[:, 2:], inverse_time=f, source=range(1, len(kind) + 1))


def test_one_straight_move_takes_the_trapezoid_time():
    # a G1 moving T1 by 40 mm in 1/100 min: 4000 mm/min (< 5000), a = 500 mm/s² = 1.8e6 mm/min²
    prog = _program([0, 1], [[0, 0, 0, 0, 0], [0, 0, 40, 10, 0]], [0, 100.0])
    v, a = 4000.0, 500.0 * 3600.0
    assert 40.0 >= v * v / a                                                 # long enough to cruise
    assert program_time(DYN, prog) == pytest.approx(40.0 / v + v / a, rel=1e-14)
    # a G0 of 1 mm on T2 never reaches 5000 mm/min: triangular, 2 √(d / a)
    rapid = _program([0, 0], [[0, 0, 0, 0, 0], [0, 0, 0, 1.0, 0]], [0, 0])
    assert program_time(DYN, rapid) == pytest.approx(2.0 * math.sqrt(1.0 / a), rel=1e-14)
    # a G0 of 300 mm on stage X at 10000 mm/min, 1000 mm/s² (the strokes are still): cruises
    stage = _program([0, 0], [[0, 0, 0, 0, 0], [300.0, 0, 0, 0, 0]], [0, 0])
    assert program_time(DYN, stage) == pytest.approx(300.0 / 10000.0 + 10000.0 / 3.6e6, rel=1e-14)


def test_trapezoid_time_handles_zero_and_rows():
    assert trapezoid_time(np.zeros(0), 1.0, 1.0).shape == (0,)
    assert trapezoid_time(0.0, 1.0, 1.0) == 0.0
    deltas = np.zeros((1, 5))
    assert move_times(DYN, np.array([1]), deltas, np.array([5.0])).tolist() == [0.0]


def _brute_force_time(dynamics: Dynamics, program: JointProgram, dt: float = 1e-5) -> float:
    """Integrate each axis of each move in time steps of ``dt`` min: accelerate at a up to the axis's
    speed, decelerate at a when the rest of the distance needs it; the move ends when every axis has."""
    deltas = joint_deltas(joint_columns(program.stage, program.strokes))
    top, acc = np.array(dynamics.speeds()), np.array(dynamics.accels())
    feed = (program.kind == MoveKind.FEED)[:, None]
    speed = np.where(feed, deltas * program.inverse_time[:, None], top)
    speed = np.broadcast_to(np.where(speed > 0, speed, top), deltas.shape)
    acc = np.broadcast_to(acc, deltas.shape)
    x, v = np.zeros(deltas.shape), np.zeros(deltas.shape)
    done = deltas <= 0
    finish = np.zeros(deltas.shape)
    t = 0.0
    while not done.all():
        brake = v * v / (2 * acc) >= deltas - x
        v = np.where(brake, np.maximum(v - acc * dt, 0.0), np.minimum(v + acc * dt, speed))
        x = x + v * dt
        t += dt
        now = ~done & ((x >= deltas) | (brake & (v == 0.0)))
        finish[now] = t
        done |= now
    dwell = sum(e.value for e in program.events if e.kind is EventKind.DWELL) / 60.0
    return float(finish.max(axis=1).sum()) + dwell


@pytest.mark.parametrize("path", [p for p in GOLDEN if p.name in ("wedge-hole-peck-dwell.ngc", "tilt35-square.ngc",
                                                                    "twofaces-auto-round-plunge.ngc")],
                         ids=lambda p: p.name)
def test_golden_program_time_matches_a_brute_force_integration(path):
    dialect = load_dialect("fanuc" if path.suffix == ".nc" else "linuxcnc")
    program = load_program(str(path), dialect).moves
    brute = _brute_force_time(DYN, program)
    assert program_time(DYN, program) == pytest.approx(brute, rel=0.01)


def test_clamp_feeds_leaves_slow_moves_and_rapids():
    deltas = np.array([[0, 0, 10, 0, 0], [0, 0, 10, 0, 0], [0, 0, 10, 0, 0]], dtype=np.float64)
    kind = np.array([MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED])
    out = clamp_feeds(DYN, kind, deltas, np.array([0.0, 100.0, 1000.0]))
    assert out.inverse_time.tolist() == [0.0, 100.0, 500.0]
    assert out.ratio.tolist() == [1.0, 1.0, 2.0]
    assert out.clamped.tolist() == [False, False, True]



def test_verify_reports_a_g1_over_an_axis_speed_with_its_line(tmp_path):
    import json

    from click.testing import CliRunner

    from prs3_post.cli.main import main

    out = tmp_path / "hole.ngc"
    assert CliRunner().invoke(main, ["demo", "--profile", "hole", "--at", "10,0", "-o", str(out)]).exit_code == 0
    lines = out.read_text().split("\n")
    number = next(n for n, ln in enumerate(lines, start=1) if ln.startswith("G1 "))
    words = lines[number - 1].split()
    f = float(words[-1][1:])
    lines[number - 1] = " ".join([*words[:-1], f"F{f * 100:.4f}"])   # 100 × the feed: over the stroke speed
    out.write_text("\n".join(lines))
    result = CliRunner().invoke(main, ["verify", str(out), "--json"])
    report = json.loads(result.stdout)
    program = load_program(str(out), load_dialect("linuxcnc")).moves
    deltas = joint_deltas(joint_columns(program.stage, program.strokes))
    row = int(np.flatnonzero(program.source == number)[0])
    axis = int(np.argmax(deltas[row] / np.array(DYN.speeds())))
    speed = deltas[row, axis] * f * 100
    top = DYN.speeds()[axis]
    assert result.exit_code == 1
    assert [p for p in report["problems"] if p["kind"] == "speed"] == [
        {"line": number, "kind": "speed",
         "message": f"line {number}: the feed drives stroke T{axis - 1} at {speed:.1f} mm/min, {speed / top:.2f} x its "
                    f"top speed {top:.1f} mm/min"}]
    assert (report["axis_speed_max_line"], report["time_model"]) == (number, "trapezoid")
    assert report["axis_speed_max_fraction"] == pytest.approx(speed / top, rel=1e-9)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 40), feed_scale=st.floats(1e-3, 1e7),
       special=st.floats(0.0, 0.3))
@example(seed=0, rows=0, feed_scale=1.0, special=0.0)
def test_the_tallys_quick_test_finds_a_move_over_a_speed_exactly_when_the_clamp_does(
        seed: int, rows: int, feed_scale: float, special: float) -> None:
    """The tally asks first whether any ratio is over 1 (an axis at a time, no row-wise maximum):
    the same answer as clamp_feeds for any steps, feeds and rapids, zeros, NaN and inf among them."""
    rng = np.random.default_rng(seed)
    kind = rng.integers(0, 2, rows)
    deltas = np.abs(rng.standard_normal((rows, 5))) * 10.0 ** rng.integers(-4, 3, (rows, 5))
    inverse_time = rng.uniform(0.0, 1.0, rows) * feed_scale
    pick = rng.random((rows, 5))
    deltas[pick < special / 3] = 0.0
    deltas[(pick >= special / 3) & (pick < special / 2)] = np.nan
    inverse_time[rng.random(rows) < special / 4] = np.inf
    with np.errstate(invalid="ignore"):
        expected = bool(clamp_feeds(DYN, kind, deltas, inverse_time).clamped.any())
        assert _any_over(DYN, kind, deltas, inverse_time) is expected


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 40))
def test_joint_columns_are_the_stage_and_strokes_side_by_side(seed: int, rows: int) -> None:
    rng = np.random.default_rng(seed)
    stage, strokes = rng.standard_normal((rows, 2)), rng.standard_normal((rows, 3))
    stage[rng.random((rows, 2)) < 0.1] = -0.0
    strokes[rng.random((rows, 3)) < 0.1] = np.nan
    joints = joint_columns(stage, strokes)
    np.testing.assert_array_equal(joints.view(np.int64), np.column_stack([stage, strokes]).view(np.int64))
    with pytest.raises(ValueError, match=f"joint_columns: {rows} stage rows, {rows + 1} stroke rows"):
        joint_columns(stage, np.vstack([strokes, [[0.0, 0.0, 0.0]]]))
