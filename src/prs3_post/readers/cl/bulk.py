"""The CL reader's bulk passes: runs of plain ``GOTO/`` lines read at once (bytes → values in C where it was
built, else numpy), with the ``PPRINT``, ``FEDRAT`` and display records between them read where they stand."""

from __future__ import annotations

import itertools
import math
import re

import numpy as np

from prs3_post.core.lexer import bad_pairs, decimal_numbers
from prs3_post.core.toolpath import Event, EventKind
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.part.stl import MAX_COORDINATE_MM
from prs3_post.readers.cl.records import Records
from prs3_post.readers.cl.syntax import AXIS_LENGTH_TOLERANCE, FEED, RAPID
from prs3_post.readers.common import MAX_RECORD_CHARS

#: A GOTO as CAM systems write nearly all of them: plain decimals, no spaces, no comment. Such lines,
#: one after another, are read in bulk (:meth:`LineReader.goto_run`); every other line record by record.
_DECIMAL = r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)"  # one way to match a number: no backtracking on long digit runs
_PLAIN_GOTO = re.compile(
    rf"GOTO/({_DECIMAL}),({_DECIMAL}),({_DECIMAL})(?:,({_DECIMAL}),({_DECIMAL}),({_DECIMAL}))?\r?\Z")
#: Byte codes of :func:`_plain_gotos` (the delimiters of numbers from _GC_DOT on).
_GC_OTHER, _GC_DIGIT, _GC_SIGN, _GC_PREFIX, _GC_DOT, _GC_COMMA, _GC_SLASH, _GC_CR, _GC_NEWLINE = range(9)
#: The codes each code may come right after, on a plain GOTO line (a line start is a line end).
_GOTO_AFTER = {_GC_PREFIX: (_GC_NEWLINE, _GC_PREFIX), _GC_SLASH: (_GC_PREFIX,), _GC_SIGN: (_GC_SLASH, _GC_COMMA),
               _GC_DIGIT: (_GC_SLASH, _GC_COMMA, _GC_SIGN, _GC_DOT, _GC_DIGIT),
               _GC_DOT: (_GC_SLASH, _GC_COMMA, _GC_SIGN, _GC_DIGIT), _GC_COMMA: (_GC_DIGIT, _GC_DOT),
               _GC_CR: (_GC_DIGIT, _GC_DOT), _GC_NEWLINE: (_GC_DIGIT, _GC_DOT, _GC_CR)}


def _goto_tables() -> tuple[bytes, bytes]:
    code = np.full(256, _GC_OTHER, dtype=np.uint8)
    code[ord("0"):ord("9") + 1] = _GC_DIGIT
    for chars, value in ((b"+-", _GC_SIGN), (b"GOT", _GC_PREFIX), (b".", _GC_DOT), (b",", _GC_COMMA),
                         (b"/", _GC_SLASH), (b"\r", _GC_CR), (b"\n", _GC_NEWLINE)):
        code[list(chars)] = value
    allowed = np.zeros((9, 9), dtype=bool)               # allowed[before, this]
    for this, before in _GOTO_AFTER.items():
        allowed[list(before), this] = True
    pair = np.arange(256)                                # (before << 4) | this, for bad_pairs
    earlier, later = pair >> 4, pair & 15
    pair_bad = (earlier > 8) | (later > 8)
    pair_bad[~pair_bad] = ~allowed[earlier[~pair_bad], later[~pair_bad]]
    return bytes(code.tolist()), bytes(pair_bad.tolist())


_GOTO_CODES, _GOTO_PAIR_BAD = _goto_tables()
_GOTO_PREFIX = int.from_bytes(b"GOTO/", "little")


