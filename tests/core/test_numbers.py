"""The one fixed-decimal formatter: scalar and whole-column forms against Python's own formatting."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from prs3_post.core.numbers import ChoiceColumn, fixed, fixed_column, render_rows, scale_column


def _python(value: float, decimals: int) -> str:
    """The reference: Python's fixed-point text, with a minus sign dropped when every digit is 0."""
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and math.isfinite(value) and float(text) == 0 else text


@pytest.mark.parametrize(("value", "decimals", "expected"), [
    (-0.00004, 4, "0.0000"), (-0.00005, 4, "-0.0001"), (-0.0, 3, "0.000"), (2.5, 0, "2"), (3.5, 0, "4"),
    (-0.5, 0, "0"), (0.125, 2, "0.12"), (1e16, 1, "10000000000000000.0"), (math.nan, 2, "nan"),
    (-math.inf, 2, "-inf"), (-12.34565, 4, "-12.3456"),  # the binary value is below the tie
])
def test_fixed(value: float, decimals: int, expected: str) -> None:
    assert fixed(value, decimals) == expected == fixed_column(np.array([value]), decimals)[0]


_ANY = st.floats(allow_nan=True, allow_infinity=True)
_TIES = st.builds(lambda k, d: (k + 0.5) / 10**d, st.integers(-10**9, 10**9), st.integers(0, 9))


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.one_of(_ANY, _TIES, st.floats(-1000, 1000)), max_size=40), decimals=st.integers(0, 9))
@example(values=[2.0**52, -(2.0**52) + 0.5, 4503599627370495.5, 5e-324, -5e-324], decimals=0)
def test_column_text_is_pythons(values: list[float], decimals: int) -> None:
    column = np.array(values, dtype=np.float64)
    expected = [_python(v, decimals) for v in values]
    assert fixed_column(column, decimals) == expected
    assert [fixed(v, decimals) for v in values] == expected
    scaled = scale_column(column, decimals)
    assert [scaled.text(row) for row in range(len(values))] == expected
    same = [False, *(a == b for a, b in itertools.pairwise(expected))]
    assert scaled.same_as_previous().tolist() == same[:len(values)]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 30), block_rows=st.integers(1, 8),
       separator=st.sampled_from([b" ", b","]), ending=st.sampled_from([b"\n", b"\r\n"]))
def test_render_rows_joins_the_words(seed: int, rows: int, block_rows: int, separator: bytes, ending: bytes) -> None:
    rng = np.random.default_rng(seed)
    values = rng.uniform(-2000, 2000, (rows, 3)) * 10.0 ** rng.integers(-6, 3, (rows, 3))
    values[rng.random((rows, 3)) < 0.1] = np.nan
    columns = [scale_column(values[:, j], d) for j, d in enumerate((4, 0, 7))]
    choice = ChoiceColumn(rng.integers(0, 3, rows), (b"G0", b"G1", b"true"))
    present = rng.random((rows, 4)) < 0.6
    present[:, 0] |= ~present[:, 1:].any(axis=1)
    buffer, ends = render_rows([choice, (b"X", columns[0]), (b"", columns[1]), (b"AB", columns[2])], present,
                               separator=separator, ending=ending, block_rows=block_rows)
    words = [[choice.texts[c].decode() for c in choice.choice],
             *[[prefix + _python(v, d) for v in values[:, j]] for j, (prefix, d) in enumerate(
                 (("X", 4), ("", 0), ("AB", 7)))]]
    joined = [separator.decode().join(w[row] for w, on in zip(words, present[row], strict=True) if on)
              for row in range(rows)]
    expected = [line + ending.decode() for line in joined]
    assert buffer.tobytes().decode("ascii") == "".join(expected)
    assert np.diff(ends).tolist() == [len(line) for line in expected]


def test_render_rows_refuses_an_empty_line_ending() -> None:
    with pytest.raises(ValueError, match="the line ending must be one or more bytes other than NUL, got b''"):
        render_rows([(b"X", scale_column(np.array([1.0]), 1))], np.array([[True]]), ending=b"")


def test_render_rows_refuses_a_row_without_words() -> None:
    with pytest.raises(ValueError, match="a row without any word"):
        render_rows([(b"X", scale_column(np.array([1.0]), 1))], np.array([[False]]))


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 60), block_rows=st.integers(1, 64),
       decimals=st.lists(st.integers(0, 12), min_size=3, max_size=3),
       prefixes=st.lists(st.sampled_from([b"", b"X", b"AB", b"ABC"]), min_size=3, max_size=3),
       density=st.floats(0.05, 1.0), ending=st.sampled_from([b"\n", b"\r\n"]))
def test_render_rows_from_tables_is_the_digit_by_digit_text(seed: int, rows: int, block_rows: int,
                                                            decimals: list[int], prefixes: list[bytes],
                                                            density: float, ending: bytes) -> None:
    """The table writer (words stored a few bytes at a time, straight to their place) against the
    digit-by-digit writer and Python's text: whole parts of 1 to 12 digits, short lines of one word
    in the same column as the line before's last (the head stores reach back), odd rows (nan)."""
    from prs3_post.core import numbers as fixed_module

    rng = np.random.default_rng(seed)
    values = rng.uniform(-1, 1, (rows, 3)) * 10.0 ** rng.integers(-3, 12, (rows, 3))
    values[rng.random((rows, 3)) < 0.05] = np.nan
    columns = [scale_column(values[:, j], d) for j, d in enumerate(decimals)]
    choice = ChoiceColumn(rng.integers(0, 3, rows), (b"G0", b"G1", b"falsity"))
    present = rng.random((rows, 4)) < density
    empty = ~present.any(axis=1)
    present[empty, rng.integers(0, 4, int(empty.sum()))] = True
    spec = [choice, *((p, c) for p, c in zip(prefixes, columns, strict=True))]
    buffer, ends = render_rows(spec, present, ending=ending, block_rows=block_rows)
    expected = []
    for row in range(rows):
        words = [choice.texts[choice.choice[row]].decode()] + [
            p.decode() + _python(values[row, j], d) for j, (p, d) in enumerate(zip(prefixes, decimals, strict=True))]
        expected.append(" ".join(w for w, on in zip(words, present[row], strict=True) if on) + ending.decode())
    assert buffer.tobytes().decode("ascii") == "".join(expected)
    assert np.diff(ends).tolist() == [len(line) for line in expected]
    digits = [fixed_module._render_block_digits(spec, present, lo, min(rows, lo + block_rows), b" ", ending)
              for lo in range(0, rows, block_rows)]
    assert b"".join(d.tobytes() for d, _ in digits) == buffer.tobytes()
    # render_rows takes the compiled writer where it was built: numpy's table writer gives the same bytes
    tables = [fixed_module._render_block(spec, present, lo, min(rows, lo + block_rows), b" ", ending)
              for lo in range(0, rows, block_rows)]
    assert b"".join(t.tobytes() for t, _ in tables) == buffer.tobytes()
