"""The G-code reader's bulk passes: the whole file's bytes checked at once (C where it was built, else numpy),
and runs of plain moves and quiet lines read from the lexer's arrays, every other line block by block."""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING, overload

import numpy as np

from prs3_post.core.errors import InputError, LexError
from prs3_post.core.lexer import (
    LINE_COMMENT,
    LINE_OTHER,
    LINE_READ,
    decode,
    forward_fill,
    lex_block_lines,
    lex_columns,
    split_comments,
)
from prs3_post.core.toolpath import Event, EventKind
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.readers.common import MAX_FEED_MM_MIN, MIN_FEED_MM_MIN
from prs3_post.readers.gcode.blocks import Blocks
from prs3_post.readers.gcode.words import BULK_LETTERS, FEED, ONE_COMMENT, QUIET, RAPID, ROTARY, ROTARY_HINT

if TYPE_CHECKING:
    from prs3_post.core import native


#: Bytes of :data:`ROTARY_HINT`: what may follow a letter in a rotary word.
_ROTARY_NEXT = np.zeros(256, dtype=bool)
_ROTARY_NEXT[list(b" \t-.0123456789")] = True
_ROTARY_HINT_BYTES = re.compile(ROTARY_HINT.pattern.encode("ascii"))


def rotary_hint(text: str) -> bool:
    """``ROTARY_HINT.search(text) is not None``, in bulk (:func:`_rotary_at`)."""
    return _rotary_at(text.encode("utf-8")) >= 0


def _rotary_at(data: bytes) -> int:
    """Where ``ROTARY_HINT`` first matches in ``data`` (bytes of UTF-8 text), or -1: only the letters
    followed by a byte that can continue a rotary word (a letter in a comment's word, ``pass``, is
    followed by another letter) are tried with the pattern."""
    data += b"\n"
    codes = np.frombuffer(data, dtype=np.uint8)
    lower = codes | np.uint8(0x20)                      # A B C a b c: a b c (and no other byte)
    lower -= np.uint8(ord("a"))
    letters = np.flatnonzero(lower < 3)
    maybe = letters[_ROTARY_NEXT[codes[letters + 1]]].tolist()
    return next((at for at in maybe if _ROTARY_HINT_BYTES.match(data, at) is not None), -1)


def scan_bytes(data: bytes) -> tuple[int, bool, int, int]:
    """(the offset of the first control byte :func:`~prs3_post.core.lexer.decode` refuses or -1, a
    byte not ASCII, the LFs, :func:`_rotary_at`): csrc/lex.c's one pass where it was built, else numpy."""
    from prs3_post.core import native  # ctypes: loaded only where a file is read

    scanned = native.scan_text(data)
    return _scan_bytes_numpy(data) if scanned is None else scanned


def _scan_bytes_numpy(data: bytes) -> tuple[int, bool, int, int]:
    """:func:`scan_bytes` with numpy (the reference of csrc/lex.c's prs3_scan_text)."""
    codes = np.frombuffer(data, dtype=np.uint8)
    control = np.flatnonzero(((codes < 32) & (codes != 9) & (codes != 10) & (codes != 13)) | (codes == 127))
    return (int(control[0]) if len(control) else -1, bool((codes >= 128).any()), data.count(b"\n"),
            _rotary_at(data))


def refuse_rotary(line: str, number: int, path: str) -> None:
    """Raise the 5-axis refusal if ``line``'s code (without comments) has a rotary word."""
    try:
        code, _ = split_comments(line)
    except LexError:
        return                                           # the careful reader names what is wrong there
    match = ROTARY.search(code)
    if match is None:
        return
    word = (match[1] + match[2]).upper().replace(" ", "").replace("\t", "")
    raise InputError(f"5-axis program: rotary word '{word}' (A, B and C words turn rotary axes); the 3+2 reader "
                     "reads programs whose tool axis is set by G68.2/G53.1 or by the work plane, so it refuses this "
                     "program rather than misread it; a 5-axis program under TCP converts when {source} names the "
                     "machine it was written for (prs3-post sources lists them)", path=path, line=number,
                     names_keys=("source",))


def _text_at(data: bytes, path: str, offset: int) -> str:
    """The text of the bytes of a file from ``offset`` (a line start) on, checked as
    :func:`~prs3_post.core.lexer.decode` checks it (its error names ``path``)."""
    try:
        return decode(data, offset=offset)
    except LexError as exc:
        raise InputError(str(exc), path=path) from exc


