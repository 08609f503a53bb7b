"""Write a :class:`~prs3_post.core.toolpath.JointProgram` as G-code text in a ``Dialect``.

Pure: :func:`emit_program` returns the program as a string and never opens a file; the CLI writes it.
The output is a function of its inputs only (no time stamps, host names or paths unless the caller
puts them in ``header``). :class:`ProgramEmitter` makes the same text in pieces — :meth:`~ProgramEmitter.begin`,
:meth:`~ProgramEmitter.rows` for each chunk of rows (the modal state crosses chunk boundaries), then
:meth:`~ProgramEmitter.end` — so that a program can be streamed; ``emit_program`` is the one-chunk case.
The motion rows are formatted a whole column at a time (:mod:`prs3_post.core.numbers`): the words' integers
decide which words a line repeats, and the lines are written as bytes for all rows together. Where
the compiled library is built (:func:`prs3_post.core.native.emit_rows`), one pass in C does the same for
the usual rows (every number an exact integer, no line too long), with their block numbers, and puts
the usual comments between them; numpy writes the others (and all of them with ``PRS3_POST_NATIVE=0``).

What is written, in order::

    %                                  program.percent
    O1000 (PRS3-POST)                  program.number / program.name
    (key: value)                       the caller's header, then the axis map and the feed mode
    G17 G21 G40 G49 G54 G80 G90 G94    blocks.safe_start, then blocks.preamble
    G61
    G0 X.. Y.. U.. V.. W..             motion rows, with the events before each row
    G93                                once, before the first feed row
    G1 U.. V.. F..                     every G1 carries F (inverse time, 1/min, > 0)
    G94                                back to units/min, if G93 was written
    M2                                 blocks.postamble, then program.end_code
    %

Why the motion looks like this (LinuxCNC's rules, DESIGN.md "Output"): the moves are joint-space
moves, so the programmed tip feed can only be held with G93 inverse time (each G1 takes 1/F min,
whatever the joints do). Under G93 every G1 needs its own F, every G93/G94 word resets F to 0, and
F0 is silently raised to 0.1, so an F that would print as 0 is an error here. Numbers are fixed
decimals (``1e-05`` would be read as an E word; ``nan``/``inf`` are refused); an axis word whose
*formatted* text is the same as the last one written for that axis is left out.
"""

from __future__ import annotations

import math
import textwrap
from bisect import bisect_left, bisect_right, insort
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from prs3_post.core.errors import LimitError
from prs3_post.core.numbers import ChoiceColumn, ScaledColumn, fixed, format_word, render_rows, scale_column
from prs3_post.core.toolpath import Event, EventKind, JointProgram, MoveKind
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.kinematics.protocol import Kinematics, joint_letters
from prs3_post.kinematics.prs3.kinematics import Prs3Kinematics
from prs3_post.machine.dialect import COMMENT_CONTINUATION as _CONTINUATION
from prs3_post.machine.dialect import CommentStyle, Dialect

__all__ = ["ProgramEmitter", "emit_program", "format_word", "inert", "sanitize_comment"]



def sanitize_comment(text: str, style: CommentStyle) -> str:
    """Make ``text`` safe to put between the comment delimiters of ``style`` (one line, no delimiter).

    Each character of ``style.replace`` is replaced first; then control characters (newline, tab,
    CR, ...) become ``style.control`` and any other character outside printable ASCII becomes
    ``style.non_ascii``; then the text is upper-cased if the style asks for it (after the
    replacements, so that only ASCII is upper-cased); last, a text that starts with one of the
    controller's ``active_words`` and a comma (LinuxCNC's ``MSG,``, ``DEBUG,``, ...; leading
    spaces and case do not matter to it) gets that comma turned into a period (:func:`inert`).

    Parameters
    ----------
    text : str
        Any text (a header value, an operator comment from the CAM input, ...).
    style : CommentStyle
        The dialect's comment style; its loader guarantees that no replacement contains a delimiter.

    Returns
    -------
    str
        Printable ASCII without any character of ``style.open`` or ``style.close``.

    Examples
    --------
    >>> from prs3_post.machine.loading import load_dialect
    >>> sanitize_comment("hole (1)\\nat 26.6°", load_dialect("linuxcnc").comments)
    'hole [1] at 26.6 deg'
    >>> sanitize_comment(" msg, stop here", load_dialect("linuxcnc").comments)
    ' msg. stop here'
    """
    if text.isascii() and text.isprintable() and _replaced(style.replace).isdisjoint(text):
        return inert(text.upper() if style.uppercase else text, style)   # nothing to replace: the usual case
    replace = dict(style.replace)
    out: list[str] = []
    for char in text:
        if char in replace:
            out.append(replace[char])
        elif " " <= char <= "~":
            out.append(char)
        elif ord(char) < 32 or ord(char) == 127 or 128 <= ord(char) < 160:  # C0, DEL, C1 controls
            out.append(style.control)
        else:
            out.append(style.non_ascii)
    safe = "".join(out)
    return inert(safe.upper() if style.uppercase else safe, style)


