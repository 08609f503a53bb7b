"""The G-code lexer: bytes → text → lines → comments and words, shared by every reader of G-code.

Strict on purpose: whatever it does not read exactly is a :class:`~prs3_post.errors.LexError` (with the
column and the text found), never skipped. It knows no file and no line number: a reader wraps the
error in an :class:`~prs3_post.errors.InputError` naming both. It knows no codes either: which
letters and codes a program may use, modal groups and modal state are the readers' business
(:mod:`prs3_post.readers.program` for prs3-post's own programs; the CAM G-code reader).

What it reads (LinuxCNC's lexical rules, restricted to plain numbers)
--------------------------------------------------------------------
- :func:`decode`: the file is UTF-8 text without a byte-order mark and without control bytes
  other than TAB, LF and CR (binary data, Latin-1 and empty files are refused with what was found).
- :func:`split_comments`: comments between delimiters (``(...)``), or from an opener to the end of
  the line (``;...``); several styles at once (``LINUXCNC_COMMENTS``: both) or a dialect's one pair.
  An unclosed comment, or one that contains its own opener (LinuxCNC rejects nested comments), is
  an error.
- :func:`lex_words`: words, each a letter (either case; returned upper case) and a plain decimal
  number: ``-12.5``, ``.5``, ``5.``, ``007``; no ``+``, no exponent (``1e-5`` reads as the words
  ``1`` … ``E-5``: the reader decides that ``E`` is not a word it takes), no ``[expression]``, no
  ``#parameter`` (a clear error: those need LinuxCNC's interpreter). Spaces and tabs between and
  inside words are ignored, as LinuxCNC ignores them (``X 1 . 5`` is ``X1.5``). Non-ASCII
  characters are errors (Python would upper-case ``ı`` to ``I`` and read ``٣`` as a digit).
- :func:`lex_line`: both steps on one line.
- :func:`code_name` (``G43.4``, ``M3``) and :func:`quote` (a line shortened for a message).

Words are plain tuples ``(letter, value, text)``: ``('X', -1.5, 'X-1.5')``, the text upper case
without spaces (for messages such as ``X1 and X2``).

The fast path
-------------
:func:`lex_columns` reads a whole chunk of lines at once into a (N, L) array, one column per letter,
for lines of a *regular shape*: upper-case words of the given letters in the given order, each at
most once, separated by spaces (``G1 X-1.5 Y2 F100.``), no comment. It marks the lines it read;
every other line (comments, other letters or order, lower case, spaces inside numbers, anything
wrong) must go through :func:`lex_line`, which reads it or says exactly what is wrong. Where both
read a line they agree exactly (values are ``float`` of the same text: correctly rounded).

pygcode is the reference of a differential test (tests/test_lexer.py), where it is documented
wrong listed there (it skips characters it does not know, reads non-ASCII letters, ...).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from prs3_post.errors import LexError
from prs3_post.types import BoolArray, FloatArray, IntArray

__all__ = [
    "BYTE_ORDER_MARK", "EMPTY", "LINUXCNC_COMMENTS", "NUMBER", "Word", "code_name", "column_pattern", "decode",
    "forward_fill", "lex_column_block", "lex_columns", "lex_line",
    "lex_words", "quote", "split_comments",
]

#: A word: upper-case letter, value, text as read (upper case, no spaces): ``('G', 43.4, 'G43.4')``.
Word = tuple[str, float, str]
#: Comment delimiters LinuxCNC reads: ``(...)`` and ``;`` to the end of the line.
LINUXCNC_COMMENTS: tuple[tuple[str, str], ...] = (("(", ")"), (";", ""))
#: A plain decimal number (ASCII digits only: ``\d`` would take other scripts' digits).
NUMBER = r"-?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)"
_WORD = re.compile(rf"([A-Za-z])({NUMBER})")
_WORDS = re.compile(rf"(?:[A-Za-z]{NUMBER})*")
_SPACES = str.maketrans("", "", " \t")
_HINT = "a letter and a plain decimal number, e.g. G1 X-1.5"


# ----------------------------------------------------------------------------- bytes to text


#: The message for a file with nothing but white space.
EMPTY = "not a G-code program: the file is empty"
#: The message for a file that starts with a UTF-8 byte-order mark.
BYTE_ORDER_MARK = "starts with a UTF-8 byte-order mark, which LinuxCNC rejects ('Bad character')"


def decode(data: bytes, *, offset: int | None = None) -> str:
    """The text of a G-code file's bytes.

    Parameters
    ----------
    data : bytes — the whole file; or, with ``offset``, a piece of it that starts at a line start
    offset : int, optional — where the piece starts in the file (for byte offsets in messages). A
        piece is not checked for being empty or for a byte-order mark: a reader that reads a file in
        pieces checks that itself (``EMPTY``, ``BYTE_ORDER_MARK``), in this order: empty, mark, the
        first piece's error.

    Raises
    ------
    LexError
        ``not a G-code program: the file is empty``, ``starts with a UTF-8 byte-order mark ...``,
        ``not a G-code program: binary data (byte 0x1a at offset 6)``, ``not a G-code program: not
        UTF-8 text (byte 0xe9 at offset 12)``.
    """
    if offset is None:
        if not data.strip():
            raise LexError(EMPTY)
        if data.startswith(b"\xef\xbb\xbf"):
            raise LexError(BYTE_ORDER_MARK)
        offset = 0
    codes = np.frombuffer(data, dtype=np.uint8)
    control = np.flatnonzero(((codes < 32) & (codes != 9) & (codes != 10) & (codes != 13)) | (codes == 127))
    if len(control):
        at = int(control[0])
        raise LexError(f"not a G-code program: binary data (byte 0x{codes[at]:02x} at offset {offset + at})")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise LexError(f"not a G-code program: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                       f"{offset + exc.start})") from exc


# ----------------------------------------------------------------------------- one line


def split_comments(line: str, delimiters: Sequence[tuple[str, str]] = LINUXCNC_COMMENTS) -> tuple[str, tuple[str, ...]]:
    """A line's code without its comments, and the comments' texts (without delimiters).

    Parameters
    ----------
    line : str — one line, without its line ending
    delimiters : sequence of (open, close) — ``close == ''``: the comment runs to the end of the line.
        The first opener on the line starts a comment, whose text may contain the other styles'
        openers (``(a;b)`` is one comment) but not its own (a nested comment).

    Raises
    ------
    LexError
        ``comment opened with '(' at column 59 is not closed with ')'``, ``comment at column 3
        contains another '(' (LinuxCNC rejects nested comments)``.
    """
    if not any(open_ in line for open_, _ in delimiters):
        return line, ()
    code: list[str] = []
    comments: list[str] = []
    pos = 0
    while True:
        found = [(at, open_, close) for open_, close in delimiters if (at := line.find(open_, pos)) >= 0]
        if not found:
            code.append(line[pos:])
            return "".join(code), tuple(comments)
        start, open_, close = min(found, key=lambda f: f[0])
        code.append(line[pos:start])
        inside = start + len(open_)
        if not close:
            comments.append(line[inside:])
            return "".join(code), tuple(comments)
        end = line.find(close, inside)
        if end < 0:
            raise LexError(f"comment opened with {open_!r} at column {start + 1} is not closed with {close!r}",
                           column=start + 1, found=line[start:])
        if open_ in line[inside:end]:
            raise LexError(f"comment at column {start + 1} contains another {open_!r} (LinuxCNC rejects nested "
                           "comments)", column=start + 1, found=line[start:end + len(close)])
        comments.append(line[inside:end])
        pos = end + len(close)


def lex_words(code: str) -> tuple[Word, ...]:
    """The words of comment-free code (module docstring: what a word is).

    >>> lex_words("g1 x-1.5 Y .5 F 100.")
    (('G', 1.0, 'G1'), ('X', -1.5, 'X-1.5'), ('Y', 0.5, 'Y.5'), ('F', 100.0, 'F100.'))

    Raises
    ------
    LexError
        With the column of the first character that does not continue a word: ``column 4: '['
        starts an expression ...``, ``column 1: cannot read 'hello' as words (...)``.
    """
    squeezed = code.translate(_SPACES)
    if _WORDS.fullmatch(squeezed) is None:
        raise _word_error(code)
    upper = squeezed.upper()                           # ASCII only: the pattern allows nothing else
    return tuple((m[1], float(m[2]), m[0]) for m in _WORD.finditer(upper))


def lex_line(line: str, delimiters: Sequence[tuple[str, str]] = LINUXCNC_COMMENTS) -> tuple[Word, ...]:
    """The words of one line: :func:`split_comments`, then :func:`lex_words` (columns stay those of ``line``).

    >>> lex_line("N10 G0 X1 (start) ; rapid")
    (('N', 10.0, 'N10'), ('G', 0.0, 'G0'), ('X', 1.0, 'X1'))

    Raises
    ------
    LexError
    """
    code, _ = split_comments(line, delimiters)
    return lex_words(code)


def _word_error(code: str) -> LexError:
    """Where and why ``code`` is not words: the first character that does not continue a word."""
    kept = [i for i, ch in enumerate(code) if ch not in " \t"]
    squeezed = "".join(code[i] for i in kept)
    pos = 0
    while (match := _WORD.match(squeezed, pos)) is not None:
        pos = match.end()
    letter = squeezed[pos].isascii() and squeezed[pos].isalpha()
    at = pos
    if letter:                                         # the word's value starts with what? ([ # after a sign too)
        at = pos + 1 + len(squeezed[pos + 1:]) - len(squeezed[pos + 1:].lstrip("+-"))
        at = at if at < len(squeezed) and squeezed[at] in "[#" else pos
    found = code[kept[pos]:].strip()
    char = squeezed[at]
    column = kept[at] + 1
    if char == "[":
        why = "'[' starts an expression ([1+2], LinuxCNC's arithmetic), which is not read here: use plain numbers"
    elif char == "#":
        why = "'#' is a parameter (#1, #<name>), which is not read here: use plain numbers"
    elif letter:
        why = (f"word '{squeezed[pos].upper()}' has no plain decimal number: found {quote(found)} "
               "(a number is -12.5, .5 or 5.; no '+', no exponent)")
    else:
        why = f"cannot read {quote(found)} as words ({_HINT})"
    return LexError(f"column {column}: {why}", column=column, found=found)


def code_name(letter: str, value: float) -> str:
    """A code as people write it: ``G1``, ``M30``, ``G43.4``.

    >>> code_name("G", 43.4), code_name("M", 3.0)
    ('G43.4', 'M3')
    """
    return f"{letter}{int(value)}" if value == int(value) else f"{letter}{value:g}"


def quote(text: str, limit: int = 40) -> str:
    """``text`` stripped and quoted for a message, cut to ``limit`` characters with ``...``."""
    text = text.strip()
    return f"'{text[:limit]}...'" if len(text) > limit else f"'{text}'"


# ----------------------------------------------------------------------------- the fast path


@lru_cache(maxsize=32)
def column_pattern(letters: str) -> re.Pattern[str]:
    """The regular line shape of :func:`lex_columns` as a regular expression (its specification: the
    tests check that a line is read in bulk exactly when it matches, words of at most 15 digits),
    one optional group per letter, in order."""
    if len(set(letters)) != len(letters) or not letters.isascii() or not letters.isupper():
        raise ValueError(f"letters must be distinct upper-case ASCII letters, not {letters!r}")
    words = " *".join(f"(?:{letter}({NUMBER}))?" for letter in letters)
    return re.compile(f" *{words} *")


def lex_columns(lines: Sequence[str], letters: str) -> tuple[FloatArray, BoolArray]:
    """Read the lines of the regular shape (module docstring) of a chunk in bulk.

    Parameters
    ----------
    lines : sequence of str — without line endings
    letters : str — the letters of a column each, in the order they must appear (``"NGXYZF"``)

    Returns
    -------
    values : (N, L) float — the number of each letter's word, NaN where the line has none (and on
        lines not read)
    read : (N,) bool — the line has the regular shape (a blank line has: all NaN); False: read it
        with :func:`lex_line` (which reads it, or raises what is wrong)

    >>> values, read = lex_columns(["G1 X1.5 F2.", "G1 X1 X2", "(note)"], "GXF")
    >>> values[0].tolist(), read.tolist()
    ([1.0, 1.5, 2.0], [True, False, False])

    How (a few passes over the chunk's bytes, in C): every byte must be allowed after the one before
    it (a table of byte pairs: a letter of ``letters`` after a number, a space or a line start; a digit
    after a letter, ``-``, ``.`` or a digit; ``.`` after a letter, ``-`` or a digit; ``-`` after a letter;
    a space or line end after a number, a space or a line start; any other byte (lower case, tab,
    ``(``, non-ASCII, ...) nowhere), so a line's number bytes follow its letters; then each ``.`` has a
    digit beside it and its word no other ``.``, a word has at most 15 digits, and letters are in order:
    exactly :data:`NUMBER` words in the order of ``letters``. The values of the lines read are made
    from their digits eight bytes at a time (:func:`_numbers`: ``float`` of the same text, to the bit).
    """
    column_pattern(letters)                              # checks the letters
    if not lines:
        return np.full((0, len(letters)), np.nan), np.zeros(0, dtype=bool)
    text = ("\n" + "\n".join(lines) + "\n").encode("ascii", errors="replace")    # byte 0: the line start
    values, read, _ = _lex_text(text, letters)
    return values, read


def lex_column_block(block: bytes, letters: str) -> tuple[FloatArray, BoolArray, IntArray]:
    """:func:`lex_columns` of the lines of a piece of a file, as bytes: the same values and lines read,
    without decoding the text and splitting it into lines first.

    Parameters
    ----------
    block : bytes — whole lines, each ending in LF (the last one may end at the end of the block); a
        CR or a non-ASCII byte is not of the regular shape (its line is not read)
    letters : str — as :func:`lex_columns`

    Returns
    -------
    values, read : as :func:`lex_columns`, one row per line (``block.split(b"\\n")`` without the empty
        piece after a final LF)
    bounds : (N + 1,) int — line k is ``block[bounds[k]:bounds[k + 1] - 1]`` (without its LF)

    >>> values, read, bounds = lex_column_block(b"G1 X1.5\\n(note)\\nX2", "GX")
    >>> values.tolist(), read.tolist(), bounds.tolist()
    ([[1.0, 1.5], [nan, nan], [nan, 2.0]], [True, False, True], [0, 8, 15, 18])
    """
    column_pattern(letters)                              # checks the letters
    if not block:
        return np.full((0, len(letters)), np.nan), np.zeros(0, dtype=bool), np.zeros(1, dtype=np.int64)
    return _lex_text(b"\n" + block + (b"" if block.endswith(b"\n") else b"\n"), letters)


def _lex_text(text: bytes, letters: str) -> tuple[FloatArray, BoolArray, IntArray]:
    """lex_columns of ``text``: LF, then each line and its LF (every byte not ASCII already one of the
    bytes that no line of the regular shape has); returns values, read and the LF positions (N + 1,)."""
    byte_class, rank_of, bad_pair, delimiter, dot = _tables(letters)
    size = len(text)
    data = np.frombuffer(text, dtype=np.uint8)
    delimiters = np.flatnonzero(np.frombuffer(text.translate(delimiter), dtype=np.bool_))    # letters, spaces, ends
    kind = byte_class[data[delimiters]]
    ends = delimiters[kind == _NEWLINE]                  # ends[k + 1] ends line k
    n, width = len(ends) - 1, len(letters)
    values = np.full((n, width), np.nan)
    at = np.flatnonzero(kind == _LETTER)
    start = delimiters[at]                               # a word: its letter up to the next delimiter
    stop = delimiters[np.minimum(at + 1, len(delimiters) - 1)]
    # the line of each word: the line ends before its letter (a running count over the delimiters)
    word_line = (np.cumsum(kind == _NEWLINE) - 1)[at]
    bad = np.zeros(n, dtype=bool)
    # every byte after byte 0 allowed after the one before it (a line end belongs to the line it ends)
    even = np.flatnonzero(bad_pair[np.frombuffer(text, dtype="<u2", count=size // 2)])
    odd = np.flatnonzero(bad_pair[np.frombuffer(text, dtype="<u2", count=(size - 1) // 2, offset=1)])
    if len(even) or len(odd):
        bad[np.searchsorted(ends, np.concatenate([2 * even + 1, 2 * odd + 2])) - 1] = True
    # a dot has a digit beside it, and its word no other dot (a dot outside every word is on a line
    # with a byte not allowed where it is: not read already)
    dots = np.flatnonzero(np.frombuffer(text.translate(dot), dtype=np.bool_))
    dot_word = np.searchsorted(start, dots) - 1
    own = dot_word >= 0
    own[own] = dots[own] < stop[dot_word[own]]
    dots, dot_word = dots[own], dot_word[own]
    lonely = (byte_class[data[dots - 1]] != _DIGIT) & (byte_class[data[dots + 1]] != _DIGIT)
    bad[word_line[dot_word[lonely]]] = True
    bad[word_line[dot_word[1:][dot_word[1:] == dot_word[:-1]]]] = True
    dotted = np.zeros(len(start), dtype=np.int64)
    dotted[dot_word] = 1
    digits = stop - start - 1 - (data[start + 1] == _MINUS_BYTE) - dotted
    rank = rank_of[data[start]]
    ordered = np.ones(len(start), dtype=bool)
    ordered[1:] = (word_line[1:] != word_line[:-1]) | (rank[1:] > rank[:-1])
    bad[word_line[(digits > 15) | ~ordered]] = True
    read = ~bad
    # the values of the words of the lines read: each a plain decimal number of at most 15 digits
    decimals = np.zeros(len(start), dtype=np.int64)     # digits after the point (0 without one)
    decimals[dot_word] = stop[dot_word] - dots - 1
    pointed = np.zeros(len(start), dtype=bool)
    pointed[dot_word] = True
    if bad.any():
        keep = read[word_line]
        start, stop, decimals, pointed = start[keep], stop[keep], decimals[keep], pointed[keep]
        word_line, rank = word_line[keep], rank[keep]
    values[word_line, rank - 1] = _numbers(text, start + 1, stop, decimals, pointed)
    return values, read, ends


def _numbers(text: bytes, first: IntArray, stop: IntArray, decimals: IntArray, pointed: BoolArray) -> FloatArray:
    """The numbers ``text[first[k]:stop[k]]``, each a plain decimal (:data:`NUMBER`) of at most 15
    digits, ``decimals[k]`` of them after its point (``pointed[k]``: it has one): ``float`` of each text.

    How (for all numbers at once, in C): each number's last 16 bytes (8 when none is longer) are
    loaded right-aligned as two little-endian uint64 (unaligned views of the text), the bytes
    before the number masked to ``0``, the sign and point read as ``0`` too; then 8 ASCII digits
    become their integer in three multiply-shift-mask steps (SWAR). With the point read as a
    ``0`` digit, that integer is ``whole·10^(d+1) + fraction``, so the digits without the point are
    ``(a − fraction) / 10 + fraction``, fraction = ``a mod 10^d``. Last, that integer (< 10^15 < 2^53:
    exact) divided by 10^d (exact for d ≤ 22): one correctly rounded division, so the value is
    ``float(text)`` to the bit, as a correctly rounded reader gives it (a minus sign negates it,
    ``-0.0`` included).
    """
    if not len(first):
        return np.zeros(0)
    length = stop - first
    width = 8 if length.max() <= 8 else 16
    digits = np.frombuffer(_ZEROS[:width] + text.translate(_SIGN_AND_POINT_AS_ZERO), dtype=np.uint8)
    words = np.ndarray((len(digits) - 7,), dtype="<u8", buffer=digits, strides=(1,))   # words[i]: bytes i..i+7
    integer = np.zeros(len(first), dtype=np.uint64)
    for part in range(width // 8):                      # the last 8 bytes, then the 8 before them
        loaded = words[stop + width - 8 * (part + 1)]
        keep = _KEEP_BYTES[np.clip(8 * (part + 1) - length, 0, 8)]     # the number's bytes only
        loaded &= keep
        loaded |= _ASCII_ZEROS & ~keep
        integer += _eight_digits(loaded) * _POWERS_OF_TEN_U8[part]
    a = integer.astype(np.int64)
    if pointed.any():
        fraction = a % _POWERS_OF_TEN[decimals]
        a = np.where(pointed, (a - fraction) // 10 + fraction, a)
    value = a / _POWERS_OF_TEN_F8[decimals]
    np.negative(value, out=value, where=np.frombuffer(text, dtype=np.uint8)[first] == _MINUS_BYTE)
    return value


def _eight_digits(words: npt.NDArray[np.uint64]) -> npt.NDArray[np.uint64]:
    """The integer each uint64 of 8 ASCII digits spells (its first byte, the lowest, the most significant)."""
    v = words - _ASCII_ZEROS
    v = (v * np.uint64(10) + (v >> np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)      # pairs of digits
    v = (v * np.uint64(100) + (v >> np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)    # fours
    return (v * np.uint64(10000) + (v >> np.uint64(32))) & np.uint64(0x00000000FFFFFFFF)


_ZEROS = b"0" * 16
#: bytes.translate table: ``-`` and ``.`` read as the digit 0 (their values are taken apart).
_SIGN_AND_POINT_AS_ZERO = bytes(ord("0") if b in b"-." else b for b in range(256))
_ASCII_ZEROS = np.uint64(0x3030303030303030)
#: _KEEP_BYTES[m]: the mask of the bytes of a uint64 from byte m on (m = 8: none).
_KEEP_BYTES = np.array([(2**64 - 1) << (8 * m) & (2**64 - 1) for m in range(9)], dtype=np.uint64)
_POWERS_OF_TEN = 10 ** np.arange(18, dtype=np.int64)
_POWERS_OF_TEN_U8 = np.array([1, 10**8], dtype=np.uint64)
_POWERS_OF_TEN_F8 = 10.0 ** np.arange(23)


#: Byte classes of lex_columns.
_LETTER, _DIGIT, _DOT, _MINUS, _SPACE, _NEWLINE, _OTHER = range(7)
_MINUS_BYTE = ord("-")
#: The classes each class may come right after (a line start is a line end).
_AFTER = {_LETTER: (_DIGIT, _DOT, _SPACE, _NEWLINE), _DIGIT: (_LETTER, _MINUS, _DOT, _DIGIT),
            _DOT: (_LETTER, _MINUS, _DIGIT), _MINUS: (_LETTER,), _SPACE: (_DIGIT, _DOT, _SPACE, _NEWLINE),
            _NEWLINE: (_DIGIT, _DOT, _SPACE, _NEWLINE), _OTHER: ()}


@lru_cache(maxsize=32)
def _tables(letters: str) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.int8], BoolArray, bytes, bytes]:
    """lex_columns' tables: byte class, letter rank (column + 1), bad byte pairs (indexed by the pair
    read as little-endian uint16: first byte low), and bytes.translate tables for delimiters and dots."""
    byte_class = np.full(256, _OTHER, dtype=np.int8)
    byte_class[ord("0"):ord("9") + 1] = _DIGIT
    byte_class[ord(".")], byte_class[ord("-")], byte_class[ord(" ")], byte_class[ord("\n")] = (
        _DOT, _MINUS, _SPACE, _NEWLINE)
    rank = np.zeros(256, dtype=np.int8)
    for column, letter in enumerate(letters):
        byte_class[ord(letter)] = _LETTER
        rank[ord(letter)] = column + 1
    allowed = np.zeros((7, 7), dtype=bool)               # allowed[before, this]
    for this, before in _AFTER.items():
        allowed[list(before), this] = True
    pair = np.arange(65536)
    bad_pair = ~allowed[byte_class[pair & 255], byte_class[pair >> 8]]
    classes = byte_class.tolist()
    delimiter = bytes(int(c in (_LETTER, _SPACE, _NEWLINE)) for c in classes)
    dot = bytes(int(b == ord(".")) for b in range(256))
    for table in (byte_class, rank, bad_pair):
        table.flags.writeable = False
    return byte_class, rank, bad_pair, delimiter, dot


def forward_fill(values: FloatArray) -> FloatArray:
    """Each NaN replaced by the last non-NaN value above it in its column (NaN where there is none): the
    modal value of each row of a :func:`lex_columns` column (prepend the state before the chunk as row 0).

    >>> forward_fill(np.array([np.nan, 1.0, np.nan, 2.0])).tolist()
    [nan, 1.0, 1.0, 2.0]
    """
    rows = np.arange(len(values)).reshape((-1,) + (1,) * (values.ndim - 1))
    last = np.where(np.isnan(values), 0, rows)
    np.maximum.accumulate(last, axis=0, out=last)
    return np.take_along_axis(values, last, axis=0)