class _BlockLines(Sequence[str]):
    """The lines of a block of a file's bytes (:func:`~prs3_post.core.lexer.lex_block_lines`'
    ``bounds``: line k is ``data[bounds[k]:bounds[k + 1] - 1]``), each decoded when first asked for
    (the lines read in bulk never are, nor the usual comment lines: ``kinds`` and ``spans``, as
    lex_block_lines gives them); a slice shares the block and the texts decoded."""

    def __init__(self, data: bytes, bounds: IntArray, offset: int, path: str, kinds: np.ndarray, spans: IntArray, *,
                 start: int = 0, stop: int | None = None, texts: dict[int, str] | None = None):
        self.data, self.bounds, self.offset, self.path = data, bounds, offset, path
        self.kinds, self.spans = kinds, spans
        self.start, self.stop = start, len(bounds) - 1 if stop is None else stop
        self.texts: dict[int, str] = {} if texts is None else texts        # line in the block → text

    def __len__(self) -> int:
        return self.stop - self.start

    @overload
    def __getitem__(self, index: int) -> str: ...

    @overload
    def __getitem__(self, index: slice) -> _BlockLines: ...

    def __getitem__(self, index: int | slice) -> str | _BlockLines:
        size = self.stop - self.start
        if isinstance(index, slice):
            first, last, step = index.indices(size)
            if step != 1:
                raise ValueError("_BlockLines: only contiguous slices")
            return _BlockLines(self.data, self.bounds, self.offset, self.path, self.kinds, self.spans,
                               start=self.start + first, stop=self.start + max(first, last), texts=self.texts)
        if not -size <= index < size:
            raise IndexError(index)
        line = self.start + index % size
        text = self.texts.get(line)
        if text is None:
            begin, end = self.bounds[line:line + 2].tolist()      # (the bounds stay an array: few lines are asked for)
            raw = self.data[begin:end - 1]
            text = raw.decode("latin-1")                 # one byte, one character: for the test below
            if not (text.isascii() and text.isprintable()):      # else checked as decode does
                text = _text_at(raw, self.path, self.offset + begin)
            self.texts[line] = text
        return text

    def quiet_comments(self, indexes: IntArray) -> tuple[BoolArray, list[str]] | None:
        """Lines ``indexes`` (of this slice; each blank or only comments) as events, where every one is
        blank (read: no words) or the usual comment line (lex_block_lines): which are comments, and
        their texts (stripped); None where any is another line (two comments, a tab in one, ...)."""
        at = indexes + self.start
        kinds = self.kinds[at]
        comment = kinds == LINE_COMMENT
        if not (comment | (kinds == LINE_READ)).all():
            return None
        spans = self.spans[at[comment]]
        data = self.data
        return comment, [data[a:b].decode("ascii") for a, b in spans.tolist()]


