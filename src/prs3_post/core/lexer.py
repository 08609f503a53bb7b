"""The G-code lexer: bytes → text → lines → comments and words, shared by every reader of G-code.

Strict on purpose: whatever it does not read exactly is a :class:`~prs3_post.core.errors.LexError` (with the
column and the text found), never skipped. It knows no file and no line number: a reader wraps the
error in an :class:`~prs3_post.core.errors.InputError` naming both. It knows no codes either: which
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
read a line they agree exactly (values are ``float`` of the same text: correctly rounded). Where
``pip install`` compiled csrc/lex.c (:mod:`prs3_post.core.native`), one pass over the bytes in C reads
the chunk, with the same rules and values; else numpy does (``PRS3_POST_NATIVE=0`` chooses that).
:func:`lex_block_lines` also names, among the lines not read, the usual comment line (one comment in
parentheses, printable ASCII) and where its text is, so that a reader makes its comment without
decoding or splitting the line.

pygcode is the reference of a differential test (tests/test_lexer.py), where it is documented
wrong listed there (it skips characters it does not know, reads non-ASCII letters, ...).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from prs3_post.core.errors import LexError
from prs3_post.core.types import BoolArray, FloatArray, IntArray

__all__ = [
    "BYTE_ORDER_MARK", "EMPTY", "LINE_COMMENT", "LINE_OTHER", "LINE_READ", "LINUXCNC_COMMENTS", "NUMBER", "Word",
    "bad_pairs", "code_name", "column_pattern", "decimal_numbers", "decode",
    "forward_fill", "lex_block_lines", "lex_column_block", "lex_columns", "lex_line",
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

    How (csrc/lex.c where it was built: one pass, line by line, byte by byte, with the same rules and
    the values made as :func:`decimal_numbers` makes them; else numpy, a few passes over the chunk's
    bytes, in C): each byte is mapped to a code (one
    ``bytes.translate``: digit, ``-``, ``.``, space, line end, the column of a letter of ``letters``,
    or other), and every byte must be allowed after the one before it (a table of code pairs: a letter
    of ``letters`` after a number, a space or a line start; a digit after a letter, ``-``, ``.`` or a
    digit; ``.`` after a letter, ``-`` or a digit; ``-`` after a letter; a space or line end after a
    number, a space or a line start; any other byte (lower case, tab, ``(``, non-ASCII, ...) nowhere),
    so a line's number bytes follow its letters. The delimiters (``.``, spaces, line ends, letters) are
    then found in one pass, in order: a word is a letter up to the next delimiter other than a point,
    its point (if any) the delimiter right after its letter; each ``.`` has a digit beside it and its
    word no other ``.``, a word has at most 15 digits, and letters are in order: exactly
    :data:`NUMBER` words in the order of ``letters``. The values are made from their digits eight
    bytes at a time (:func:`decimal_numbers`: ``float`` of the same text, to the bit).
    """
    column_pattern(letters)                              # checks the letters
    if not lines:
        return np.full((0, len(letters)), np.nan), np.zeros(0, dtype=bool)
    text = ("\n".join(lines) + "\n").encode("ascii", errors="replace")
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
    values, kinds, bounds, _ = lex_block_lines(block, letters)
    return values, kinds == LINE_READ, bounds