@lru_cache(maxsize=8)
def _replaced(replace: tuple[tuple[str, str], ...]) -> frozenset[str]:
    """The characters a comment style replaces."""
    return frozenset(key for key, _ in replace)


def inert(text: str, style: CommentStyle) -> str:
    """``text``, with the comma after a leading active word made a period so the controller does
    not act on it (``MSG, x`` → ``MSG. x``: a plain comment, and the same length).

    >>> from prs3_post.machine.loading import load_dialect
    >>> inert("  Debug, x", load_dialect("linuxcnc").comments), inert("debugging, x", load_dialect("linuxcnc").comments)
    ('  Debug. x', 'debugging, x')
    """
    if "," not in text:
        return text
    head = text.lstrip().split(",", 1)
    if len(head) == 2 and head[0].strip().upper() in style.active_words:
        return text.replace(",", ".", 1)
    return text



#: Rows formatted together when a chunk is long: bounds the scratch memory (about 100 bytes a row).
CHUNK_ROWS = 65536


class _Blocks:
    """Lines of text: block numbers, comment wrapping and the line-length limit in one place."""

    def __init__(self, dialect: Dialect, numbered: bool, start: int, step: int):
        self.dialect = dialect
        self.numbered, self.start, self.number, self.step = numbered, start, start, step
        # LinuxCNC counts the CR of a CRLF ending towards its limit.
        self.limit = dialect.max_line_length - (len(dialect.line_ending) - 1)
        self.lines: list[str] = []
        style = dialect.comments
        self._comment_width = self.limit - len(style.open) - len(style.close)
        self._replaced = _replaced(style.replace)
        self._open, self._close, self._upper = style.open, style.close, style.uppercase
        self._ending = dialect.line_ending

    def raw(self, text: str) -> None:
        """A line written as it is, never numbered (``%``, the ``O`` line)."""
        self.lines.append(text)

    def block(self, text: str, where: str) -> None:
        """A block, numbered when numbering is on; a line over the limit is a LimitError at ``where``."""
        if self.numbered:
            text = f"{self.dialect.line_numbers.letter}{self.number} {text}"
            self.number = int(self.numbers_after(1)[0])
        self.check_length(text, where)
        self.lines.append(text)

    def check_length(self, text: str, where: str) -> None:
        if len(text) > self.limit:
            raise LimitError(
                f"{where}: the block is {len(text)} characters, the dialect allows {self.limit}: {text[:60]}..."
            )

    def numbers_after(self, count: IntArray | int) -> IntArray:
        """The block number ``count`` blocks after the current one: ``step`` apart, back to the
        program's first number after ``line_numbers.wrap_after``."""
        count = np.asarray(count, dtype=np.int64).reshape(-1)
        wrap = self.dialect.line_numbers.wrap_after
        first_lap = (wrap - self.number) // self.step + 1           # numbers left before the first wrap
        lap = (wrap - self.start) // self.step + 1                  # numbers in every later lap
        later = self.start + ((count - first_lap) % lap) * self.step
        return np.where(count < first_lap, self.number + count * self.step, later)

    def plain_line(self, text: str) -> str | None:
        """The usual comment's line with its ending: ``text`` as it is (upper-cased if the style says so),
        where it fits on one line and needs no replacement; None for any other (:meth:`comment` it).
        The emitter puts these straight between its rows (a comment every few dozen rows is common)."""
        if (len(text) <= self._comment_width and text.isascii() and text.isprintable() and "," not in text
                and self._replaced.isdisjoint(text)):      # as comment() would write it (trailing spaces dropped)
            return f"{self._open}{(text.upper() if self._upper else text).rstrip(' ')}{self._close}{self._ending}"
        return None

    @property
    def comment_frame(self) -> int:
        """The characters a usual comment's line has besides its text: the delimiters and the ending."""
        return len(self._open) + len(self._close) + len(self._ending)

    def plain_lines(self, texts: list[str]) -> str | None:
        """:meth:`plain_line` of every text, back to back, where every one is usual and none ends in a
        space; else None. Checked and made for all together (a program has a comment every few dozen rows)."""
        joined = "".join(texts)
        if not (joined.isascii() and joined.isprintable() and "," not in joined
                and not any(char in joined for char in self._replaced)
                and max(map(len, texts), default=0) <= self._comment_width):
            return None
        lines = "\n".join(texts) + "\n"              # printable texts: no LF of their own
        if " \n" in lines:                            # a trailing space to drop: one by one
            return None
        if self._upper:
            lines = lines.upper()
        if not texts:
            return ""
        framed = lines.replace("\n", self._close + self._ending + self._open)    # "a)\n(b)\n("
        return self._open + framed[:len(framed) - len(self._open)]

    def comment(self, text: str) -> None:
        """A comment, sanitized, split over as many unnumbered lines as it needs."""
        style = self.dialect.comments
        line = self.plain_line(text)
        if line is not None:                   # the usual one: as it is, on one line (as below)
            self.lines.append(line[:len(line) - len(self._ending)])
            return
        width = self._comment_width
        # Sanitizing first: it can lengthen the text, and it leaves one line of printable ASCII.
        safe = sanitize_comment(text, style)
        if len(safe) <= width:                 # one line: what textwrap makes of it (trailing spaces dropped)
            parts = [safe.rstrip(" ")]
        else:
            parts = wrap_comment(safe, width) or [""]
        # a continuation line could start with an active word again: guard every line
        self.lines.extend(f"{style.open}{inert(part, style)}{style.close}" for part in parts)

    def take(self) -> str:
        """The lines so far, each ended by the dialect's line ending; the list starts over."""
        ending = self.dialect.line_ending
        text = "".join(line + ending for line in self.lines)
        self.lines.clear()
        return text