class LineReader(Blocks):
    """A program's blocks as the lines go by: runs of plain moves and quiet lines in bulk, every other line
    block by block."""

    # ---- lines, chunks, the end
    def lines(self, first: int, lines: list[str]) -> None:
        """Read ``lines`` (without line ends), the first of which is line ``first`` of the file.

        Runs of regular motion lines (``N.. G0/G1 X.. Y.. Z.. F..``, :func:`~prs3_post.core.lexer.lex_columns`),
        with the blank and comment-only lines between them, go to :meth:`bulk`; the others, and a run
        the bulk step refuses, to :meth:`line` one at a time.
        """
        if not lines:
            return
        values, fast = lex_columns(lines, BULK_LETTERS)
        self.runs(first, values, fast, lines)

    def read_block(self, first: int, data: bytes, offset: int) -> int:
        """Lines ``first``... as the file's bytes from ``offset`` on (whole lines, each with its LF; the
        last may end at the end of the file), read as :meth:`lines` reads them decoded; returns their
        number. The lines of the regular motion shape are read without being decoded; the others are
        decoded when read (a block with a CR is decoded whole: its lines without the CR before the LF).
        The file's text was checked before (:func:`~prs3_post.core.lexer.decode`)."""
        if b"\r" in data:
            text = _text_at(data, self.path, offset)
            lines = text.split("\n")
            if lines[-1] == "":
                lines.pop()                              # the block's final line end
            lines = [line.removesuffix("\r") for line in lines]
            self.lines(first, lines)
            return len(lines)
        values, kinds, bounds, spans = lex_block_lines(data, BULK_LETTERS, rows=self.block_lines)
        self.block_lines = len(kinds)                    # the next block's, but for the last one
        self.runs(first, values, kinds == LINE_READ, _BlockLines(data, bounds, offset, self.path, kinds, spans))
        return len(kinds)

    def runs(self, first: int, values: FloatArray, fast: BoolArray, lines: Sequence[str]) -> None:
        """Lines ``first``... as lexed (``values``, ``fast``: :func:`~prs3_post.core.lexer.lex_columns`)
        with their texts ``lines``: runs to :meth:`bulk`, the rest to :meth:`line` (see :meth:`lines`)."""
        if isinstance(lines, _BlockLines):               # the usual comment lines known, and the blank ones
            fast, quiet = _line_roles(values, lines.kinds)
            maybe = lines.kinds == LINE_OTHER
        else:
            g = values[:, 1]
            fast &= np.isnan(g) | (g == 0.0) | (g == 1.0)
            fast &= ~np.isnan(np.fmax(np.fmax(values[:, 2], values[:, 3]), values[:, 4]))   # a move: an axis word
            quiet = np.zeros(len(lines), dtype=bool)     # blank or only comments: nothing but events
            maybe = ~fast
        quiet[maybe] = [QUIET.fullmatch(lines[i]) is not None for i in np.flatnonzero(maybe).tolist()]
        span = fast | quiet
        edges = np.flatnonzero(np.diff(span.astype(np.int8))) + 1
        for a, b in itertools.pairwise([0, *edges.tolist(), len(lines)]):
            if span[a] and not fast[a:b].any() and self.quiet_lines(lines[a:b]):
                continue
            if not (span[a] and fast[a:b].any() and self.bulk(first + a, values[a:b], fast[a:b], lines[a:b])):
                for i in range(a, b):
                    self.line(first + i, lines[i])

    def quiet_lines(self, lines: Sequence[str]) -> bool:
        """Lines that are all blank or usual comment lines (read without decoding: a block's), in bulk:
        their events and counts, as :meth:`line` makes them one by one. False (state untouched) where
        any is another kind of line (two comments, a tab in one...), or after the closing '%' (the
        5-axis reader counts what follows it apart): :meth:`line` reads them."""
        if not isinstance(lines, _BlockLines) or self.percent >= 2:
            return False
        known = lines.quiet_comments(np.arange(len(lines)))
        if known is None:
            return False
        _, comments = known
        row = self.rows - self.chunk_start
        self.comments += len(comments)
        self.comment_lines += len(comments)
        self.blank_lines += len(lines) - len(comments)
        self.events += [Event(row, EventKind.COMMENT, 0.0, text) for text in comments]
        return True

    def bulk(self, first: int, values: FloatArray, moves: BoolArray, lines: Sequence[str]) -> bool:
        """Lines ``first``... in bulk: where ``moves``, of the regular motion shape (``values`` (k, 6): N G X Y Z
        F, NaN where absent), elsewhere blank or comments only. True if done; False (state untouched)
        where any line would need the careful reader."""
        if (self.end_line is not None or self.percent >= 2 or self.cycle is not None or not self.absolute
                or self.inverse_time or not self.tilt_ready or self.pending_p3 is not None or self.start_pending):
            return False
        state = np.array([math.nan if self.motion is None else self.motion,
                          math.nan if self.feed_word is None else self.feed_word, *self.position])
        filled = _fill_moves(values, moves, state, self.scale, first)
        if filled is None:
            return False
        tip, kind, feed, source, state, words = filled
        others = np.flatnonzero(~moves)
        k = len(tip)
        known = lines.quiet_comments(others) if len(others) and isinstance(lines, _BlockLines) else None
        if known is not None:                            # the usual comment lines and blank ones, known
            before = self.rows - self.chunk_start + np.cumsum(moves)[others]
            comment, comments = known
            self.comments += len(comments)
            self.comment_lines += len(comments)
            self.blank_lines += len(others) - len(comments)
            event = EventKind.COMMENT
            self.events += [Event(row, event, 0.0, text) for row, text in zip(before[comment].tolist(), comments,
                                                                                strict=True)]
        elif len(others):                                # the comments, each before the next move's row
            before = self.rows - self.chunk_start + np.cumsum(moves)[others]
            one_comment = ONE_COMMENT.fullmatch
            for index, row in zip(others.tolist(), before.tolist(), strict=True):
                line = lines[index]
                match = one_comment(line)                # the usual comment line: split_comments' answer
                texts = (match[1],) if match is not None else split_comments(line)[1]
                if texts:
                    self.comment_lines += 1
                else:
                    self.blank_lines += 1
                for text in texts:
                    self.comments += 1
                    self.events.append(Event(before=row, kind=EventKind.COMMENT, text=text.strip()))
        self.add_rows(tip, kind, feed, source)
        motion, feed_word = state[:2].tolist()
        self.motion = motion
        self.feed_word = None if math.isnan(feed_word) else feed_word
        self.moves += k
        self.records += k
        self.code_seen = True
        rapids, feeds = words.tolist()
        if rapids or feeds:
            self.by_word["G0"] += rapids
            self.by_word["G1"] += feeds
        return True