def _plain_gotos(lines: list[str]) -> tuple[FloatArray, BoolArray]:
    """The plain GOTO lines of a chunk (:data:`_PLAIN_GOTO`, numbers of at most 15 digits), read in bulk.

    Returns
    -------
    values : (N, 6) float — x, y, z, i, j, k of each line read (NaN: no i, j, k; and on lines not read)
    read : (N,) bool — the line matches :data:`_PLAIN_GOTO` with numbers of at most 15 digits (a plain
        GOTO with longer numbers is not read here: :data:`_PLAIN_GOTO` reads it)

    How: the lines joined as UTF-8 (a lone surrogate as ``?``: any non-ASCII byte breaks a plain GOTO
    line), then one pass over the bytes in C (csrc/goto.c) where ``pip install`` compiled it, else a
    few passes with numpy (:func:`_plain_goto_text_numpy`, ``PRS3_POST_NATIVE=0``): the same rules and
    values. The rules: each byte is coded (digit, sign, point, comma, slash, CR, line end, a letter of
    ``GOTO``, other); every byte must be allowed after the one before it on a plain GOTO line
    (:data:`_GOTO_AFTER`, one table for both: ``GOT`` letters after a line start or each other, ``/``
    after them; a sign after ``/`` or ``,``; a digit after ``/``, ``,``, a sign, a point or a digit; a
    point after ``/``, ``,``, a sign or a digit; ``,``, CR and the line end after a digit or a point; a
    line end also after a CR); the line starts with ``GOTO/``; a
    number is what follows ``/`` or ``,`` up to the next ``,``, CR or line end: at most one point,
    with a digit beside it, at most 15 digits; 3 or 6 numbers. Their values: ``float`` of the text.
    """
    n = len(lines)
    if not n:
        return np.full((0, 6), np.nan), np.zeros(0, dtype=bool)
    return _plain_goto_text(("\n" + "\n".join(lines) + "\n").encode("utf-8", errors="replace"), n)


def _plain_goto_text(text: bytes, n: int) -> tuple[FloatArray, BoolArray]:
    """:func:`_plain_gotos` of ``text``: LF, then ``n`` lines each with its LF. In C (csrc/goto.c) where it
    was built, else :func:`_plain_goto_text_numpy`: the same."""
    from prs3_post.core import native  # ctypes: loaded only where lines are read in bulk

    found = native.plain_gotos(text, _GOTO_CODES, _GOTO_PAIR_BAD, n)
    return _plain_goto_text_numpy(text, n) if found is None else found


def _plain_goto_text_numpy(text: bytes, n: int) -> tuple[FloatArray, BoolArray]:
    """:func:`_plain_goto_text` with numpy (the reference of csrc/goto.c, and where that was not built)."""
    size = len(text)
    classes = text.translate(_GOTO_CODES)
    code = np.frombuffer(classes + b"\0", dtype=np.uint8)
    delimiters = np.flatnonzero(code >= _GC_DOT)
    kind = code[delimiters]
    line_end = kind == _GC_NEWLINE
    ends = delimiters[line_end]                          # ends[k + 1] ends line k
    padded = np.frombuffer(text + bytes(8), dtype=np.uint8)
    heads = np.ndarray((size + 1,), dtype="<u8", buffer=padded, strides=(1,))[ends[:-1] + 1]
    read = (heads & np.uint64(0xFFFFFFFFFF)) == np.uint64(_GOTO_PREFIX)
    bad = np.zeros(n, dtype=bool)
    wrong = bad_pairs(code[:size], _GOTO_PAIR_BAD, 4)
    if len(wrong):
        bad[np.searchsorted(ends, wrong) - 1] = True
    at = np.flatnonzero((kind == _GC_SLASH) | (kind == _GC_COMMA))   # a number follows each
    word_line = (np.cumsum(line_end, dtype=np.int32) - 1)[at]
    start = delimiters[at]
    pointed = kind[at + 1] == _GC_DOT
    after = at + 1 + pointed
    stop = delimiters[after]
    dot = delimiters[at + 1]
    bad[word_line[pointed & (kind[after] == _GC_DOT)]] = True                          # a second point
    bad[word_line[pointed & (code[dot - 1] != _GC_DIGIT) & (code[dot + 1] != _GC_DIGIT)]] = True   # a lone point
    signed = code[start + 1] == _GC_SIGN
    bad[word_line[stop - start - 1 - signed - pointed > 15]] = True
    count = np.bincount(word_line, minlength=n)
    read &= ~bad & ((count == 3) | (count == 6))
    keep = read[word_line]
    start, stop, dot, pointed, signed, word_line = (start[keep], stop[keep], dot[keep], pointed[keep], signed[keep],
                                                    word_line[keep])
    first_word = np.cumsum(count[read]) - count[read]   # each line read: its first number's index
    rank = np.arange(len(start)) - np.repeat(first_word, count[read])
    values = np.full((n, 6), np.nan)
    minus = np.frombuffer(text, dtype=np.uint8)[start + 1] == ord("-")
    values.reshape(-1)[word_line * 6 + rank] = decimal_numbers(text, start + 1 + signed, stop, dot, pointed, minus)
    return values, read


def _goto_values(values: FloatArray, written: dict[int, tuple[str | None, ...]],
                 run_index: list[int] | IntArray) -> FloatArray:
    """(k, 6) the numbers of a run of plain GOTO lines ``run_index``: from ``values`` (:func:`_plain_gotos`)
    where read in bulk, else (``written``: position in the run → the numbers as written) ``float`` of
    the text (NaN for no i, j, k)."""
    rows = values[run_index]
    for k, groups in written.items():
        rows[k] = [math.nan if g is None else float(g) for g in groups]
    return rows


