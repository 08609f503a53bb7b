"""pipeline and linearize: setup transform, inverse-time feeds, axis-change subdivision, reach and limit errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import LimitError, ReachError
from prs3_post.core.rowwise import row_lengths
from prs3_post.core.toolpath import Event, EventKind, MoveKind, Toolpath
from prs3_post.kinematics import forward, inverse
from prs3_post.machine.loading import load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.limits import check_limits
from prs3_post.post.linearize import (
    CHECK_FRACTIONS,
    joint_path_deviation,
    joint_path_deviations,
    linearize,
    slerp,
    subdivide_axis_changes,
)
from prs3_post.post.pipeline import inverse_time, machine_path, post_process

MACHINE = load_machine("patel2020")
ORIGIN = Setup((-100.0, -200.0, -970.0))
A = np.array([1.0, 0.0, 2.0]) / np.sqrt(5.0)           # the wedge face normal


def path(tips, axes, kinds, feeds, labels=(), events=()):
    n = len(tips)
    return Toolpath(kind=np.array(kinds), tip=np.array(tips, dtype=float), axis=np.array(axes, dtype=float),
                    feed=np.array(feeds, dtype=float), source=np.arange(n), events=tuple(events),
                    source_labels=tuple(labels) or tuple(f"step {i}" for i in range(n)))


def test_inverse_time_is_feed_over_length():
    p = path([[0, 0, 0], [3, 4, 0], [3, 4, 0.5], [3, 4, 10]], [A] * 4,
             [MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED, MoveKind.RAPID], [0, 300, 100, 0])
    assert_allclose(inverse_time(p), [0.0, 60.0, 200.0, 0.0], atol=1e-12)


def test_inverse_time_refuses_a_first_feed_and_a_zero_length_feed():
    with pytest.raises(LimitError) as caught:
        inverse_time(path([[0, 0, 0]], [A], [MoveKind.FEED], [100]))
    assert str(caught.value) == "step 0: the program starts with a feed move; its start point is unknown"
    with pytest.raises(LimitError) as caught:
        inverse_time(path([[0, 0, 0], [0, 0, 0]], [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100]))
    assert str(caught.value) == "step 1: feed move of zero length"


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 40), rapids=st.booleans(), repeat=st.booleans())
def test_inverse_time_is_each_rows_feed_over_its_length_bit_for_bit(seed, rows, rapids, repeat):
    """Every row a feed move after a start point (the steps as slices) or some rapids among them (the
    feed rows picked out): each F is the row's feed over np.linalg.norm of its step, the same bits, and
    a repeated point is the zero-length error at its row on either way."""
    rng = np.random.default_rng(seed)
    tips = rng.uniform(-300.0, 300.0, (rows, 3)) * 10.0 ** rng.integers(-5, 2, (rows, 1))
    kinds = np.where(rng.random(rows) < 0.3, MoveKind.RAPID, MoveKind.FEED) if rapids else np.full(rows, MoveKind.FEED)
    feeds = np.where(kinds == MoveKind.FEED, rng.uniform(1.0, 5000.0, rows), 0.0)
    start = rng.uniform(-300.0, 300.0, 3)
    if repeat:
        row = int(rng.integers(rows))
        tips[row] = tips[row - 1] if row else start
        kinds[row], feeds[row] = MoveKind.FEED, 100.0
    p = path(tips, [A] * rows, kinds, feeds)
    before = np.vstack([start, tips[:-1]])
    expected = np.zeros(rows)
    for i in np.flatnonzero(kinds == MoveKind.FEED):
        length = np.linalg.norm(tips[i:i + 1] - before[i:i + 1], axis=1)[0]
        if length < 1e-9:
            for steps in (None, row_lengths(np.diff(tips, axis=0))):
                with pytest.raises(LimitError) as caught:
                    inverse_time(p, start=start, steps=steps)
                assert str(caught.value) == f"step {i}: feed move of zero length"
            return
        expected[i] = feeds[i] / length
    np.testing.assert_array_equal(inverse_time(p, start=start).view(np.int64), expected.view(np.int64))
    steps = row_lengths(np.diff(tips, axis=0))            # the stream's step lengths, shared with its guard
    np.testing.assert_array_equal(inverse_time(p, start=start, steps=steps).view(np.int64), expected.view(np.int64))
    with pytest.raises(ValueError, match=f"inverse_time: {rows} step lengths for {rows} rows"):
        inverse_time(p, start=start, steps=np.zeros(rows))


def test_post_process_places_the_part_and_matches_case_2a():
    tip_part = np.array([18.9736, 221.2132, 290.5135])         # the paper's point 2a on the wedge
    p = path([tip_part + 10 * A, tip_part], [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100])
    result = post_process(MACHINE, p, ORIGIN, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert_allclose(result.path.tip[1], [-81.0264, 21.2132, -679.4865], atol=1e-12)
    # DESIGN's -2.7639 is for the rounded axis (0.447214, 0, 0.894427); the exact normal gives -2.76402
    assert_allclose(result.program.stage[1], [-2.7639, 12.0703], atol=2e-4)
    assert_allclose(result.program.stage[1], [-2.764021, 12.070327], atol=1e-6)
    assert_allclose(result.program.strokes[1], [36.2244, 170.3886, 88.9519], atol=2e-4)   # same axis rounding
    direct = inverse(MACHINE.geometry, np.array([[-81.0264, 21.2132, -679.4865]]), A[None, :])
    assert_allclose(result.program.strokes[1], direct.strokes[0], atol=1e-9)
    assert_allclose(result.program.inverse_time, [0.0, 10.0], atol=1e-12)
    assert result.limits.ok.all()


@pytest.mark.parametrize("turning", [False, True])
def test_the_limit_report_is_made_when_read_and_is_that_of_the_rows_kept(turning):
    """The stream checks the limits without a report; the result's report, made when first read (and
    kept through dataclasses.replace), is check_limits of the rows kept, as the one made at once was:
    the same names, bounds, values, margins and oks, bit for bit."""
    b = np.array([0.9, 0.0, 2.0]) / np.linalg.norm([0.9, 0.0, 2.0]) if turning else A
    steps = np.array([[-20.0, 0.0, 5.0], [-10.0, 0.0, 5.0], [-10.0, 0.00001, 5.0], [0.0, 5.0, 5.0]])
    tips = np.array([18.9736, 221.2132, 290.5135]) + steps      # about the paper's point 2a
    p = path(tips, [A, A, A, b], [MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED, MoveKind.FEED], [0, 300, 300, 300])
    result = post_process(MACHINE, p, ORIGIN, length_decimals=4,
                          tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert 2 not in result.path.source.tolist()                  # the 0.00001 mm step goes
    assert (len(result.path) > 3) == turning                     # the turn is subdivided, its rows checked after
    report = result.limits
    expected = check_limits(MACHINE, result.ik, result.path.axis)
    assert report.names == expected.names and report.units == expected.units
    for name in ("low", "high", "value", "margin", "ok"):
        np.testing.assert_array_equal(getattr(report, name), getattr(expected, name))
    assert report.ok.all() and result.limits is report
    assert dataclasses.replace(result, program=result.program).limits is report


def test_limit_error_names_the_step():
    far = np.array([0.0, 0.0, 900.0])                            # 900 mm above the part origin: stroke < -100
    p = path([far, far - A], [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100],
             labels=("hole 1 approach", "hole 1 feed"))
    with pytest.raises(LimitError) as caught:
        post_process(MACHINE, p, ORIGIN, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == ("hole 1 approach: T1 stroke -573.2621 mm is below the minimum -100.0000 mm "
                                 "by 473.2621 mm (2 points outside limits in all)")


def test_head_machine_reports_how_far_off_the_tip_is():
    head = load_machine("patel2020-head")
    tip_part = np.array([18.9736, 221.2132, 290.5135])
    p = path([tip_part + 10 * A, tip_part], [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100],
             labels=("hole 1 approach", "hole 1 feed"))
    with pytest.raises(ReachError) as caught:
        post_process(head, p, ORIGIN, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == (
        "hole 1 approach: machine patel2020-head has no stage and its head alone misses the tip "
        "(-76.5543, 21.2132, -670.5422) by 12.1906 mm (x 1.7081, y 12.0703) (2 points unreachable in all)"
    )


def test_head_alone_moves_its_tip_only_vertically_at_a_fixed_tilt():
    """With the axis fixed, the head's tip x, y are fixed (parasitic shift - TL a_xy): only z is free.

    So a pure head cannot feed along a tilted axis; it reaches a tilted pose only where the setup
    puts the part under that x, y, and then moves vertically.
    """
    head = load_machine("patel2020-head")
    tip_part = np.array([18.9736, 221.2132, 290.5135])
    p = path([tip_part + np.array([0, 0, 10]), tip_part], [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100])
    # the part placed under the head's tip
    shifted = ORIGIN.with_origin(ORIGIN.shift - np.array([-2.7640208, 12.0703266, 0.0]))
    result = post_process(head, p, shifted, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert_allclose(result.program.stage, 0.0, atol=0.0)
    assert_allclose(result.ik.stage, 0.0, atol=1e-6)
    assert_allclose(np.diff(result.program.strokes, axis=0), [[10.0, 10.0, 10.0]], atol=1e-9)


def test_slerp_ends_and_midpoint():
    a, b = np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]])
    assert_allclose(slerp(a, b, np.array([0.0])), a, atol=1e-15)
    assert_allclose(slerp(a, b, np.array([1.0])), b, atol=1e-15)
    assert_allclose(slerp(a, b, np.array([0.5])), [[np.sqrt(0.5), 0.0, np.sqrt(0.5)]], atol=1e-15)


def test_axis_changing_feed_is_subdivided_until_within_tolerance():
    start_axis = np.array([0.0, 0.0, 1.0])
    tips = np.array([[-80.0, 20.0, -690.0], [-80.0, 20.0, -680.0], [-40.0, 20.0, -680.0]])
    axes = np.array([start_axis, start_axis, A])
    events = (Event(before=2, kind=EventKind.COMMENT, text="turn"), Event(before=3, kind=EventKind.SPINDLE_OFF))
    p = path(tips, axes, [MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED], [0, 100, 100], events=events)
    before = joint_path_deviation(MACHINE.geometry, p.tip, p.axis, np.array([1]))
    assert before[0] > 0.1                                      # the raw joint-space line strays far
    out = subdivide_axis_changes(MACHINE.geometry, p, tolerance=0.002, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert len(out) > len(p)
    assert_allclose(out.tip[[0, 1, -1]], tips, atol=0.0)        # original rows kept, in order
    # every inserted row lies on the intended move: tip on the segment, axis on the great circle
    inserted = out.tip[2:-1]
    t = (inserted[:, 0] - tips[1, 0]) / (tips[2, 0] - tips[1, 0])
    assert_allclose(inserted, tips[1] + t[:, None] * (tips[2] - tips[1]), atol=1e-12)
    assert_allclose(out.axis[2:-1], slerp(np.tile(start_axis, (len(t), 1)), np.tile(A, (len(t), 1)), t), atol=1e-12)
    assert (out.source[2:] == 2).all() and (out.kind[2:] == MoveKind.FEED).all()
    # events moved with their rows: the comment still precedes the turning move, spindle off stays last
    assert [e.before for e in out.events] == [2, len(out)]
    # and now the joint-space line of every piece stays within tolerance at the checked fractions
    deviation = joint_path_deviation(MACHINE.geometry, out.tip, out.axis, np.arange(1, len(out) - 1))
    assert deviation.max() <= 0.002
    # independent check at other fractions than the ones the subdivision looked at
    ik = inverse(MACHINE.geometry, out.tip, out.axis)
    joints = np.column_stack([ik.stage, ik.strokes])
    for frac in (0.1, 0.4, 0.9):
        assert frac not in CHECK_FRACTIONS
        mixed = (1 - frac) * joints[1:-1] + frac * joints[2:]
        fk = forward(MACHINE.geometry, mixed[:, 2:], mixed[:, :2])
        intended = (1 - frac) * out.tip[1:-1] + frac * out.tip[2:]
        assert np.linalg.norm(fk.tip - intended, axis=1).max() <= 0.002


def test_constant_axis_moves_are_not_subdivided():
    tips = np.array([[-80.0, 20.0, -690.0], [-40.0, 60.0, -670.0]])
    p = path(tips, [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100])
    out = subdivide_axis_changes(MACHINE.geometry, p,
                                 tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert len(out) == 2
    assert joint_path_deviation(MACHINE.geometry, p.tip, p.axis, np.array([0]))[0] <= 1e-9


def test_machine_without_stage_refuses_a_feed_along_a_tilted_axis():
    head = dataclasses.replace(MACHINE, stage=dataclasses.replace(MACHINE.stage, present=False), name="nostage")
    tip_part = np.array([0.0, 200.0, 300.0])
    p = path([tip_part + 10 * A, tip_part], [A, A], [MoveKind.RAPID, MoveKind.FEED], [0, 100])
    with pytest.raises(ReachError):
        post_process(head, p, ORIGIN, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)


def test_the_angle_tolerance_bounds_the_tool_axis_of_subdivided_moves():
    """With the tip bound out of the way (1 m), only the angle bound subdivides: every piece's FK axis
    stays within 0.01° of the great circle; without either bound the move stays one line, 0.97° off."""
    start_axis = np.array([0.0, 0.0, 1.0])
    tips = np.array([[-80.0, 20.0, -690.0], [-80.0, 20.0, -680.0], [-40.0, 20.0, -680.0]])
    p = path(tips, [start_axis, start_axis, A], [MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED], [0, 100, 100])
    loose = subdivide_axis_changes(MACHINE.geometry, p, tolerance=1e3, angle_tolerance=np.inf)
    assert len(loose) == 3
    _, angle = joint_path_deviations(MACHINE.geometry, loose.tip, loose.axis, np.array([1]))
    assert_allclose(np.degrees(angle), [0.9713], atol=1e-4)
    out = subdivide_axis_changes(MACHINE.geometry, p, tolerance=1e3, angle_tolerance=np.radians(0.01))
    assert len(out) == 18
    tip_gap, angle = joint_path_deviations(MACHINE.geometry, out.tip, out.axis, np.arange(1, len(out) - 1))
    assert np.degrees(angle.max()) <= 0.01
    assert tip_gap.max() > 0.002                                  # the tip alone would have asked for more
    # the defaults bound both: here the tip bound (0.002 mm) is the tighter one
    both = subdivide_axis_changes(MACHINE.geometry, p,
                                  tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert len(both) == len(subdivide_axis_changes(MACHINE.geometry, p, angle_tolerance=np.inf,
                                                   tolerance=DEFAULT_TOLERANCE)) == 66


def test_a_move_that_bisection_cannot_bring_within_tolerance_is_an_error():
    """Here after one round (max_rounds=1); in practice a move whose FK does not converge (a singularity)."""
    start_axis = np.array([0.0, 0.0, 1.0])
    tips = np.array([[-80.0, 20.0, -690.0], [-80.0, 20.0, -680.0], [-40.0, 20.0, -680.0]])
    p = path(tips, [start_axis, start_axis, A], [MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED], [0, 100, 100],
             labels=("approach", "down", "turn"))
    with pytest.raises(LimitError) as caught:
        subdivide_axis_changes(MACHINE.geometry, p, max_rounds=1,
                               tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == ("turn: the joint-space move still strays 1.708 mm / 0.3002 deg from the intended one "
                                 "after 1 rounds of bisection (allowed: 0.002 mm, 0.01 deg); the tool axis may pass "
                                 "a singularity")
    done = linearize(MACHINE.geometry, p, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert_allclose([done.tip_before, np.degrees(done.angle_before)], [6.2503, 0.9713], atol=1e-4)
    assert 0.0 < done.tip_after <= 0.002 and len(done.path) == 66
    # the same move needs 63 inserted rows: with room for 40 the bisection stops, naming it
    with pytest.raises(LimitError) as caught:
        subdivide_axis_changes(MACHINE.geometry, p, max_inserted=40,
                               tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == ("turn: the joint-space move to this point would need more than 40 inserted points: "
                                 "it still strays 0.007515 mm / 0.001484 deg from the intended one after 5 rounds of "
                                 "bisection (allowed: 0.002 mm, 0.01 deg); the tool axis may pass a singularity")
    assert len(subdivide_axis_changes(MACHINE.geometry, p, max_inserted=63,
                                      tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)) == 66


def test_a_move_through_the_singularity_names_the_limit_its_end_breaks():
    """A feed from a vertical axis to one tilted 70°: past the singularity (49.8°), the joint-space
    line cannot be bisected onto the path: the bisection gives up when the move would need more than
    its cap of rows; post-processing checks the end poses first, and the error is the first limit
    its end pose breaks (its tilt too), not the bisection; the placement's machine path does not
    subdivide it at all."""
    tilted = np.array([np.sin(np.radians(70.0)), 0.0, np.cos(np.radians(70.0))])
    p = path([[20.0, 220.0, 290.0], [60.0, 220.0, 290.0]], [[0.0, 0.0, 1.0], tilted], [MoveKind.RAPID, MoveKind.FEED],
             [0, 100], labels=("approach", "turn"))
    with pytest.raises(LimitError) as caught:
        subdivide_axis_changes(MACHINE.geometry, machine_path(MACHINE, p, ORIGIN,
            tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE),
                               tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == ("turn: the joint-space move to this point would need more than 1000 inserted "
                                 "points: it still strays 59.85 mm / 17.97 deg from the intended one after 12 rounds "
                                 "of bisection (allowed: 0.002 mm, 0.01 deg); the tool axis may pass a singularity")
    # the placement's machine path leaves a path that tilts past the limit as given (no setup runs it)
    assert len(machine_path(MACHINE, p, ORIGIN,
                            tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)) == 2
    with pytest.raises(LimitError) as caught:
        post_process(MACHINE, p, ORIGIN, tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    assert str(caught.value) == "turn: T2 stroke 412.4087 mm is above the maximum 400.0000 mm by 12.4087 mm"