_FILL_CODES = np.array([RAPID, FEED], dtype=np.int64)


def _line_roles(values: FloatArray, kinds: np.ndarray) -> tuple[BoolArray, BoolArray]:
    """Which lines of a lexed block (``values`` (n, 6): N G X Y Z F; ``kinds``: lex_block_lines') are
    regular G0/G1 moves (read, G0, G1 or no G, an axis word) and which are quiet (the usual comment
    line, or read without a word: blank): csrc/lex.c's one pass where it was built, else
    :func:`_line_roles_numpy`."""
    from prs3_post.core import native  # ctypes: loaded only where lines are read in bulk

    roles = native.line_roles(values, kinds)
    return _line_roles_numpy(values, kinds) if roles is None else roles


def _line_roles_numpy(values: FloatArray, kinds: np.ndarray) -> tuple[BoolArray, BoolArray]:
    """:func:`_line_roles` with numpy (the reference of prs3_line_roles)."""
    read = kinds == LINE_READ
    g = values[:, 1]
    move = read & (np.isnan(g) | (g == 0.0) | (g == 1.0))
    move &= ~np.isnan(np.fmax(np.fmax(values[:, 2], values[:, 3]), values[:, 4]))   # a move: an axis word
    quiet = (kinds == LINE_COMMENT) | (read & np.isnan(values).all(axis=1))
    return move, quiet


def _fill_moves(values: FloatArray, moves: BoolArray, state: FloatArray, scale: float,
                first: int) -> native.FilledMoves | None:
    """The rows of a run of bulk lines (:meth:`LineReader.bulk`), its state after them and its G0 and G1
    words (:data:`~prs3_post.core.native.FilledMoves`); None where a line needs the careful reader. In C
    (csrc/lex.c's prs3_fill_moves) where it was built, else :func:`_fill_moves_numpy`: the same."""
    from prs3_post.core import native  # ctypes: loaded only where lines are read in bulk

    limits = np.array([scale, MIN_FEED_MM_MIN, MAX_FEED_MM_MIN])
    filled = native.fill_moves(values, moves, state, limits, _FILL_CODES, first)
    if filled is True:
        return _fill_moves_numpy(values, moves, state, scale, first)
    return filled or None


def _fill_moves_numpy(values: FloatArray, moves: BoolArray, state: FloatArray, scale: float,
                      first: int) -> native.FilledMoves | None:
    """:func:`_fill_moves` with numpy (the reference of prs3_fill_moves): each move's modal motion, F and
    position filled down the run from ``state`` (motion, F word, X Y Z mm; NaN where none)."""
    values = values[moves]
    g, axes, feed = values[:, 1], values[:, 2:5] * scale, values[:, 5]
    motion = forward_fill(np.concatenate([state[:1], g]))[1:]
    given_feed = forward_fill(np.concatenate([state[1:2], feed]))[1:]
    position = forward_fill(np.vstack([state[2:], axes]))[1:]
    feeding = motion == 1.0
    has_f = ~np.isnan(feed)
    if (((motion != 0.0) & (motion != 1.0)).any() or not (feed[has_f] > 0).all()
            or not (feed[has_f] * scale <= MAX_FEED_MM_MIN).all()   # the careful reader words it
            or not (feed[has_f] * scale >= MIN_FEED_MM_MIN).all()
            or np.isnan(given_feed[feeding]).any() or not np.isfinite(position).all()):
        return None
    after = np.concatenate([motion[-1:], given_feed[-1:], position[-1]]) if len(values) else np.array(state)
    codes = g[~np.isnan(g)]
    rapids = int((codes == 0.0).sum())
    return (position, np.where(feeding, FEED, RAPID).astype(np.int64), np.where(feeding, given_feed * scale, 0.0),
            first + np.flatnonzero(moves), after, np.array([rapids, len(codes) - rapids], dtype=np.int64))
