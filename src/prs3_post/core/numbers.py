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

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from prs3_post.core.columns import ChoiceColumn, Column, ScaledColumn
from prs3_post.core.types import BoolArray, FloatArray, IntArray

__all__ = ["REPORT_DECIMALS", "ChoiceColumn", "Column", "ScaledColumn", "degrees_text", "exact_list", "exact_text",
           "fixed", "fixed_column", "fixed_list", "fixed_or_na", "format_word", "render_rows", "scale_column",
           "short_text", "short_tuple"]

#: Decimals a report or message shows of a number unless told otherwise (mm: 0.1 µm).
REPORT_DECIMALS = 4

#: |value·10^d| below this is written from exact integers; at or above it (and nan/inf) one by one.
_EXACT_LIMIT = 2.0**52


def fixed(value: float, decimals: int = REPORT_DECIMALS) -> str:
    """``value`` with ``decimals`` digits after the point; never exponent notation, never ``-0.000``.

    Parameters
    ----------
    value : float — any float (nan and inf give ``nan``, ``inf``, ``-inf``)
    decimals : int — ≥ 0 (0: no decimal point), :data:`REPORT_DECIMALS` unless given

    Examples
    --------
    >>> fixed(-0.00004, 4), fixed(1.23456, 2), fixed(2.5, 0), fixed(-1e-9, 0), fixed(-12.5, 1)
    ('0.0000', '1.23', '2', '0', '-12.5')
    """
    text = f"{value:.{decimals}f}"
    if text[0] == "-" and not text.strip("-0."):  # every digit is 0: no sign
        return text[1:]
    return text


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


