"""Fixed-decimal text of numbers: one definition for program words, tables, CSV and messages.

The text is always what Python's ``f"{value:.{decimals}f}"`` prints (the binary value rounded half
to even, never exponent notation), except that a value that rounds to zero never keeps its minus
sign: ``-0.00004`` with 4 decimals is ``0.0000``, not ``-0.0000``.

Two ways to get it:

* :func:`fixed` — one number (messages, headers, a table cell);
* :func:`scale_column` + :func:`render_rows` — whole columns at once, for programs and tables with
  millions of numbers. A column is first turned into integers (the printed digits without the
  point: ``-12.3457`` is ``-123457``), which also decide "is this word the same as the last one"
  without making any text; :func:`render_rows` then writes whole lines of words as bytes, digit
  position by digit position for all rows together, with no Python object per number.

How the integers stay exact: ``y = value·10^d`` is computed in float64 with a relative error of at
most 2⁻⁵³, so ``rint(y)`` is the correctly rounded integer unless ``y`` lies within that error of
a half-integer. Those rare near-ties, and numbers too large for exact integers (or not finite),
are formatted one by one with :func:`fixed`; the rest never touch Python floats.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from prs3_post.types import BoolArray, FloatArray, IntArray

__all__ = ["ChoiceColumn", "Column", "ScaledColumn", "fixed", "fixed_column", "render_rows", "scale_column"]

#: |value·10^d| below this is written from exact integers; at or above it (and nan/inf) one by one.
_EXACT_LIMIT = 2.0**52


def fixed(value: float, decimals: int = 4) -> str:
    """``value`` with ``decimals`` digits after the point; never exponent notation, never ``-0.000``.

    Parameters
    ----------
    value : float — any float (nan and inf give ``nan``, ``inf``, ``-inf``)
    decimals : int — ≥ 0 (0: no decimal point), 4 unless given

    Examples
    --------
    >>> fixed(-0.00004, 4), fixed(1.23456, 2), fixed(2.5, 0), fixed(-1e-9, 0), fixed(-12.5, 1)
    ('0.0000', '1.23', '2', '0', '-12.5')
    """
    text = f"{value:.{decimals}f}"
    if text[0] == "-" and not text.strip("-0."):  # every digit is 0: no sign
        return text[1:]
    return text


@dataclass(frozen=True, slots=True)
class ScaledColumn:
    """A column of numbers as the integers their fixed-decimal text shows.

    Attributes
    ----------
    scaled : (N,) int64 — the digits without the point, with the sign (``-12.3457`` → ``-123457``;
        0 for what prints as zero); 0 on the rows listed in ``odd``
    decimals : int — digits after the point
    odd : (K,) int64 — rows whose text could not be made from an int64 (not finite, or
        ``|value|·10^decimals ≥ 2⁵²``), increasing
    odd_text : tuple of str — their text, from :func:`fixed`
    """

    scaled: IntArray
    decimals: int
    odd: IntArray
    odd_text: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.scaled)

    def text(self, row: int) -> str:
        """The text of one row (for messages and for comparing odd rows)."""
        position = int(np.searchsorted(self.odd, row))
        if position < len(self.odd) and self.odd[position] == row:
            return self.odd_text[position]
        return _text_of_scaled(int(self.scaled[row]), self.decimals)

    def same_as_previous(self) -> BoolArray:
        """(N,) bool — row r prints exactly as row r − 1 (row 0: False)."""
        same = np.zeros(len(self.scaled), dtype=bool)
        same[1:] = self.scaled[1:] == self.scaled[:-1]
        for row in np.unique(np.concatenate([self.odd, self.odd + 1])).tolist():  # an odd row on either side
            if 1 <= row < len(same):
                same[row] = self.text(row) == self.text(row - 1)
        return same


def _text_of_scaled(scaled: int, decimals: int) -> str:
    digits = str(abs(scaled)).rjust(decimals + 1, "0")
    sign = "-" if scaled < 0 else ""
    return f"{sign}{digits[:-decimals]}.{digits[-decimals:]}" if decimals else f"{sign}{digits}"


def scale_column(values: FloatArray, decimals: int) -> ScaledColumn:
    """The integers that the fixed-decimal text of ``values`` shows (see :class:`ScaledColumn`).

    Parameters
    ----------
    values : (N,) float
    decimals : int — 0 … 15

    Examples
    --------
    >>> column = scale_column(np.array([-0.00004, 12.34565, 0.25, np.nan, 1e300]), 4)
    >>> column.scaled.tolist(), column.odd.tolist(), column.odd_text[0]
    ([0, 123456, 2500, 0, 0], [3, 4], 'nan')
    """
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    if not 0 <= decimals <= 15:
        raise ValueError(f"decimals must be 0..15, got {decimals}")
    with np.errstate(invalid="ignore", over="ignore"):
        y = values * 10.0**decimals             # one rounding: relative error ≤ 2⁻⁵³
        nearest = np.rint(y)                    # half to even, as Python's formatting on a true tie
        size = np.abs(y)
        wide = ~(size < _EXACT_LIMIT)           # also nan, inf
        # A half-integer within the rounding error of y: rint(y) may differ from the rounding of
        # the exact value·10^d; let Python's correctly rounded formatting decide.
        size *= 2.0**-50
        size += np.abs(y - nearest)
        near_tie = size >= 0.5                  # 0.5 − |y − rint(y)| ≤ |y|·2⁻⁵⁰
    if wide.any():
        near_tie &= ~wide
        nearest[wide] = 0.0
    scaled = nearest.astype(np.int64)           # rint(-0.3) is -0.0: the int is 0 either way
    for row in np.flatnonzero(near_tie).tolist():
        scaled[row] = int(fixed(float(values[row]), decimals).replace(".", ""))
    odd = np.flatnonzero(wide).astype(np.int64)
    return ScaledColumn(scaled=scaled, decimals=decimals, odd=odd,
                        odd_text=tuple(fixed(v, decimals) for v in values[odd].tolist()))


def fixed_column(values: FloatArray, decimals: int) -> list[str]:
    """:func:`fixed` of every value, computed for the whole column at once.

    >>> fixed_column(np.array([-0.00004, 1.5, -2.25, np.inf]), 1)
    ['0.0', '1.5', '-2.2', 'inf']
    """
    column = scale_column(values, decimals)
    if not len(column):
        return []
    buffer, _ = render_rows([(b"", column)], np.ones((len(column), 1), dtype=bool), ending=b"\n")
    return buffer.tobytes().decode("ascii").split("\n")[:-1]


@dataclass(frozen=True, slots=True)
class ChoiceColumn:
    """A column of words picked per row from a few fixed texts (``G0``/``G1``, ``true``/``false``).

    Attributes
    ----------
    choice : (N,) int — index into ``texts`` per row
    texts : tuple of bytes — ASCII
    """

    choice: IntArray
    texts: tuple[bytes, ...]


#: One column of a row of words: a number with its prefix (the word letter), or a choice.
Column = tuple[bytes, ScaledColumn] | ChoiceColumn


def _digit_count(magnitude: IntArray) -> IntArray:
    """(N,) int — decimal digits of each non-negative integer (0 has one)."""
    count = np.ones(len(magnitude), dtype=np.int64)
    for power in range(1, 19):
        above = magnitude >= 10**power
        if not above.any():
            break
        count += above
    return count


def render_rows(columns: Sequence[Column], present: BoolArray, *, separator: bytes = b" ",
                ending: bytes = b"\n", block_rows: int = 8192) -> tuple[np.ndarray, IntArray]:
    """Lines of words as ASCII bytes, for all rows at once.

    Row r is the words of the columns where ``present[r, j]`` (in column order) joined by
    ``separator``, then ``ending``. A number word is its prefix and the number's fixed-decimal text.

    Parameters
    ----------
    columns : sequence of ``(prefix, ScaledColumn)`` or ChoiceColumn, each with N rows
    present : (N, C) bool — which words each line has; every row needs at least one
    separator : bytes — one ASCII byte
    ending : bytes — ASCII
    block_rows : int — rows formatted together (the scratch memory is about 100 bytes per row)

    Returns
    -------
    buffer : (B,) uint8 — the lines, back to back
    ends : (N + 1,) int — row r is ``buffer[ends[r]:ends[r + 1]]`` (with its ending); ``ends[0] == 0``

    Examples
    --------
    >>> x = scale_column(np.array([1.5, -0.04]), 1)
    >>> g = ChoiceColumn(np.array([0, 1]), (b"G0", b"G1"))
    >>> buffer, ends = render_rows([g, (b"X", x)], np.array([[True, True], [True, False]]))
    >>> buffer.tobytes(), ends.tolist()
    (b'G0 X1.5\\nG1\\n', [0, 8, 11])
    """
    present = np.asarray(present, dtype=bool)
    rows = present.shape[0]
    if rows and not present.any(axis=1).all():
        raise ValueError("render_rows: a row without any word")
    if len(separator) != 1 or separator == b"\0" or b"\0" in ending:
        raise ValueError(f"render_rows: the separator must be one byte other than NUL, got {separator!r}")
    blocks = [_render_block(columns, present, lo, min(rows, lo + block_rows), separator, ending)
              for lo in range(0, rows, block_rows)]
    ends = np.zeros(rows + 1, dtype=np.int64)
    if blocks:
        np.cumsum(np.concatenate([length for _, length in blocks]), out=ends[1:])
    buffer = np.concatenate([text for text, _ in blocks]) if blocks else np.zeros(0, dtype=np.uint8)
    return buffer, ends


def _render_block(columns: Sequence[Column], present: BoolArray, lo: int, hi: int, separator: bytes,
                  ending: bytes) -> tuple[np.ndarray, IntArray]:
    """Rows ``lo:hi`` of :func:`render_rows`: (their bytes, each line's length with its ending).

    Each word goes right-aligned, with one separator byte before it, into its own field of a
    NUL-filled grid with a fixed byte column per character position; absent words stay NUL;
    dropping every NUL then leaves the lines back to back. The grid is held transposed
    (``grid[column, row]``), so that writing one digit position of every row is one contiguous write.
    """
    m = hi - lo
    on_all = present[lo:hi]
    fields = [_Field.of(column, lo, hi) for column in columns]
    offsets = np.cumsum([0] + [f.width for f in fields])
    stride = int(offsets[-1]) + len(ending)
    grid = np.zeros((stride, m), dtype=np.uint8)
    flat = grid.reshape(-1)                                  # grid[c, r] is flat[c·m + r]
    rows = np.arange(m, dtype=np.int64)
    words = np.zeros((m, len(fields)), dtype=np.int64)      # width of each word with its separator
    for j, field in enumerate(fields):
        on = on_all[:, j]
        field.write(grid, flat, rows, int(offsets[j]), separator[0])
        words[:, j] = np.where(on, field.lengths + 1, 0)
        if not on.all():
            grid[offsets[j]:offsets[j + 1]] *= on            # absent words: NUL
    for k, byte in enumerate(ending):
        grid[stride - len(ending) + k] = byte
    # the first word of a line has no separator before it
    first = np.argmax(on_all, axis=1)
    right = offsets[1:][first]                               # end of that word's field
    flat[(right - words[rows, first]) * m + rows] = 0
    lengths = words.sum(axis=1) - 1 + len(ending)
    lines = np.ascontiguousarray(grid.T).reshape(-1)
    return np.compress(lines != 0, lines), lengths     # compress: several times faster than a mask index


def _narrow(values: IntArray) -> np.ndarray:
    """int32 where the values fit (its division is several times faster), else int64."""
    return values.astype(np.int32) if values.max(initial=0) < 2**31 else values


def _write_digits(grid: np.ndarray, values: np.ndarray, last: int, places: int, digits: IntArray | None) -> None:
    """The decimal digits of ``values`` (M,) ≥ 0, units digit in grid column ``last``, ``places`` digits
    to the left; with ``digits`` given, a row's digits beyond its own count stay NUL (no leading zeros)."""
    remaining = values
    for place in range(places):
        quotient = remaining // 10                           # // is fast; % is not
        char = grid[last - place]
        np.subtract(remaining, quotient * 10, out=char, casting="unsafe")
        char += ord("0")
        if digits is not None and place:
            char[digits <= place] = 0
        remaining = quotient


@dataclass(slots=True)
class _Field:
    """One column's words for a block of rows, right-aligned in ``width`` bytes (separator included)."""

    column: Column
    lengths: IntArray            # (m,) bytes of each row's word, without the separator
    width: int
    parts: tuple[IntArray, IntArray, IntArray, BoolArray] | None   # whole, fraction, digits, negative
    choice: IntArray | None                                        # a ChoiceColumn's rows
    odd: list[tuple[int, bytes]]                                   # (row in block, prefix + text) as is

    @classmethod
    def of(cls, column: Column, lo: int, hi: int) -> _Field:
        if isinstance(column, ChoiceColumn):
            sizes = np.array([len(t) for t in column.texts], dtype=np.int64)
            lengths = sizes[column.choice[lo:hi]]
            return cls(column, lengths, 1 + int(sizes.max(initial=0)), None, column.choice[lo:hi], [])
        prefix, numbers = column
        scaled = numbers.scaled[lo:hi]
        magnitude = np.abs(scaled)
        unit = 10**numbers.decimals
        whole = magnitude // unit
        fraction = magnitude - whole * unit
        digits = _digit_count(whole)
        negative = scaled < 0
        lengths = len(prefix) + negative + digits + (numbers.decimals + 1 if numbers.decimals else 0)
        first, last = np.searchsorted(numbers.odd, [lo, hi])
        odd = [(int(row) - lo, prefix + text.encode("ascii"))
               for row, text in zip(numbers.odd[first:last].tolist(), numbers.odd_text[first:last], strict=True)]
        # the digits of an odd row are written too (from its placeholder 0), then overwritten: room for both
        width = 1 + int(lengths.max(initial=0))
        for row, text in odd:
            lengths[row] = len(text)
        width = max(width, 1 + int(lengths.max(initial=0)))
        return cls(column, lengths, width, (whole, fraction, digits, negative), None, odd)

    def write(self, grid: np.ndarray, flat: np.ndarray, rows: IntArray, offset: int, separator: int) -> None:
        """Every row's word and the separator before it into ``grid[offset : offset + width]``."""
        end = offset + self.width                            # one past the field's last byte
        m = len(rows)
        column = self.column
        if isinstance(column, ChoiceColumn):
            for index, text in enumerate(column.texts):
                chosen = rows[self.choice == index]
                for k, byte in enumerate(text):
                    flat[(end - len(text) + k) * m + chosen] = byte
        else:
            assert self.parts is not None
            self._write_number(grid, flat, rows, offset, end, *column, self.parts)
        flat[(end - self.lengths - 1) * m + rows] = separator

    def _write_number(self, grid: np.ndarray, flat: np.ndarray, rows: IntArray, offset: int, end: int,
                      prefix: bytes, numbers: ScaledColumn,
                      parts: tuple[IntArray, IntArray, IntArray, BoolArray]) -> None:
        whole, fraction, digits, negative = parts
        m = len(rows)
        decimals = numbers.decimals
        units = end - 1 - (decimals + 1 if decimals else 0)  # the grid column of the units digit
        if decimals:
            _write_digits(grid, _narrow(fraction), end - 1, decimals, None)
            grid[units + 1] = ord(".")
        _write_digits(grid, _narrow(whole), units, int(digits.max(initial=0)), digits)
        head = units - digits                                # where the sign goes (or the prefix ends)
        flat[head[negative] * m + rows[negative]] = ord("-")
        head = head - negative
        for k, byte in enumerate(reversed(prefix)):
            flat[(head - k) * m + rows] = byte
        for row, text in self.odd:
            grid[offset:end, row] = 0
            grid[end - len(text):end, row] = np.frombuffer(text, dtype=np.uint8)
