"""The setup: part → machine rigid transform, its inverse, its range checks and its one resolver."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.machine.loading import load_machine
from prs3_post.part.setup_transform import Setup, SetupError

MACHINE = load_machine("patel2020")


def test_rotation_is_counter_clockwise_about_machine_z_seen_from_above():
    setup = Setup((1.0, 2.0, 3.0), 90.0)
    # the part's +x points along the machine's +y, its +y along the machine's -x; z unchanged
    assert_allclose(setup.points_to_machine(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])),
                    [[1.0, 3.0, 3.0], [0.0, 2.0, 3.0], [1.0, 2.0, 4.0]], atol=0)
    assert_allclose(setup.axes_to_machine(np.array([[1.0, 0.0, 0.0]])), [[0.0, 1.0, 0.0]], atol=0)
    assert_allclose(setup.part_to_machine(), [[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]], atol=0)


def test_default_is_the_machine_files_origin_without_rotation():
    assert Setup.resolve(MACHINE) == Setup((-100.0, -200.0, -970.0), 0.0)
    assert Setup.resolve(MACHINE, (1, 2, 3)) == Setup((1.0, 2.0, 3.0), 0.0)
    assert Setup.resolve(MACHINE, None, 30) == Setup((-100.0, -200.0, -970.0), 30.0)


@settings(max_examples=50, deadline=None)
@given(origin=st.tuples(*[st.floats(-2000, 2000)] * 3), rotation=st.floats(-720, 720),
       points=st.lists(st.tuples(*[st.floats(-500, 500)] * 3), min_size=0, max_size=5))
def test_inverse_undoes_the_transform(origin, rotation, points):
    setup = Setup(origin, rotation)
    p = np.array(points, dtype=np.float64).reshape(-1, 3)
    machine = setup.points_to_machine(p)
    assert machine.shape == p.shape
    assert_allclose(setup.points_to_part(machine), p, atol=1e-9)
    assert_allclose(setup.axes_to_part(setup.axes_to_machine(p)), p, atol=1e-9)
    assert_allclose(setup.machine_to_part() @ setup.part_to_machine(), np.eye(4), atol=1e-12)
    homogeneous = np.column_stack([p, np.ones(len(p))]) @ setup.part_to_machine().T
    assert_allclose(homogeneous[:, :3], machine, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(origin=st.tuples(*[st.sampled_from([0.0, -0.0, -690.0, 1e-300]) | st.floats(-2000, 2000)] * 3),
       rotation=st.sampled_from([0.0, 360.0, -720.0, 90.0, -180.0]) | st.floats(-720, 720),
       seed=st.integers(0, 2**32 - 1),
       rows=st.integers(0, 50))
def test_points_to_machine_is_the_rotation_and_the_shift_bit_for_bit(origin, rotation, seed, rows):
    """The shift is added a column at a time (faster than a broadcast row), and without a turn the
    product is skipped for finite points: the bits of points @ R.T + origin either way, signed zeros
    in the points and the origin, NaN and inf among the points included."""
    setup = Setup(origin, rotation)
    rng = np.random.default_rng(seed)
    p = rng.standard_normal((rows, 3)) * 10.0 ** rng.integers(-8, 6, (rows, 3))
    pick = rng.random((rows, 3))
    p[pick < 0.1], p[(pick >= 0.1) & (pick < 0.2)] = 0.0, -0.0
    if seed % 2:                                       # (without a turn, finite points skip the product)
        p[pick > 0.97] = np.inf
    with np.errstate(invalid="ignore"):
        expected = p @ setup.rotation.T + setup.shift
        got = setup.points_to_machine(p)
    assert got.shape == (rows, 3)
    np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))


@pytest.mark.parametrize(("origin", "rotation", "field", "message"), [
    ((math.nan, 0, 0), 0.0, "origin",
     "part origin: each of x, y, z must be a finite number within ±100000 mm, got [nan, 0, 0]"),
    ((1e308, 0, 0), 0.0, "origin",
     "part origin: each of x, y, z must be a finite number within ±100000 mm, got [1e+308, 0, 0]"),
    ((0, 0, 0), math.inf, "rotation", "part rotation: must be a finite number within ±3600 degrees, got inf"),
    ((0, 0, 0), 1e308, "rotation", "part rotation: must be a finite number within ±3600 degrees, got 1e+308"),
])
def test_out_of_range_values_are_refused(origin, rotation, field, message):
    with pytest.raises(SetupError) as caught:
        Setup(origin, rotation)
    assert str(caught.value) == message
    assert caught.value.field == field
    assert caught.value.exit_code == 2


def test_describe_is_the_headers_form():
    assert Setup((-118.0, -10.0, -678.0), 30.0).describe() == (
        "part origin at machine [-118.0000, -10.0000, -678.0000] mm, rotation 30.0000 deg about z")