def fixed_or_na(value: float | None, decimals: int = REPORT_DECIMALS) -> str:
    """:func:`fixed`, and ``n/a`` for a missing value (NaN in a record; the reports of ik, fk and verify).

    >>> fixed_or_na(-0.00001), fixed_or_na(1.23456, 2), fixed_or_na(None)
    ('0.0000', '1.23', 'n/a')
    """
    return "n/a" if value is None else fixed(value, decimals)


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
                ending: bytes = b"\n", block_rows: int = 16384) -> tuple[np.ndarray, IntArray]:
    """Lines of words as ASCII bytes, for all rows at once.

    Row r is the words of the columns where ``present[r, j]`` (in column order) joined by
    ``separator``, then ``ending``. A number word is its prefix and the number's fixed-decimal text.

    Parameters
    ----------
    columns : sequence of ``(prefix, ScaledColumn)`` or ChoiceColumn, each with N rows
    present : (N, C) bool — which words each line has; every row needs at least one
    separator : bytes — one ASCII byte
    ending : bytes — ASCII, at least one byte
    block_rows : int — rows formatted together (the scratch memory is about 100 bytes per row)

    The lines are written by the compiled writer (:mod:`prs3_post.core.native`) where it was built, else by
    numpy: the same bytes.

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
    if rows and not _any_per_row(present).all():
        raise ValueError("render_rows: a row without any word")
    if len(separator) != 1 or separator == b"\0" or b"\0" in ending:
        raise ValueError(f"render_rows: the separator must be one byte other than NUL, got {separator!r}")
    if not ending or b"\0" in ending:                 # (a first word's separator lands on the ending's last byte)
        raise ValueError(f"render_rows: the line ending must be one or more bytes other than NUL, got {ending!r}")
    from prs3_post.core import native  # ctypes: loaded only where lines are written

    render = _render_block
    if native.available():
        render, block_rows = native.render_block, max(block_rows, 65536)    # no scratch grid: any size
    blocks = [render(columns, present, lo, min(rows, lo + block_rows), separator, ending)
              for lo in range(0, rows, block_rows)]
    ends = np.zeros(rows + 1, dtype=np.int64)
    if blocks:
        np.cumsum(np.concatenate([length for _, length in blocks]), out=ends[1:])
    if len(blocks) == 1:
        buffer = blocks[0][0]
    else:
        buffer = np.concatenate([text for text, _ in blocks]) if blocks else np.zeros(0, dtype=np.uint8)
    return buffer, ends


def _render_block(columns: Sequence[Column], present: BoolArray, lo: int, hi: int, separator: bytes,
                  ending: bytes) -> tuple[np.ndarray, IntArray]:
    """Rows ``lo:hi`` of :func:`render_rows`: (their bytes, each line's length with its ending).

    Every word goes straight to its place in the output, a few bytes at a time from tables
    (:class:`_Layout`), where the columns allow it; else the words are written digit by digit
    (:func:`_render_block_digits`).

    Words are written column by column, each right-aligned so that it ends where it must: a head
    (separator, prefix, sign and whole digits) is one 8-byte store whose leading NUL bytes keep
    what is already there (the word before), four decimals are one 4-byte store; the first word's
    separator falls on the line before's last byte, and the line endings are written last.
    """
    m = hi - lo
    on_all = present[lo:hi]
    layouts = [_Layout.of(column, lo, hi) for column in columns]
    if not m or any(layout is None for layout in layouts):
        return _render_block_digits(columns, present, lo, hi, separator, ending)
    # where each word ends within its line (with its separator), column by column: a running sum over
    # the columns (sums along the rows' short axis are several times slower)
    on_columns = np.ascontiguousarray(on_all.T)              # (C, m)
    within = np.zeros((len(layouts), m), dtype=np.int64)
    total = np.zeros(m, dtype=np.int64)
    for j, layout in enumerate(layouts):
        total += (layout.lengths + 1) * on_columns[j]       # type: ignore[union-attr]
        within[j] = total
    lengths = total - 1 + len(ending)
    line_end = np.cumsum(lengths)
    line_start = line_end - lengths - 1 + _FRONT
    out = np.zeros(_FRONT + int(line_end[-1]), dtype=np.uint8)
    for j, layout in enumerate(layouts):
        on = on_columns[j]
        if not layout.write(out, line_start + within[j], None if on.all() else np.flatnonzero(on),  # type: ignore[union-attr]
                            separator):
            return _render_block_digits(columns, present, lo, hi, separator, ending)
    for k, byte in enumerate(ending):
        out[_FRONT + line_end - len(ending) + k] = byte
    return out[_FRONT:], lengths


def _any_per_row(present: BoolArray) -> BoolArray:
    """(N,) bool — ``present.any(axis=1)`` of an (N, C) array, one column at a time (faster for few columns)."""
    if present.shape[1] == 0:
        return np.zeros(present.shape[0], dtype=bool)
    anywhere = present[:, 0].copy()
    for j in range(1, present.shape[1]):
        anywhere |= present[:, j]
    return anywhere


#: Bytes before a block's output: a line's first head store may reach 8 bytes before the line.
_FRONT = 8


def _digit_table() -> np.ndarray:
    """(10000,) little-endian uint32: the four ASCII digits of k with leading zeros (``0042``)."""
    k = np.arange(10_000)
    digits = np.column_stack([k // 1000, k // 100 % 10, k // 10 % 10, k % 10]).astype(np.uint8) + ord("0")
    return np.ascontiguousarray(digits).view("<u4").reshape(-1)


_DIGITS4 = _digit_table()
#: (10000,) int64: the decimal digits of k (no leading zeros; 0 has one).
_COUNT4 = 1 + (np.arange(10_000) >= 10) + (np.arange(10_000) >= 100) + (np.arange(10_000) >= 1000)
_HEAD_TABLES: dict[tuple[bytes, bytes], tuple[np.ndarray, np.ndarray]] = {}


def _head_table(prefix: bytes, separator: bytes) -> tuple[np.ndarray, np.ndarray]:
    """(20000,) little-endian uint64 each: entry ``10000·negative + k`` of the first is the separator,
    ``prefix``, a minus sign when negative and the digits of k (no leading zeros), right-aligned in
    8 bytes (NUL before them); of the second, the mask of those NUL bytes (what a store keeps).
    ``prefix`` has at most 2 bytes."""
    key = (prefix, separator)
    if key not in _HEAD_TABLES:
        k = np.tile(np.arange(10_000), 2)
        negative = np.repeat([0, 1], 10_000)
        table = np.zeros((20_000, 8), dtype=np.uint8)
        rows = np.arange(20_000)
        count = _digit_count(k)
        remaining = k.copy()
        for place in range(4):                            # the digits, units in byte 7
            has = place < count
            table[rows[has], 7 - place] = remaining[has] % 10 + ord("0")
            remaining //= 10
        head = 7 - count                                  # the byte before the first digit
        table[rows[negative == 1], head[negative == 1]] = ord("-")
        head = head - negative
        for byte in reversed(prefix):
            table[rows, head] = byte
            head = head - 1
        table[rows, head] = separator[0]
        keep = (table == 0).astype(np.uint8) * np.uint8(255)
        _HEAD_TABLES[key] = (table.view("<u8").reshape(-1), keep.view("<u8").reshape(-1))
    return _HEAD_TABLES[key]


def _choice_table(texts: tuple[bytes, ...], separator: bytes) -> np.ndarray:
    """(K,) little-endian uint64: the separator and each text right-aligned in 8 bytes (NUL before)."""
    table = np.zeros((len(texts), 8), dtype=np.uint8)
    for k, text in enumerate(texts):
        word = separator + text
        table[k, 8 - len(word):] = np.frombuffer(word, dtype=np.uint8)
    return table.view("<u8").reshape(-1)


def _merge(out: np.ndarray, at: IntArray, values: np.ndarray, keep: np.ndarray) -> None:
    """Store 8 bytes at each ``at`` (byte offsets into ``out``), keeping the existing bytes where
    ``keep`` has its bits set (the leading NUL bytes of each value)."""
    view = np.ndarray((len(out) - 7,), dtype="<u8", buffer=out, strides=(1,))
    old = view[at]
    old &= keep
    old |= values
    view[at] = old


def _store4(out: np.ndarray, at: IntArray, values: np.ndarray) -> None:
    """Store the 4 bytes of each uint32 value at byte offset ``at`` of ``out``."""
    view = np.ndarray((len(out) - 3,), dtype="<u4", buffer=out, strides=(1,))
    view[at] = values


@dataclass(slots=True)
class _Layout:
    """One column's words for a block of rows, stored from tables (:meth:`write`).

    A number word is its head (separator, prefix, sign, whole digits: one 8-byte store, or a store
    of the top digits and a 4-byte one of the last four when the whole part has 5 to 8 digits),
    then the point and the decimals (4-byte stores of four digits, from the right); a choice is
    one 8-byte store. Rows whose text could not be made from integers (``ScaledColumn.odd``) are
    copied as they are.
    """

    column: Column
    lengths: IntArray            # (m,) bytes of each row's word, without the separator
    tail: int                    # bytes after the head: the point and the decimals
    lo: int
    hi: int
    head: IntArray | None        # (m,) index of each row's head in the head table (10000·negative + top digits)
    low: IntArray | None         # (m,) the last four whole digits (5 to 8 digits), else −1
    fraction: IntArray | None    # (m,) the decimals as an integer

    @classmethod
    def of(cls, column: Column, lo: int, hi: int) -> _Layout | None:
        """The layout, or None where the tables do not serve (a prefix over 2 bytes, a whole part
        over 8 digits, a choice over 7 bytes)."""
        if isinstance(column, ChoiceColumn):
            sizes = np.array([len(t) for t in column.texts], dtype=np.int64)
            if sizes.max(initial=0) > 7:
                return None
            return cls(column, sizes[column.choice[lo:hi]], 0, lo, hi, None, None, None)
        prefix, numbers = column
        if len(prefix) > 2:
            return None
        scaled = numbers.scaled[lo:hi]
        magnitude = np.abs(scaled)
        unit = 10**numbers.decimals
        whole = magnitude // unit
        fraction = magnitude - whole * unit
        if numbers.decimals <= 9:
            fraction = fraction.astype(np.int32)     # its divisions are several times faster
        top = int(whole.max(initial=0))
        negative = scaled < 0
        if top < 10_000:
            head, low = whole, None
            count = _COUNT4[whole]
        elif top < 10**8:
            big = whole >= 10_000
            head = np.where(big, whole // 10_000, whole)
            low = np.where(big, whole - head * 10_000, -1)
            count = _COUNT4[head] + 4 * big
        else:
            return None
        tail = numbers.decimals + 1 if numbers.decimals else 0
        lengths = len(prefix) + negative + count + tail
        first, last = np.searchsorted(numbers.odd, [lo, hi])
        for row, text in zip((numbers.odd[first:last] - lo).tolist(), numbers.odd_text[first:last], strict=True):
            lengths[row] = len(prefix) + len(text)
        return cls(column, lengths, tail, lo, hi, head + negative * 10_000, low, fraction)

    def write(self, out: np.ndarray, end: IntArray, rows: IntArray | None, separator: bytes) -> bool:
        """Each row's word with the separator before it, ending at ``end`` (m,) in ``out``; only
        ``rows`` (None: all). False, with nothing written, where one row's head store would reach
        the head of the row before (short lines: the caller writes the block digit by digit)."""
        column = self.column
        if isinstance(column, ChoiceColumn):
            choice = column.choice[self.lo:self.hi]
            if rows is not None:
                choice, end = choice[rows], end[rows]
            if (end[1:] - 8 < end[:-1]).any():
                return False
            table = _choice_table(column.texts, separator)
            _merge(out, end - 8, table[choice], _keep_of(table)[choice])
            return True
        assert self.head is not None and self.fraction is not None
        prefix, numbers = column
        first, last = np.searchsorted(numbers.odd, [self.lo, self.hi])
        odd = numbers.odd[first:last] - self.lo
        odd_end = end[odd]
        head, low, fraction = self.head, self.low, self.fraction
        if rows is not None or len(odd):
            written = np.zeros(len(end), dtype=bool) if rows is not None else np.ones(len(end), dtype=bool)
            if rows is not None:
                written[rows] = True
            odd_written = written[odd]
            written[odd] = False                      # copied below: their placeholder 0 is not their text
            rows = np.flatnonzero(written)
            end, head, fraction = end[rows], head[rows], fraction[rows]
            low = None if low is None else low[rows]
        else:
            odd_written = np.zeros(0, dtype=bool)
        point = end - self.tail                       # where the decimal point goes (or the word ends)
        head_end = point                              # the head store ends here (4 digits before for 5 to 8)
        big = None
        if low is not None:
            big = np.flatnonzero(low >= 0)
            head_end = point.copy()
            head_end[big] -= 4
        if (head_end[1:] - 8 < head_end[:-1]).any():
            return False
        if numbers.decimals:
            remaining = fraction
            for group_end in range(numbers.decimals, 0, -4):   # four digits at a time, from the right; the
                remaining, group = np.divmod(remaining, 10_000)  # last (leftmost) store reaches back onto
                _store4(out, point + (group_end - 3), _DIGITS4[group])   # the point and head, stored after it
            out[point] = ord(".")
        if big is not None and low is not None and len(big):
            _store4(out, head_end[big], _DIGITS4[low[big]])
        values, keep = _head_table(prefix, separator)
        _merge(out, head_end - 8, values[head], keep[head])
        for stop, on, odd_text in zip(odd_end.tolist(), odd_written.tolist(), numbers.odd_text[first:last],
                                      strict=True):
            if on:
                word = separator + prefix + odd_text.encode("ascii")
                out[stop - len(word):stop] = np.frombuffer(word, dtype=np.uint8)
        return True


def _keep_of(table: np.ndarray) -> np.ndarray:
    """The mask of the NUL bytes of each uint64 of ``table``."""
    return ((table.view(np.uint8) == 0).astype(np.uint8) * np.uint8(255)).view("<u8")


def _render_block_digits(columns: Sequence[Column], present: BoolArray, lo: int, hi: int, separator: bytes,
                  ending: bytes) -> tuple[np.ndarray, IntArray]:
    """Rows ``lo:hi`` of :func:`render_rows` (the general way, for any column): (their bytes, each
    line's length with its ending).

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

def exact_text(value: float, decimals: int) -> str:
    """``value`` in fixed decimals, at least ``decimals`` and as many more as reading it back exactly takes.

    >>> exact_text(6.0, 3), exact_text(2.00001, 3), exact_text(-0.0, 4), exact_text(0.1 + 0.2, 1)
    ('6.000', '2.00001', '0.0000', '0.30000000000000004')
    """
    for places in range(decimals, 25):
        text = fixed(value, places)
        if float(text) == value:
            return text
    return repr(float(value))                           # not reached for finite values

def format_word(letter: str, value: float, decimals: int) -> str:
    """One G-code word with fixed decimals: never exponent notation, never ``-0.000``.

    Parameters
    ----------
    letter : str
        The word letter (``X``).
    value : float
        The number; rounded half-even on its binary value by Python's fixed-point formatting.
    decimals : int
        Digits after the decimal point (0: no decimal point).

    Returns
    -------
    str
        e.g. ``X-12.3457``; ``X0.0000`` for ``-0.00004``.

    Raises
    ------
    ValueError
        When ``value`` is nan or infinite (the caller, which knows the row, reports it).

    Examples
    --------
    >>> format_word("X", -0.00004, 4), format_word("U", 1e-5, 4), format_word("F", 2.0, 0)
    ('X0.0000', 'U0.0000', 'F2')
    """
    if not math.isfinite(value):
        raise ValueError(f"{letter}: {value!r} is not a finite number")
    return f"{letter}{fixed(value, decimals)}"


def degrees_text(radians: float, decimals: int) -> str:
    """An angle kept in radians, in degrees such that ``math.radians(float(text)) == radians``.

    >>> degrees_text(math.radians(15.0), 3), degrees_text(math.radians(3.0), 3)
    ('15.000', '3.000')
    """
    degrees = math.degrees(radians)
    candidate = degrees
    for _ in range(64):                                # radians() may not invert degrees(): nudge
        if math.radians(candidate) == radians:
            break
        candidate = float(np.nextafter(candidate, math.inf if math.radians(candidate) < radians else -math.inf))
    else:
        candidate = degrees
    for places in range(decimals, 25):
        text = fixed(candidate, places)
        if math.radians(float(text)) == radians:
            return text
    return repr(candidate)


def exact_list(values: Iterable[float], decimals: int) -> str:
    """``[a, b, c]``, each :func:`exact_text` (read back as the same float).

    >>> exact_list([1.0, 0.1 + 0.2], 1)
    '[1.0, 0.30000000000000004]'
    """
    return "[" + ", ".join(exact_text(float(v), decimals) for v in values) + "]"


def fixed_list(values: Iterable[float], decimals: int) -> str:
    """``[a, b, c]`` in fixed decimals, for people (not read back).

    >>> fixed_list([1.0, -0.00001], 3)
    '[1.000, 0.000]'
    """
    return "[" + ", ".join(fixed(float(v), decimals) for v in values) + "]"


def short_text(value: float) -> str:
    """A number for a message, in at most six significant digits (never 300 digits; may be exponent notation).

    >>> short_text(1.0), short_text(1e300), short_text(-0.1234567)
    ('1', '1e+300', '-0.123457')
    """
    return f"{value:.6g}"


def short_tuple(values: Iterable[float]) -> str:
    """``(a, b, c)``, each :func:`short_text` (a vector in a message).

    >>> short_tuple([0.0, 1.5, 1 / 3])
    '(0, 1.5, 0.333333)'
    """
    return "(" + ", ".join(short_text(float(v)) for v in values) + ")"