class _Wrapper(textwrap.TextWrapper):
    """textwrap's wrapping, with a word longer than a line cut in one pass. TextWrapper cuts one line off such a
    word and puts the rest back, copying it, once per line: quadratic in the word's length (a CAM comment of 20 MB
    without a space took some 20 s to convert, 50 MB minutes). The pieces are the same: the first fills the line,
    each later one a whole line (``width`` less the indent), the last is what is left."""

    def _handle_long_word(self, reversed_chunks: list[str], cur_line: list[str], cur_len: int, width: int) -> None:
        room = self.width - len(self.subsequent_indent)           # every later line's
        chunk = reversed_chunks[-1]
        if (width < 1 or room < 1 or not self.break_long_words or self.break_on_hyphens
                or chunk.strip() == ""):                          # spaces: a later line drops them whole
            super()._handle_long_word(reversed_chunks, cur_line, cur_len, width)
            return
        space_left = width - cur_len
        cur_line.append(chunk[:space_left])
        rest = chunk[space_left:]
        reversed_chunks[-1:] = [rest[i:i + room] for i in range(0, len(rest), room)][::-1] or [""]


def wrap_comment(text: str, width: int) -> list[str]:
    """``text`` in lines of at most ``width`` characters, the later ones indented by :data:`_CONTINUATION`: as
    ``textwrap.wrap(text, width, subsequent_indent=_CONTINUATION, break_on_hyphens=False)``, in linear time."""
    return _Wrapper(width=width, subsequent_indent=_CONTINUATION, break_on_hyphens=False).wrap(text)


#: The M code of each spindle direction, and of each program stop.
_SPINDLE_ON = {EventKind.SPINDLE_ON: "M3", EventKind.SPINDLE_ON_CCW: "M4"}
_STOPS = {EventKind.STOP: "M0", EventKind.OPTIONAL_STOP: "M1"}


def _event_blocks(where: str, event: Event, dialect: Dialect) -> tuple[str | None, str]:
    """``(comment or None, block)`` for a non-COMMENT event; bad values are a LimitError at ``where``."""
    value = float(event.value)
    dec = dialect.decimals
    if event.kind in _SPINDLE_ON:
        word = format_word("S", value, dec.spindle) if math.isfinite(value) else ""
        if not word or float(word[1:]) <= 0:
            raise LimitError(
                f"{where}: spindle speed must be > 0 rpm once printed with decimals.spindle = {dec.spindle}, "
                f"got {value!r}"
            )
        return None, f"{word} {_SPINDLE_ON[event.kind]}"
    if event.kind is EventKind.SPINDLE_OFF:
        return None, "M5"
    if event.kind is EventKind.COOLANT_ON:
        return None, event.coolant.m_word
    if event.kind is EventKind.COOLANT_OFF:
        return None, "M9"
    if event.kind is EventKind.TOOL_CHANGE:
        top = dialect.tool_number_max
        if not (math.isfinite(value) and 0 <= value <= top and value == int(value)):
            raise LimitError(f"{where}: tool number must be a whole number 0..{top} (words.tool_number_max), "
                             f"got {value!r}")
        return (event.text or None), f"T{int(value)} M6"
    if event.kind is EventKind.DWELL:
        if not (math.isfinite(value) and value >= 0):
            raise LimitError(f"{where}: dwell must be a finite number ≥ 0 s, got {value!r}")
        seconds = value * 1000.0 if dialect.dwell_unit == "ms" else value
        return None, f"G4 {format_word('P', seconds, dec.dwell)}"
    if event.kind in _STOPS:
        return None, _STOPS[event.kind]
    raise ValueError(f"no G-code for event kind {event.kind!r}")


def _axis_line(dialect: Dialect, stage: bool, joints: tuple[tuple[str, str], ...]) -> str:
    ax = dialect.axes
    strokes = (f"{' '.join(letter for _, letter in joints)} = actuator strokes "
               f"{' '.join(name for name, _ in joints)} mm")
    if stage:
        return f"axes: {ax.x} {ax.y} = stage X Y mm, {strokes}"
    return f"axes: {strokes}, no stage"


#: Events after which the axes are stated again: the tool-change macro or the operator may move them.
_RESTATE = (EventKind.TOOL_CHANGE, EventKind.STOP, EventKind.OPTIONAL_STOP)


@dataclass(slots=True)
class _Modal:
    """What the controller remembers between lines, as far as the emitter relies on it."""

    words: list[str | None]
    """Text of the last word written for each axis column (None: unknown, write it)."""
    motion: int | None = None
    """MoveKind of the last motion line (None: unknown, write G0/G1)."""
    inverse_time: bool = False
    """G93 is in effect (written before the first feed row)."""
    rows: int = 0
    """Rows emitted so far (messages count rows across chunks)."""

    def restate(self) -> None:
        self.words = [None] * len(self.words)
        self.motion = None


