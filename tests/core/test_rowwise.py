"""prs3_post.core.rowwise: the column-at-a-time row arithmetic gives numpy's bits (lengths) and values (all, any)."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from prs3_post.core.rowwise import row_all, row_any, row_lengths, same_rows


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 300), spread=st.integers(0, 300))
@example(seed=0, rows=0, spread=0)
def test_row_lengths_are_numpys_norm_bit_for_bit(seed: int, rows: int, spread: int) -> None:
    """Any magnitudes (tiny, huge, overflowing to inf), signed zeros, NaN and inf: the same bits."""
    rng = np.random.default_rng(seed)
    vectors = rng.standard_normal((rows, 3)) * 10.0 ** rng.integers(-spread, spread + 1, (rows, 3))
    special = rng.random((rows, 3))
    vectors[special < 0.03] = -0.0
    vectors[(special >= 0.03) & (special < 0.05)] = np.nan
    vectors[(special >= 0.05) & (special < 0.06)] = -np.inf
    with np.errstate(over="ignore", invalid="ignore"):
        expected = np.linalg.norm(vectors, axis=1)
        got = row_lengths(vectors)
    assert got.shape == (rows,)
    np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 50), columns=st.integers(1, 6),
       density=st.floats(0.0, 1.0))
def test_row_all_and_row_any_are_numpys(seed: int, rows: int, columns: int, density: float) -> None:
    mask = np.random.default_rng(seed).random((rows, columns)) < density
    assert row_all(mask).tolist() == mask.all(axis=1).tolist()
    assert row_any(mask).tolist() == mask.any(axis=1).tolist()
    assert row_all(mask[:, ::-1]).tolist() == mask[:, ::-1].all(axis=1).tolist()    # strided columns too


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 30), columns=st.integers(1, 5),
       change=st.sampled_from(["none", "value", "sign of zero", "nan", "strided"]))
@example(seed=0, rows=1, columns=3, change="none")
def test_same_rows_is_every_row_with_the_bits_of_the_first(seed: int, rows: int, columns: int, change: str) -> None:
    rng = np.random.default_rng(seed)
    row = rng.standard_normal(columns)
    row[rng.random(columns) < 0.3] = 0.0
    row[rng.random(columns) < 0.1] = np.nan
    values = np.tile(row, (rows, 1))
    at, column = int(rng.integers(rows)), int(rng.integers(columns))
    if change == "value":
        values[at, column] = np.nextafter(values[at, column], np.inf)
    elif change == "sign of zero":
        values[at, column] = -0.0 if values[at, column] == 0.0 and not np.signbit(values[at, column]) else 0.0
    elif change == "nan":
        values[at, column] = np.nan if not np.isnan(values[at, column]) else 1.0
    elif change == "strided":
        values = np.tile(row, (rows, 2))[:, ::2]
    expected = all(values[i].tobytes() == values[0].tobytes() for i in range(rows))
    assert same_rows(values) is expected
    assert expected or change in ("value", "sign of zero", "nan")