def lex_block_lines(block: bytes, letters: str, *, rows: int | None = None
                    ) -> tuple[FloatArray, npt.NDArray[np.uint8], IntArray, IntArray]:
    """:func:`lex_column_block`, and what each line not read is: the usual comment line (one comment
    in parentheses, only spaces and tabs around it, its text printable ASCII: no parenthesis, no tab,
    nothing a careful reader would refuse) and where its text is, so that a reader makes its comment
    without decoding the line or matching it.

    Parameters
    ----------
    block, letters : as :func:`lex_column_block`
    rows : int, optional — a guess of the number of lines (the last block's), which spares counting them

    Returns
    -------
    values, bounds : as :func:`lex_column_block`
    kinds : (N,) uint8 — :data:`LINE_READ` (read: the regular shape), :data:`LINE_COMMENT`, :data:`LINE_OTHER`
    spans : (N, 2) int — on the LINE_COMMENT lines, ``block[start:stop]`` is the comment's text without
        the spaces at either end (``split_comments``' text, ``.strip()``-ed); 0 on the other lines

    >>> values, kinds, bounds, spans = lex_block_lines(b"G1 X1.5\\n ( note ) \\n(a)(b)", "GX")
    >>> kinds.tolist(), spans.tolist()
    ([1, 2, 0], [[0, 0], [11, 15], [0, 0]])
    """
    column_pattern(letters)                              # checks the letters
    if not block:
        return (np.full((0, len(letters)), np.nan), np.zeros(0, dtype=np.uint8), np.zeros(1, dtype=np.int64),
                np.zeros((0, 2), dtype=np.int64))
    return _lex_lines(block if block.endswith(b"\n") else block + b"\n", letters, rows)


def _lex_text(text: bytes, letters: str) -> tuple[FloatArray, BoolArray, IntArray]:
    """lex_columns of ``text``: lines each with its LF (every byte not ASCII already one of the bytes
    that no line of the regular shape has); returns values, read and where each line starts (N + 1,).
    In C (csrc/lex.c, several times faster) where it was built, else :func:`_lex_text_numpy`: the same."""
    values, kinds, bounds, _ = _lex_lines(text, letters)
    return values, kinds == LINE_READ, bounds


def _lex_lines(text: bytes, letters: str, rows: int | None = None
               ) -> tuple[FloatArray, npt.NDArray[np.uint8], IntArray, IntArray]:
    """The values, line kinds, line starts and comment spans (positions in ``text``) of
    :func:`lex_block_lines` of ``text`` (lines each ending in LF): csrc/lex.c where it was built, else
    numpy (:func:`_lex_text_numpy`, :func:`_line_kinds_numpy`, on the text after a LF)."""
    from prs3_post.core import native  # ctypes: loaded only where lines are read in bulk

    lexed = native.lex_text(text, _tables(letters)[0], len(letters), rows)
    if lexed is not None:
        return lexed
    after_lf = b"\n" + text                              # byte 0: the first line's start
    values, read, ends = _lex_text_numpy(after_lf, letters)
    kinds, spans = _line_kinds_numpy(after_lf, read, ends)
    spans -= kinds[:, None] == LINE_COMMENT              # positions in the text after the LF: in ``text``
    return values, kinds, ends, spans


#: The usual comment line of :func:`lex_block_lines`: its text the group.
_COMMENT_LINE = re.compile(rb"[ \t]*\(([\x20-\x27\x2a-\x7e]*)\)[ \t]*")


def _line_kinds_numpy(text: bytes, read: BoolArray, ends: IntArray) -> tuple[npt.NDArray[np.uint8], IntArray]:
    """The line kinds and comment spans (positions in ``text``) of :func:`_lex_lines` from the lines
    read and the LF positions: each line not read matched with a pattern (the reference of csrc/lex.c's)."""
    kinds = read.astype(np.uint8)                        # LINE_READ or LINE_OTHER
    spans = np.zeros((len(read), 2), dtype=np.int64)
    for k in np.flatnonzero(~read).tolist():
        match = _COMMENT_LINE.fullmatch(text, int(ends[k]) + 1, int(ends[k + 1]))
        if match is not None:
            first, stop = match.span(1)
            inner = match[1]
            first += len(inner) - len(inner.lstrip(b" "))
            stop = max(first, stop - (len(inner) - len(inner.rstrip(b" "))))
            kinds[k], spans[k] = LINE_COMMENT, (first, stop)
    return kinds, spans