@dataclass(frozen=True, slots=True)
class _Chunk:
    """One chunk's rows, checked and formatted as integers; lines not made yet."""

    program: JointProgram
    axes: list[tuple[bytes, FloatArray]]     # word letter and values (checked finite), in word order
    feed: FloatArray                         # F of every row, checked (1 on rapids: never written)
    befores: list[int] = field(default_factory=list)
    """Each event's row (``program.events`` is in row order)."""
    rows_with_events: list[int] = field(default_factory=list)
    """The rows that have events, increasing."""
    restate: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """The rows (increasing) after a tool change or a stop: every word is written again."""
    numbered: dict[int, int] = field(default_factory=dict)
    """How many numbered blocks (events other than comments) come before each row that has some."""
    special: frozenset[int] = frozenset()
    """The rows with an event other than a usual comment (:meth:`_Blocks.plain_line`): written by
    :meth:`ProgramEmitter._event` (all of the row's events, in order)."""
    comment_rows: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """(K,) the rows of the usual comments of the other rows, increasing: the compiled writer puts
    their lines, ``comment_bytes[comment_starts[k]:comment_starts[k + 1]]``, before their row."""
    comment_starts: IntArray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    comment_bytes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.uint8))

    def events_at(self, row: int) -> tuple[Event, ...]:
        """The events before ``row``, in order."""
        return self.program.events[bisect_left(self.befores, row):bisect_right(self.befores, row)]