#: Records read inside a bulk run of GOTOs (:meth:`LineReader.lines`): a PPRINT (its text: a comment event
#: between the rows) and a FEDRAT (read by :meth:`LineReader.fedrat` where it stands), neither with a
#: ``$`` (continuation or comment).
_PLAIN_PPRINT = re.compile(r"PPRINT/([^$]*)")
_PLAIN_FEDRAT = re.compile(r"FEDRAT/[^$]*")


class LineReader(Records):
    """A CL file's records as the lines go by: runs of plain GOTOs in bulk, every other line record by record."""

    # ---- lines, chunks, the end
    def lines(self, first: int, lines: list[str]) -> None:
        """Read ``lines`` (without line ends), the first of which is line ``first`` of the file.

        Runs of plain GOTO lines (:data:`_PLAIN_GOTO`) are read in bulk; plain ``PAINT/`` lines
        between them (display only, no comment, no continuation) are counted without ending the run,
        and plain ``PPRINT/`` and ``FEDRAT/`` lines (:data:`_PLAIN_PPRINT`, :data:`_PLAIN_FEDRAT`)
        are read where they stand in it.
        """
        assembler = self.assembler
        plain, pprint, fedrat = _PLAIN_GOTO.match, _PLAIN_PPRINT.fullmatch, _PLAIN_FEDRAT.fullmatch
        values, read = _plain_gotos(lines)
        # where each stretch of lines read in bulk ends: the first line from each index on not read
        not_read = np.flatnonzero(~read)
        stretch_end = np.append(not_read, len(lines))[np.searchsorted(not_read, np.arange(len(lines)))].tolist()
        written: dict[int, tuple[str | None, ...]] = {}  # position in the run → numbers as written (not read)
        run_index: list[int] = []
        marks: list[tuple[int, int]] = []              # (rows of the run before it, line index): PPRINT, FEDRAT
        paints = 0
        bulk = self.arc is None and self.cycle is None and not self.finished and not assembler.pending
        index, count = 0, len(lines)
        while index < count:
            if bulk:
                end = stretch_end[index]
                if end > index:                          # plain GOTO lines read in bulk, all at once
                    run_index.extend(range(index, end))
                    index = end
                    continue
                raw = lines[index]
                match = plain(raw)                       # a plain GOTO of longer numbers
                if match is not None:
                    written[len(run_index)] = match.groups()
                    run_index.append(index)
                    index += 1
                    continue
                if raw.startswith("PAINT/") and "$" not in raw:
                    paints += 1
                    index += 1
                    continue
                if run_index and (pprint(raw.rstrip("\r")) or fedrat(raw.rstrip("\r"))):
                    marks.append((len(run_index), index))
                    index += 1
                    continue
            if run_index:
                at = np.array(run_index, dtype=np.int64)
                self.goto_run(first, lines, _goto_values(values, written, at), run_index, marks, at)
                written, run_index, marks = {}, [], []
            record = assembler.push(first + index, lines[index])
            if record is not None:
                self.record(record)
            bulk = self.arc is None and self.cycle is None and not self.finished and not assembler.pending
            index += 1
        if run_index:
            at = np.array(run_index, dtype=np.int64)
            self.goto_run(first, lines, _goto_values(values, written, at), run_index, marks, at)
        if paints:
            self.records += paints
            self.by_word["PAINT"] += paints
            self.skipped["PAINT"] += paints

    def goto_run(self, first: int, lines: list[str], run: FloatArray, run_index: list[int],
                 marks: list[tuple[int, int]] | None = None, at: IntArray | None = None) -> None:
        """Plain GOTO lines ``lines[run_index]`` in bulk (``run``: (k, 6) their x, y, z, i, j, k as
        written, NaN where a GOTO has no i, j, k; ``at``: ``run_index`` as an array, if made already),
        with the PPRINT and FEDRAT lines ``marks`` ((GOTOs before it, index into ``lines``)) among
        them: the same rows, events, counts and errors as record by record."""
        marks = marks or []
        with_axis = ~np.isnan(run[:, 3])
        tip = run[:, :3] * self.scale
        given = run[with_axis, 3:]
        i, j, k = given[:, 0], given[:, 1], given[:, 2]
        length = np.sqrt(i * i + j * j + k * k)
        if (not (np.abs(tip) <= MAX_COORDINATE_MM).all() or (with_axis.any() and self.multax_on is False)
                or np.any(np.abs(length - 1.0) > AXIS_LENGTH_TOLERANCE) or np.any(length == 0.0)):
            order = sorted([*run_index, *(index for _, index in marks)])
            for index in order:                                      # one by one, for the exact error
                record = self.assembler.push(first + index, lines[index])
                assert record is not None  # a plain GOTO, PPRINT or FEDRAT line is a whole record
                self.record(record)
            return
        given = np.where((length == 1.0)[:, None], given, given / length[:, None])
        axes = np.zeros((len(run), 3))
        axes[with_axis] = given
        last = np.maximum.accumulate(np.where(with_axis, np.arange(len(run)), -1))
        axes[last < 0] = self.tool_axis
        axes[last >= 0] = axes[last[last >= 0]]
        kind = np.full(len(run), FEED, dtype=np.int64)
        if self.rapid_next:
            kind[0] = RAPID
            self.rapid_next = False
        feed = np.zeros(len(run))
        pprints = [(b, index) for b, index in marks if lines[index].startswith("PPRINT/")]
        # where no PPRINT is too long (refused where it stands), the PPRINTs in one go: no feed changes there
        together = all(len(lines[index]) <= MAX_RECORD_CHARS for _, index in pprints)
        # the feed of the rows between the marks: the FEDRAT before them (read in order, for its errors)
        feeds = [mark for mark in marks if not lines[mark[1]].startswith("PPRINT/")] if together else marks
        for (a, _), (b, index) in itertools.pairwise([(0, -1), *feeds, (len(run), -1)]):
            rows = range(max(a, 1) if kind[0] == RAPID else a, b)
            if len(rows):
                self.line = first + run_index[rows[0]]
                feed[rows.start:b] = self.current_feed()
            if index >= 0:
                self.mark(first + index, lines[index], self.rows + b)
        if together and pprints:
            before = self.rows - self.chunk_start
            comment = EventKind.COMMENT
            self.events += [Event(before + b, comment, 0.0, lines[index][len("PPRINT/"):].strip())
                            for b, index in pprints]
            self.records += len(pprints)
            self.by_word["PPRINT"] += len(pprints)
            self.comments += len(pprints)
            end_mark, end_index = marks[-1]              # the line the loop over every mark would end on
            end_start = max(end_mark, 1) if int(kind[0]) == RAPID else end_mark
            self.line = first + (run_index[end_start] if end_start < len(run) else end_index)
        count = len(run)
        self.records += count
        self.by_word["GOTO"] += count
        self.gotos += count
        self.gotos_with_axis += int(with_axis.sum())
        self.moves += count
        self.after_end = False
        self.add_rows(tip, axes, kind, feed, (np.array(run_index, dtype=np.int64) if at is None else at) + first)
        x, y, z = axes[-1].tolist()
        self.tool_axis = (x, y, z)

    def mark(self, number: int, raw: str, before: int) -> None:
        """A plain PPRINT or FEDRAT line inside a bulk run, read as :meth:`record` reads it, its comment
        event before row ``before`` (counted from the file's start: the run's rows are added after).

        Without the record's objects where that changes nothing: a PPRINT's text is the line's after
        ``PPRINT/``, stripped (as the assembler splits it); a FEDRAT line that was read before, word for
        word, sets the same feed again (:attr:`fedrat_seen`; the state it depends on, the file's scale,
        does not change). A line over the record limit goes the assembler's way, which refuses it."""
        if len(raw) <= MAX_RECORD_CHARS:
            seen = self.fedrat_seen.get(raw)
            if seen is not None or raw.startswith("PPRINT/"):
                self.line = number
                self.records += 1
                self.after_end = False
                if seen is not None:
                    self.by_word["FEDRAT"] += 1
                    self.feed_value, self.per_rev = seen
                    return
                self.by_word["PPRINT"] += 1
                self.comments += 1
                self.events.append(Event(before - self.chunk_start, EventKind.COMMENT, 0.0,
                                         raw[len("PPRINT/"):].strip()))
                return
        record = self.assembler.push(number, raw)
        assert record is not None and record.comment is None  # no '$' on the line: a whole record
        if record.word != "PPRINT":
            self.record(record)                            # FEDRAT: no rows, no events
            if len(self.fedrat_seen) >= 64:
                self.fedrat_seen.clear()
            self.fedrat_seen[raw] = (self.feed_value, self.per_rev)
            return
        self.line = number
        self.records += 1
        self.by_word["PPRINT"] += 1
        self.after_end = False
        self.comments += 1
        self.events.append(Event(before=before - self.chunk_start, kind=EventKind.COMMENT, text=record.rest or ""))