def _lex_text_numpy(text: bytes, letters: str) -> tuple[FloatArray, BoolArray, IntArray]:
    """The values, lines read and LF positions (N + 1,) of ``text``: a LF, then lines each with its LF,
    with numpy (the reference of csrc/lex.c, and where that was not built; its LF positions in
    ``text`` are the line starts in the text after the first LF)."""
    code_table, pair_table = _tables(letters)
    size = len(text)
    classes = text.translate(code_table)                 # one byte a byte: its class (_CODE_*)
    code = np.frombuffer(classes + b"\0", dtype=np.uint8)         # + a byte after the last line end
    # the delimiters: dots, spaces, line ends, letters (the codes from _CODE_DOT on), in order
    delimiters = np.flatnonzero(code >= _CODE_DOT)
    kind = code[delimiters]
    line_end = kind == _CODE_NEWLINE
    ends = delimiters[line_end]                          # ends[k + 1] ends line k
    n, width = len(ends) - 1, len(letters)
    bad = np.zeros(n, dtype=bool)
    # every byte after byte 0 allowed after the one before it (a line end belongs to the line it ends;
    # the letters' codes taken as one)
    letter = np.full(size, _CODE_LETTER, dtype=np.uint8)    # (np.minimum with a scalar is several times slower)
    wrong = bad_pairs(np.minimum(code[:size], letter), pair_table, 3)
    if len(wrong):
        bad[np.searchsorted(ends, wrong) - 1] = True
    at = np.flatnonzero(kind >= _CODE_LETTER)           # the words: a letter up to the next delimiter but a dot
    word_line = (np.cumsum(line_end, dtype=np.int32) - 1)[at]
    start = delimiters[at]
    # With every byte allowed after the one before it, a number's bytes follow its letter (digits, a
    # minus, dots): a dot of a word is the delimiter right after its letter, and a second dot the next.
    pointed = kind[at + 1] == _CODE_DOT                   # (the last delimiter is a line end: no letter is)
    after = at + 1 + pointed
    stop = delimiters[after]
    dot = delimiters[at + 1]                             # where pointed: the word's point
    bad[word_line[pointed & (kind[after] == _CODE_DOT)]] = True                        # a second point
    # a point has a digit beside it
    lonely = pointed & (code[dot - 1] != _CODE_DIGIT) & (code[dot + 1] != _CODE_DIGIT)
    bad[word_line[lonely]] = True
    minus = code[start + 1] == _CODE_MINUS
    digits = stop - start - 1 - minus - pointed
    rank = kind[at] - _CODE_LETTER                        # the letter's column
    ordered = np.ones(len(start), dtype=bool)
    ordered[1:] = (word_line[1:] != word_line[:-1]) | (rank[1:] > rank[:-1])
    bad[word_line[(digits > 15) | ~ordered]] = True
    read = ~bad
    # the values of the words, each a plain decimal number of at most 15 digits on the lines read (the
    # words of the other lines are made into something, then their lines set back to NaN)
    first = start + 1 + minus
    if bad.any():
        keep = read[word_line]
        pointed &= keep
        first += (stop - first) * ~keep                # no bytes: 0
    values = np.full((n, width), np.nan)
    values.reshape(-1)[word_line * width + rank] = decimal_numbers(text, first, stop, dot, pointed, minus)
    values[bad] = np.nan
    return values, read, ends