class ProgramEmitter:
    """A program in ``dialect``, made in pieces: ``begin(header)``, ``rows(chunk)`` ..., ``end()``.

    Each call returns the text of its lines (joined and terminated by ``dialect.line_ending``); the
    concatenation is the program :func:`emit_program` writes for all rows in one chunk, whatever
    the chunking. Parameters and errors: see :func:`emit_program`. Rows are named ``row K from ...``
    with K counted over all chunks.
    """

    def __init__(self, dialect: Dialect, *, stage: bool = True, line_numbers: bool | None = None,
                 line_start: int | None = None, line_step: int | None = None,
                 kinematics: Kinematics | None = None):
        numbering = dialect.line_numbers
        start = numbering.start if line_start is None else line_start
        step = numbering.step if line_step is None else line_step
        if not 0 <= start <= numbering.wrap_after:
            raise ValueError(f"line_start must be 0..{numbering.wrap_after}, got {start}")
        if step < 1:
            raise ValueError(f"line_step must be ≥ 1, got {step}")
        self.dialect, self.stage = dialect, stage
        given = Prs3Kinematics if kinematics is None else kinematics          # (no kinematics: the 3-PRS head's)
        letters = joint_letters(given.joint_names, given.default_letters, dialect.axes)
        self.joints = tuple(zip(given.joint_names, letters, strict=True))
        self._out = _Blocks(dialect, numbering.enabled if line_numbers is None else line_numbers, start, step)
        self._modal = _Modal(words=[None] * (len(self.joints) + (2 if stage else 0)))

    # ------------------------------------------------------------------ begin and end
    def begin(self, header: tuple[tuple[str, str], ...] = ()) -> str:
        """``%``, the O line, the header comments, the safe start and the preamble."""
        dialect, out = self.dialect, self._out
        if dialect.percent:
            out.raw("%")
        if dialect.program_number:
            o_line = f"O{dialect.program_number}"
            if dialect.program_name:
                style = dialect.comments
                o_line += f" {style.open}{sanitize_comment(dialect.program_name, style)}{style.close}"
            out.raw(o_line)
        for key, value in header:
            out.comment(f"{key}: {value}")
        out.comment(_axis_line(dialect, self.stage, self.joints))
        out.comment("motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min")
        for line in dialect.safe_start:
            out.block(line, "blocks.safe_start")
        for line in dialect.preamble:
            out.block(line, "blocks.preamble")
        return out.take()

    def end(self) -> str:
        """Back to G94 (if G93 was written), the postamble, the end code and ``%``."""
        dialect, out = self.dialect, self._out
        if self._modal.inverse_time:
            out.block("G94", "the end of inverse time")
        for line in dialect.postamble:
            out.block(line, "blocks.postamble")
        out.block(dialect.end_code, "program.end_code")
        if dialect.percent:
            out.raw("%")
        return out.take()

    # ------------------------------------------------------------------ rows
    def rows(self, program: JointProgram) -> str:
        """The motion lines of ``program``'s rows and the events between them (``before == N``:
        after its last row), continuing from the rows before."""
        return "".join(self.row_pieces(program))

    def row_pieces(self, program: JointProgram) -> Iterator[str]:
        """:meth:`rows` as consecutive pieces of text (a few ten thousand lines each), for a
        writer that streams them. The rows are checked before the first piece."""
        n = len(program)
        _check_rows(program)
        chunk = self._prepare(program)
        for lo in range(0, max(n, 1), CHUNK_ROWS):
            yield from self._emit_rows(chunk, lo, min(n, lo + CHUNK_ROWS))
        self._modal.rows += n

    def _where(self, program: JointProgram, row: int) -> str:
        return f"row {self._modal.rows + row} from {program.describe(row)}"

    def _event_where(self, program: JointProgram, event: Event) -> str:
        if event.before == len(program):
            return f"{event.kind.value} event after the last row"
        return f"{event.kind.value} event before {self._where(program, event.before)}"

    def _prepare(self, program: JointProgram) -> _Chunk:
        """Every column checked, the F words scaled to the integers they print as (the axis words
        are scaled CHUNK_ROWS rows at a time, when written); errors name the first bad row."""
        ax, dec = self.dialect.axes, self.dialect.decimals
        named = [(ax.x, program.stage[:, 0], "stage X"), (ax.y, program.stage[:, 1], "stage Y"),
                 *((letter, program.strokes[:, j], f"actuator stroke {name}")
                   for j, (name, letter) in enumerate(self.joints))]
        with np.errstate(over="ignore", invalid="ignore"):       # a sum is not finite where a value is not
            finite = np.isfinite(program.stage.sum() + program.strokes.sum())    # (or where it overflows)
        for letter, values, name in ([] if finite else named):
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                row = int(bad[0])
                raise LimitError(f"{self._where(program, row)}: {name} ({letter}) is {float(values[row])!r}, "
                                 "not a finite number")
        if not self.stage:
            for _, values, name in (named[:2] if program.stage.any() else []):    # (zeros print as zero)
                column = scale_column(values, dec.length)
                moved = np.flatnonzero(column.scaled)
                if moved.size:
                    raise LimitError(f"{self._where(program, int(moved[0]))}: {name} is "
                                     f"{column.text(int(moved[0]))} mm on a machine without a stage")
            named = named[2:]
        befores = [event.before for event in program.events]       # increasing (JointProgram sorts them)
        numbered: dict[int, int] = {}
        restate: set[int] = set()
        comments: list[Event] = []
        for event in program.events:
            if event.kind is EventKind.COMMENT:
                comments.append(event)
                continue
            numbered[event.before] = numbered.get(event.before, 0) + 1
            if event.kind in _RESTATE:
                restate.add(event.before)
        special, comment_rows, comment_starts, comment_bytes = self._comment_lines(comments, numbered)
        return _Chunk(program=program, axes=[(letter.encode("ascii"), values) for letter, values, _ in named],
                      feed=self._feed_column(program, dec.inverse_time), befores=befores,
                      rows_with_events=list(dict.fromkeys(befores)), restate=np.array(sorted(restate), dtype=np.int64),
                      numbered=numbered, special=special, comment_rows=comment_rows, comment_starts=comment_starts,
                      comment_bytes=comment_bytes)

    def _comment_lines(self, comments: list[Event], numbered: dict[int, int],
                       ) -> tuple[frozenset[int], IntArray, IntArray, np.ndarray]:
        """The rows whose events the compiled writer leaves to :meth:`_event` (those with an event other
        than a usual comment), and the usual comments of the other rows as ``_Chunk`` holds them."""
        out = self._out
        texts = [event.text for event in comments]
        rows = np.fromiter((event.before for event in comments), dtype=np.int64, count=len(comments))
        joined = out.plain_lines(texts)
        if joined is not None:
            lines = joined.encode("ascii")
            usual = np.ones(len(texts), dtype=bool)
            lengths = np.fromiter(map(len, texts), dtype=np.int64, count=len(texts)) + out.comment_frame
        else:                                        # one by one: some need sanitizing or wrapping
            each = [out.plain_line(text) for text in texts]
            usual = np.array([line is not None for line in each], dtype=bool)
            kept = [line for line in each if line is not None]
            lines = "".join(kept).encode("ascii")
            lengths = np.fromiter(map(len, kept), dtype=np.int64, count=len(kept))
        special = frozenset(numbered) | frozenset(rows[~usual].tolist())
        data = np.frombuffer(lines, dtype=np.uint8)
        rows = rows[usual]
        if special:                                  # the comments of a special row go with its other events
            keep = ~np.isin(rows, np.fromiter(special, dtype=np.int64, count=len(special)))
            data = data[np.repeat(keep, lengths)]
            rows, lengths = rows[keep], lengths[keep]
        starts = np.zeros(len(rows) + 1, dtype=np.int64)
        np.cumsum(lengths, out=starts[1:])
        return special, rows, starts, data

    def _feed_column(self, program: JointProgram, decimals: int) -> FloatArray:
        """The F word's value on every FEED row (rapids: 1, never written); one that is not > 0 once
        printed is a LimitError naming its row. The words are scaled where they are written."""
        feed = program.kind == MoveKind.FEED
        values = np.where(feed, program.inverse_time, 1.0)
        with np.errstate(invalid="ignore", over="ignore"):   # min: nan where one is; sum: inf where one is
            usual = bool(values.min(initial=1.0) > 0) and bool(np.isfinite(values.sum()))
            bad = np.zeros(0, dtype=np.int64) if usual else np.flatnonzero(~(np.isfinite(values) & (values > 0)))
        if bad.size:
            row = int(bad[0])
            raise LimitError(f"{self._where(program, row)}: inverse-time feed must be a finite number > 0 /min, "
                             f"got {float(values[row])!r}")
        if float(values.min(initial=1.0)) * 10.0**decimals > 0.75:    # (so far from 0.5 that it prints >= 1)
            return values
        column = scale_column(values, decimals)
        zero = np.flatnonzero(feed & (column.scaled == 0))
        if zero.size:
            row = int(zero[0])
            value = float(values[row])
            raise LimitError(
                f"{self._where(program, row)}: inverse-time feed {value:.6g} /min formats to "
                f"F{column.text(row)} with decimals.inverse_time = {decimals} (the move would take "
                f"{1 / value:.6g} min); LinuxCNC would raise F0 to 0.1 and run the move at another feed"
            )
        return values

    def _emit_rows(self, chunk: _Chunk, lo: int, hi: int) -> list[str]:
        """Rows ``lo:hi`` of the chunk with the events before them (and those after the last row)."""
        program, out, modal = chunk.program, self._out, self._modal
        n = len(program)
        kind = program.kind[lo:hi]
        g93 = _first_feed(kind, lo) if not modal.inverse_time else None
        restate = chunk.restate[(chunk.restate >= lo) & (chunk.restate < hi)] - lo
        keys = chunk.rows_with_events
        written = self._rows_in_one_pass(chunk, lo, hi, g93, restate)
        if written is not None:                      # the usual comments are in text: the other events
            text, offsets = written
            too_long, plain_rows = hi - lo, True
            breaks = [b for b in keys[bisect_left(keys, lo):bisect_left(keys, hi)] if b in chunk.special]
        else:
            text, offsets, too_long = self._rows_numpy(chunk, lo, hi, g93, restate)
            # the rows between two breaks need no more than a slice of text when they are not numbered and
            # none is too long (the usual case); else _rows_text
            plain_rows = not out.numbered and too_long == hi - lo
            breaks = keys[bisect_left(keys, lo):bisect_left(keys, hi)]
        if hi == n:
            breaks.append(n)                         # (and the events after the last row)
        if g93 is not None and g93 not in breaks:   # (once a program)
            insort(breaks, g93)
        plain_line = out.plain_line
        pieces = []
        at, previous = 0, lo                         # where the text not yet written starts, and its row
        for b in breaks:
            cut = int(offsets[b - lo])               # where row b's line starts (after comments put in)
            if cut > at:                             # the text up to this break, as one piece
                if out.lines:
                    pieces.append(out.take())
                pieces.append(self._slice(text, at, cut, b - previous) if plain_rows else
                              self._rows_text(chunk, text, offsets, too_long, lo, previous - lo, b - lo))
                at, previous = cut, b
            if written is None or b in chunk.special or b == n:
                for event in chunk.events_at(b):
                    if event.kind is EventKind.COMMENT and not out.lines:
                        line = plain_line(event.text)    # the usual comment: its line goes straight in
                        if line is not None:
                            pieces.append(line)
                            continue
                    self._event(program, event)
            if b == g93:
                out.block("G93", self._where(program, b))
                modal.inverse_time = True
        if len(text) > at:
            if out.lines:
                pieces.append(out.take())
            pieces.append(self._slice(text, at, len(text), hi - previous) if plain_rows else
                          self._rows_text(chunk, text, offsets, too_long, lo, previous - lo, hi - lo))
        if out.lines:
            pieces.append(out.take())
        self._remember(chunk, hi, kind)
        return pieces                                # (one piece, the usual: rows() joins it without a copy)

    def _slice(self, text: str, a: int, b: int, rows: int) -> str:
        """``text[a:b]``, which holds ``rows`` numbered rows: the block number moves on past them."""
        if self._out.numbered:
            self._out.number = int(self._out.numbers_after(rows)[0])
        return text[a:b]

    def _rows_in_one_pass(self, chunk: _Chunk, lo: int, hi: int, g93: int | None,
                          restate: IntArray) -> tuple[str, IntArray] | None:
        """Rows ``lo:hi``'s lines by the compiled writer (:func:`prs3_post.core.native.emit_rows`), with the
        usual comments of the rows that have no other event before them: (the text, where each row's
        line starts, then the text's end (M + 1)). None where it cannot: not built, a feed or a number
        not written from an exact integer, or an over-long line (:meth:`_rows_numpy` writes those, and
        finds the errors)."""
        out, modal, dialect = self._out, self._modal, self.dialect
        from prs3_post.core import native  # ctypes: loaded only where lines are written

        decimals = dialect.decimals.length
        first_present = [word is None or (lo < hi and fixed(float(values[lo]), decimals) != word)
                         for (_, values), word in zip(chunk.axes, modal.words, strict=True)]
        a, b = np.searchsorted(chunk.comment_rows, [lo, hi])
        written = native.emit_rows(
            [values[lo:hi] for _, values in chunk.axes], decimals, first_present, chunk.program.kind[lo:hi],
            -1 if modal.motion is None else modal.motion, restate, dialect.modal_motion, chunk.feed[lo:hi],
            dialect.decimals.inverse_time, [letter for letter, _ in chunk.axes], dialect.line_ending.encode("ascii"),
            (chunk.comment_rows[a:b] - lo, chunk.comment_starts[a:b + 1], chunk.comment_bytes),
            (dialect.line_numbers.letter.encode("ascii"), out.numbers_after(self._block_index(chunk, lo, hi, g93)))
            if out.numbered else None)
        if written is None:
            return None
        buffer, starts, lengths = written
        if lengths.size and int(lengths.max()) - len(dialect.line_ending) > out.limit:
            return None
        line_starts = np.append(starts[1:] - lengths, starts[-1])    # (a few are looked up: not made a list)
        return str(buffer.data, "ascii"), line_starts

    @staticmethod
    def _block_index(chunk: _Chunk, lo: int, hi: int, g93: int | None) -> IntArray:
        """(M,) — how many blocks after the current one each of the rows ``lo:hi`` is numbered: the rows
        and the numbered blocks between them (events other than comments, and G93), in order."""
        blocks_before = np.zeros(hi - lo, dtype=np.int64)
        for b, count in chunk.numbered.items():
            if lo <= b < hi:
                blocks_before[b - lo:] += count
        if g93 is not None:
            blocks_before[g93 - lo:] += 1
        return np.arange(hi - lo) + blocks_before

    def _rows_numpy(self, chunk: _Chunk, lo: int, hi: int, g93: int | None,
                    restate: IntArray) -> tuple[str, IntArray, int]:
        """Rows ``lo:hi``'s lines, column by column with numpy: (the text, where each row's line starts
        (M + 1), the first over-long line (M: none))."""
        out = self._out
        axes = [(letter, scale_column(values[lo:hi], self.dialect.decimals.length)) for letter, values in chunk.axes]
        present, motion = self._words_present(chunk, axes, lo, hi, restate)
        block_index = self._block_index(chunk, lo, hi, g93) if out.numbered else np.arange(hi - lo)
        buffer, ends = self._render(chunk, axes, lo, hi, present, motion, block_index)
        text = str(buffer.data, "ascii")             # every row's line; ASCII: a byte offset is a character's
        long = np.flatnonzero(np.diff(ends) - len(self.dialect.line_ending) > out.limit)
        return text, ends, int(long[0]) if long.size else hi - lo

    def _event(self, program: JointProgram, event: Event) -> None:
        out = self._out
        if event.kind is EventKind.COMMENT:
            out.comment(event.text)
            return
        where = self._event_where(program, event)
        comment, block = _event_blocks(where, event, self.dialect)
        if comment is not None:
            out.comment(comment)
        out.block(block, where)
        if event.kind in _RESTATE:
            self._modal.restate()

    def _words_present(self, chunk: _Chunk, axes: list[tuple[bytes, ScaledColumn]], lo: int, hi: int,
                       restate: IntArray) -> tuple[BoolArray, IntArray]:
        """(rows, columns) — which axis words each of the rows ``lo:hi`` (``axes``: theirs) writes,
        and each line's motion word (0 G0, 1 G1, 2 none). A word is left out when its text is the
        one last written for its axis; everything is written again on the first line and after a
        tool change or a stop."""
        modal, dialect = self._modal, self.dialect
        m = hi - lo
        kind = chunk.program.kind[lo:hi]
        present = np.ones((m, len(axes)), dtype=bool)
        for j, (_, column) in enumerate(axes):
            if m:
                same = column.same_as_previous()
                same[0] = column.text(0) == modal.words[j]
                present[:, j] = ~same
        present[restate] = True
        previous = np.empty(m, dtype=np.int64)
        previous[1:] = kind[:-1]
        previous[:1] = -1 if modal.motion is None else modal.motion
        previous[restate] = -1
        motion = np.where(kind == MoveKind.FEED, 1, 0)
        if dialect.modal_motion:
            motion = np.where((kind != previous) | ~present.any(axis=1), motion, 2)
        return present, motion

    def _render(self, chunk: _Chunk, axes: list[tuple[bytes, ScaledColumn]], lo: int, hi: int,
                present: BoolArray, motion: IntArray, block_index: IntArray) -> tuple[np.ndarray, IntArray]:
        """Every row's line as bytes (see :func:`prs3_post.core.numbers.render_rows`); over-long ones are
        found here and reported when their turn comes."""
        out = self._out
        m = hi - lo
        columns: list = []
        shown = []
        if out.numbered:
            numbers = out.numbers_after(block_index)
            columns.append((self.dialect.line_numbers.letter.encode("ascii"),
                            ScaledColumn(numbers, 0, np.zeros(0, dtype=np.int64), ())))
            shown.append(np.ones(m, dtype=bool))
        columns.append(ChoiceColumn(np.minimum(motion, 1), (b"G0", b"G1")))
        shown.append(motion < 2)
        columns.extend(axes)
        shown.extend(present.T)
        columns.append((b"F", scale_column(chunk.feed[lo:hi], self.dialect.decimals.inverse_time)))
        shown.append(chunk.program.kind[lo:hi] == MoveKind.FEED)
        return render_rows(columns, np.column_stack(shown) if m else np.zeros((0, len(columns)), dtype=bool),
                           ending=self.dialect.line_ending.encode("ascii"))

    def _rows_text(self, chunk: _Chunk, text: str, offsets: IntArray, too_long: int, lo: int, a: int,
                   b: int) -> str:
        """Lines ``a:b`` of those rendered for the rows from ``lo`` on (``text``, ``offsets``: where each
        line starts), as text; the first over-long one (``too_long``) is a LimitError naming its row."""
        out = self._out
        if a <= too_long < b:
            ending = len(self.dialect.line_ending)
            line = text[offsets[too_long]:offsets[too_long + 1] - ending]
            out.check_length(line, self._where(chunk.program, lo + too_long))
        if out.numbered:
            out.number = int(out.numbers_after(b - a)[0])
        return text[offsets[a]:offsets[b]]

    def _remember(self, chunk: _Chunk, hi: int, kind: IntArray) -> None:
        """The modal state after the rows up to ``hi`` (``kind``: the last rows') and the events after
        the last row."""
        modal = self._modal
        if len(kind):
            decimals = self.dialect.decimals.length
            for j, (_, values) in enumerate(chunk.axes):
                modal.words[j] = fixed(float(values[hi - 1]), decimals)    # as the line printed it
            modal.motion = int(kind[-1])
        if hi == len(chunk.program) and any(e.kind in _RESTATE for e in chunk.events_at(hi)):
            modal.restate()


