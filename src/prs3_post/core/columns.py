"""The columns that :func:`prs3_post.core.numbers.render_rows` and the compiled writer
(:mod:`prs3_post.core.native`) write as lines of words: numbers as the integers their fixed-decimal text
shows, and choices among a few fixed texts. Data only; :mod:`prs3_post.core.numbers` makes them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import BoolArray, IntArray

__all__ = ["ChoiceColumn", "Column", "ScaledColumn"]


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