def decimal_numbers(text: bytes, first: IntArray, stop: IntArray, dot: IntArray, pointed: BoolArray,
             minus: BoolArray) -> FloatArray:
    """The numbers ``text[first[k]:stop[k]]``, each plain decimal digits of at most 15 with at most one
    point (at ``dot[k]`` where ``pointed[k]``), negated where ``minus[k]``: ``float`` of each text.

    How (for all numbers at once, in C): each number's last 16 bytes (8 when none is longer) are
    loaded right-aligned as two little-endian uint64 (unaligned views of the text), the bytes
    before the number masked to ``0``, the point read as ``0`` too (by adding 2 to its byte); then 8
    ASCII digits become their integer in three multiply-shift-mask steps (SWAR). With the point read
    as a ``0`` digit, that integer is ``whole·10^(d+1) + fraction`` (d digits after the point), so
    the digits without the point are ``(a − fraction) / 10 + fraction``, fraction = ``a mod 10^d``.
    Last, that integer (< 10^15 < 2^53: exact) divided by ±10^d (exact for d ≤ 22): one correctly
    rounded division, so the value is ``float(text)`` to the bit, as a correctly rounded reader gives
    it (a minus sign negates it, ``-0.0`` included).
    """
    if not len(first):
        return np.zeros(0)
    length = stop - first
    decimals = (stop - dot - 1) * pointed
    width = 8 if length.max() <= 8 else 16
    data = np.frombuffer(_ZEROS[:width] + text, dtype=np.uint8)
    words = np.ndarray((len(data) - 7,), dtype="<u8", buffer=data, strides=(1,))   # words[i]: bytes i..i+7
    integer = np.zeros(len(first), dtype=np.uint64)
    point_at = decimals + 16 * pointed                  # index of the point's fix-up (none: 0 to 15)
    for part in range(width // 8):                      # the last 8 bytes, then the 8 before them
        loaded = words[stop + width - 8 * (part + 1)]
        before = 8 * (part + 1) - length                # bytes of the load before the number
        keep = _KEEP_BYTES[before if width == 8 else np.clip(before, 0, 8)]   # the number's bytes only
        loaded &= keep
        loaded |= _ASCII_ZEROS & ~keep
        loaded += _POINT_TO_ZERO[part][point_at]        # '.' + 2 is '0'
        integer += _eight_digits(loaded) * _POWERS_OF_TEN_U8[part]
    a = integer.astype(np.int64)
    if pointed.any():
        fraction = a % _POWERS_OF_TEN[decimals]
        a = np.where(pointed, (a - fraction) // 10 + fraction, a)
    return a / _SIGNED_POWERS_OF_TEN[decimals + 23 * minus]


def _eight_digits(words: npt.NDArray[np.uint64]) -> npt.NDArray[np.uint64]:
    """The integer each uint64 of 8 ASCII digits spells (its first byte, the lowest, the most significant)."""
    v = words - _ASCII_ZEROS
    v = (v * np.uint64(10) + (v >> np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)      # pairs of digits
    v = (v * np.uint64(100) + (v >> np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)    # fours
    return (v * np.uint64(10000) + (v >> np.uint64(32))) & np.uint64(0x00000000FFFFFFFF)


_ZEROS = b"0" * 16
_ASCII_ZEROS = np.uint64(0x3030303030303030)
#: _KEEP_BYTES[m]: the mask of the bytes of a uint64 from byte m on (m = 8: none).
_KEEP_BYTES = np.array([(2**64 - 1) << (8 * m) & (2**64 - 1) for m in range(9)], dtype=np.uint64)
_POWERS_OF_TEN = 10 ** np.arange(18, dtype=np.int64)
_POWERS_OF_TEN_U8 = np.array([1, 10**8], dtype=np.uint64)
#: 10^d for d = 0 … 22, then −10^d (index d + 23: a negative number's divisor).
_SIGNED_POWERS_OF_TEN = np.concatenate([10.0 ** np.arange(23), -(10.0 ** np.arange(23))])
#: _POINT_TO_ZERO[part][d + 16]: what turns the point of a number with d decimals into ``0`` in the
#: part-th uint64 from its end (2 added to its byte: ``'.' + 2 == '0'``); 0 where the point is not
#: in that part, and for the numbers without a point (index d < 16).
_POINT_TO_ZERO = np.zeros((2, 32), dtype=np.uint64)
for _d in range(16):
    _POINT_TO_ZERO[_d // 8, 16 + _d] = 2 << (8 * (7 - _d % 8))


#: The kinds of line of :func:`lex_block_lines` (csrc/lex.c's LINE_*): not read, read, the usual comment line.
LINE_OTHER, LINE_READ, LINE_COMMENT = 0, 1, 2
#: Byte codes of lex_columns (a bytes.translate table maps each byte to its code); the delimiters of
#: words are the codes from _CODE_DOT on, the letters of the columns from _CODE_LETTER on (+ column).
_CODE_OTHER, _CODE_DIGIT, _CODE_MINUS, _CODE_DOT, _CODE_SPACE, _CODE_NEWLINE, _CODE_LETTER = range(7)
#: Byte classes of the pair check.
_LETTER, _DIGIT, _DOT, _MINUS, _SPACE, _NEWLINE, _OTHER = range(7)
#: The classes each class may come right after (a line start is a line end).
_AFTER = {_LETTER: (_DIGIT, _DOT, _SPACE, _NEWLINE), _DIGIT: (_LETTER, _MINUS, _DOT, _DIGIT),
            _DOT: (_LETTER, _MINUS, _DIGIT), _MINUS: (_LETTER,), _SPACE: (_DIGIT, _DOT, _SPACE, _NEWLINE),
            _NEWLINE: (_DIGIT, _DOT, _SPACE, _NEWLINE), _OTHER: ()}


def bad_pairs(codes: npt.NDArray[np.uint8], table: bytes, shift: int) -> IntArray:
    """The positions k ≥ 1 where the pair of codes ``(codes[k − 1], codes[k])`` is bad: where
    ``table[codes[k − 1] << shift | codes[k]]`` is 1 (a ``bytes.translate`` table; every code below
    ``2**shift``, ``shift`` ≤ 4). In C: two byte operations, one translate, one search.

    >>> bad_pairs(np.array([0, 1, 2, 1], dtype=np.uint8), bytes([0, 0, 0, 0, 0, 0, 1] + [0] * 249), 2).tolist()
    [2]
    """
    pairs = codes[:-1] * (1 << shift)                   # (numpy's shift of uint8 is several times slower)
    pairs |= codes[1:]
    return np.flatnonzero(np.frombuffer(pairs.tobytes().translate(table), dtype=np.bool_)) + 1


@lru_cache(maxsize=32)
def _tables(letters: str) -> tuple[bytes, bytes]:
    """lex_columns' tables: the bytes.translate table of each byte's code, and that of the bad pairs of
    codes for :func:`bad_pairs` (shift 3, the letters' codes clipped to _CODE_LETTER)."""
    code = np.full(256, _CODE_OTHER, dtype=np.uint8)
    code[ord("0"):ord("9") + 1] = _CODE_DIGIT
    code[ord("-")], code[ord(".")], code[ord(" ")], code[ord("\n")] = _CODE_MINUS, _CODE_DOT, _CODE_SPACE, _CODE_NEWLINE
    for column, letter in enumerate(letters):
        code[ord(letter)] = _CODE_LETTER + column
    class_of = np.full(8, _OTHER, dtype=np.int8)        # the class of each code (clipped)
    class_of[[_CODE_DIGIT, _CODE_MINUS, _CODE_DOT, _CODE_SPACE, _CODE_NEWLINE, _CODE_LETTER]] = (
        _DIGIT, _MINUS, _DOT, _SPACE, _NEWLINE, _LETTER)
    allowed = np.zeros((7, 7), dtype=bool)               # allowed[before, this]
    for this, before in _AFTER.items():
        allowed[list(before), this] = True
    pair = np.arange(64)                                 # (before << 3) | this
    pair_bad = ~allowed[class_of[pair >> 3], class_of[pair & 7]]
    return bytes(code.tolist()), bytes(pair_bad.tolist() + [False] * 192)


def forward_fill(values: FloatArray) -> FloatArray:
    """Each NaN replaced by the last non-NaN value above it in its column (NaN where there is none): the
    modal value of each row of a :func:`lex_columns` column (prepend the state before the chunk as row 0).

    >>> forward_fill(np.array([np.nan, 1.0, np.nan, 2.0])).tolist()
    [nan, 1.0, 1.0, 2.0]
    """
    rows = np.arange(len(values)).reshape((-1,) + (1,) * (values.ndim - 1))
    last = np.where(np.isnan(values), 0, rows)
    np.maximum.accumulate(last, axis=0, out=last)
    if values.ndim == 1:
        return values[last]
    if values.ndim == 2:                                 # a flat gather (take_along_axis' general path is slower)
        width = values.shape[1]
        return np.ascontiguousarray(values).reshape(-1)[last * width + np.arange(width)]
    return np.take_along_axis(values, last, axis=0)