def _first_feed(kind: IntArray, lo: int) -> int | None:
    feeds = np.flatnonzero(kind == MoveKind.FEED)
    return lo + int(feeds[0]) if feeds.size else None


def _check_rows(program: JointProgram) -> None:
    """Mistakes no caller should make: a kind that is not a MoveKind, an event outside ``0 ..= N``."""
    n, kind, events = len(program), program.kind, program.events
    if n and not (kind.min() >= MoveKind.RAPID and kind.max() <= MoveKind.FEED):    # (RAPID 0, FEED 1)
        unknown = np.flatnonzero((kind != MoveKind.RAPID) & (kind != MoveKind.FEED))
        raise ValueError(f"row {int(unknown[0])}: kind {int(kind[unknown[0]])} is not a MoveKind")
    if events and not (0 <= events[0].before and events[-1].before <= n):     # in row order (JointProgram)
        for event in events:
            if not 0 <= event.before <= n:
                raise ValueError(f"{event.kind.value} event: before = {event.before} is outside 0..{n}")


def emit_program(
    program: JointProgram,
    dialect: Dialect,
    *,
    header: tuple[tuple[str, str], ...] = (),
    stage: bool = True,
    line_numbers: bool | None = None,
    line_start: int | None = None,
    line_step: int | None = None,
    kinematics: Kinematics | None = None,
) -> str:
    """The whole program as G-code text in ``dialect``.

    Parameters
    ----------
    program : JointProgram
        Rows in actuator space: ``stage`` (N, 2) mm, ``strokes`` (N, J) mm, ``inverse_time`` (N,)
        1/min (> 0 on FEED rows), and the events between rows (``before == N``: after the last row).
    dialect : Dialect
        Letters, decimals, comments, numbering and the fixed blocks (see ``postproc/dialects``).
    header : tuple of (str, str)
        ``(key, value)`` pairs written as ``(key: value)`` comments at the top, in order (tool,
        machine, part, face, operation, parameters, units, ...). Long ones are split over lines.
    stage : bool
        The machine has an XY stage. False: X and Y words are never written, and a non-zero stage
        value is an error.
    line_numbers, line_start, line_step : bool, int, int, optional
        Override the dialect's block numbering (None: the dialect's value).
    kinematics : Kinematics, optional
        Whose joints the ``strokes`` columns are: their names and letters (None: the 3-PRS head's).

    Returns
    -------
    str
        The program, lines joined and terminated by ``dialect.line_ending``; every line is at most
        ``dialect.max_line_length`` characters (one less with CRLF).

    Raises
    ------
    LimitError
        Naming the row (``row 3 from hole 1 feed``) or event: a non-finite axis value, an
        inverse-time feed that is not > 0 once printed, a stage value on a machine without a
        stage, a bad spindle speed, dwell or tool number, or a block longer than the dialect allows.
    ValueError
        For arguments no caller should pass: a kind that is not a MoveKind, an event outside
        ``0 ..= N``, ``line_start`` outside ``0 ..= line_numbers.wrap_after``, ``line_step < 1``
        (the CLI bounds its options so that these never come from a user).

    Notes
    -----
    An axis word is left out when its formatted text equals the last one written for that axis. The
    first motion line, and the first one after a tool change or a program stop (the operator or
    the tool-change macro may have moved the axes), carry every axis word. With
    ``words.modal_motion`` G0/G1 is also written only when it changes (and always on those lines,
    and on a line that would otherwise carry no axis word).
    """
    emitter = ProgramEmitter(dialect, stage=stage, line_numbers=line_numbers, line_start=line_start,
                             line_step=line_step, kinematics=kinematics)
    _check_rows(program)
    return "".join([emitter.begin(header), *emitter.row_pieces(program), emitter.end()])
