"""Read a prs3-post program (actuator-space G-code) back into a :class:`~prs3_post.core.toolpath.JointProgram`.

This is the input side of ``prs3-post verify`` and ``prs3-post preview``: it understands exactly
what the emitter (:mod:`prs3_post.emit.gcode`) writes, in any dialect, and rejects everything
else with an :class:`~prs3_post.core.errors.InputError` naming the file and the line, so that nothing
in a program is skipped silently.

Understood
----------
- The axis letters of the dialect (``[axes]``: stage X, Y and strokes T1, T2, T3); any other axis
  letter (A B C U V W X Y Z) is an error (``word 'Z' is not an axis of dialect linuxcnc (axes: X Y
  U V W)``). On a machine without a stage (``stage=False``) the stage letters are errors too.
- G0 G1 G4 G17 G21 G40 G49 G54 G61 G64 G80 G90 G93 G94; M0 M1 M2 M3 M4 M5 M6 M7 M8 M9 M30; F, S, T, P
  (with G4 or G64), N (first word), an ``O`` line, ``%`` lines, comments in the dialect's
  delimiters. Numbers are plain decimals (``-12.5``, ``.5``, ``5.``); spaces between and inside
  words are ignored and letters may be lower case, as LinuxCNC reads them.
- Modal state as LinuxCNC keeps it: G0/G1 stays active (Fanuc-style lines with axis words only),
  an axis keeps its value until a word changes it, G93/G94 is the feed mode.

Rules (LinuxCNC's, and the emitter's): every G1 runs under G93 with its own F > 0 (``F = 1 /
minutes``); F appears only on G1 lines; the first move sets every axis (the start position is
otherwise unknown); one code per modal group and no letter twice on a line; the program ends with
M2 or M30 and only comments, blank lines and a closing ``%`` follow. A file that is not UTF-8
text, has control bytes, or does not read as G-code words is refused as not G-code.

Parsing: bytes, comments and words are the shared lexer's (:mod:`prs3_post.core.lexer`; pygcode
is its reference in a differential test, no longer a step here). Lines of the emitter's own motion
shape (``N.. G0/G1 X.. Y.. <T1> <T2> <T3> F..``, upper case, no comment) are read a chunk at a time
(:func:`~prs3_post.core.lexer.lex_columns`) and replayed on the modal state in bulk; a chunk where
any rule would fail, and every other line, goes through the careful reader one line at a time,
which is the definition: the bulk step only ever takes lines it would read the same way.

Streaming: :class:`ProgramStream` reads a file in pieces and hands out its moves a chunk of lines at
a time, with the modal state and the last position carried across, so memory stays flat in the
program's length; :func:`load_program` reads it whole.

Every move keeps its 1-based line number (``JointProgram.source``), for the reports.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from prs3_post.core.errors import InputError, LexError
from prs3_post.core.input_files import iter_pieces, line_blocks, read_input
from prs3_post.core.lexer import (
    BYTE_ORDER_MARK,
    EMPTY,
    Word,
    code_name,
    decode,
    forward_fill,
    lex_column_block,
    lex_columns,
    lex_words,
    quote,
    split_comments,
)
from prs3_post.core.toolpath import Coolant, Event, EventKind, JointProgram, MoveKind, join_programs
from prs3_post.core.types import BoolArray, FloatArray, IntArray, Progress
from prs3_post.kinematics.protocol import Kinematics, joint_letters
from prs3_post.kinematics.prs3.kinematics import Prs3Kinematics
from prs3_post.machine.loading import AXIS_LETTERS, Dialect

__all__ = ["ALLOWED_G", "ALLOWED_M", "CHUNK_LINES", "ProgramFile", "ProgramStream", "load_program", "read_program"]

#: G-codes the emitter writes, with their modal group (one code per group and line).
ALLOWED_G: dict[int, str] = {
    0: "motion", 1: "motion", 80: "motion", 4: "dwell", 17: "plane", 21: "units", 40: "cutter compensation",
    49: "tool length offset", 54: "coordinate system", 61: "path control", 64: "path control",
    90: "distance mode", 93: "feed mode", 94: "feed mode",
}
#: M-codes the emitter writes, with their modal group.
ALLOWED_M: dict[int, str] = {0: "stop", 1: "stop", 2: "stop", 30: "stop", 3: "spindle", 4: "spindle", 5: "spindle",
                             6: "tool change", 7: "coolant", 8: "coolant", 9: "coolant"}
#: Word letters other than axes: what each is for.
_OTHER_LETTERS = "GMNFSTPO"
#: mm, the largest axis value a program may give (a kilometre).
MAX_AXIS_MM = 1e6
#: Lines handed out per chunk by :class:`ProgramStream` (and read in bulk at a time).
CHUNK_LINES = 16384
#: Bytes read from the file at a time.
_PIECE_BYTES = 1 << 20


@dataclass(frozen=True, slots=True)
class ProgramFile:
    """A program read back from G-code.

    Attributes
    ----------
    path : str — as given (shown in messages)
    dialect : str — the dialect's name
    moves : JointProgram — one row per G0/G1 line: ``stage`` (N, 2) mm (zeros without a stage),
        ``strokes`` (N, 3) mm, ``inverse_time`` (N,) 1/min (the F of each G1, 0 for G0), ``source``
        (N,) the 1-based line number, and the events (spindle, coolant, tool change, dwell in s, stop)
    lines : tuple of str — the file's lines without line endings (``lines[n - 1]`` is line n)
    end_line : int — the line of M2 / M30
    blending_lines : tuple of int — lines that switch on G64 path blending (the control may round
        corners in joint space; the replay assumes exact stops, as G61 asks)
    """

    path: str
    dialect: str
    moves: JointProgram
    lines: tuple[str, ...]
    end_line: int
    blending_lines: tuple[int, ...]


def load_program(path: str, dialect: Dialect, *, stage: bool = True,
                 kinematics: Kinematics | None = None) -> ProgramFile:
    """Read a program file whole (see the module docstring for what is understood).

    Parameters
    ----------
    path : str
    dialect : Dialect — letters, comment delimiters, dwell unit and line length of the program
    stage : bool — the machine has an XY stage (False: stage words are errors, stage = 0)
    kinematics : Kinematics, optional — whose joints the program moves (None: the 3-PRS head's)

    Returns
    -------
    ProgramFile

    Raises
    ------
    InputError
        ``path: message`` for a file that cannot be read or is not text, ``path:line: message``
        for the first line that is not understood.
    """
    data = read_input(path, "a G-code program")
    return read_program(text_from_bytes(data, path), dialect, path=path, stage=stage, kinematics=kinematics)


def text_from_bytes(data: bytes, path: str) -> str:
    """The program text of a file's bytes (:func:`prs3_post.core.lexer.decode`, its errors naming ``path``).

    Raises
    ------
    InputError
        ``not a G-code program: ...`` with what was found.
    """
    try:
        return decode(data)
    except LexError as exc:
        raise InputError(str(exc), path=path) from exc


def text_from_bytes_at(data: bytes, path: str, offset: int) -> str:
    """:func:`text_from_bytes` of a piece of a file that starts at ``offset`` (a line start)."""
    try:
        return decode(data, offset=offset)
    except LexError as exc:
        raise InputError(str(exc), path=path) from exc


def _split_lines(text: str) -> tuple[list[str], list[bool]]:
    """Lines without their endings (a final line ending ends the last line) and which ended in CRLF."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()                                    # the final line ending
    if "\r" not in text:
        return lines, [False] * len(lines)
    crlf = [ln.endswith("\r") for ln in lines]
    lines = [ln[:-1] if cr else ln for ln, cr in zip(lines, crlf, strict=True)]
    return lines, crlf


def read_program(text: str, dialect: Dialect, *, path: str, stage: bool = True,
                 chunk_lines: int = CHUNK_LINES, kinematics: Kinematics | None = None) -> ProgramFile:
    """Read program text (see the module docstring); ``path`` is only used in messages.

    Raises
    ------
    InputError
    """
    reader = _Reader(dialect, path, stage, kinematics)
    lines, crlf = _split_lines(text)
    parts = []
    for first in range(0, len(lines), chunk_lines):
        reader.lines(first + 1, lines[first:first + chunk_lines], crlf[first:first + chunk_lines])
        parts.append(reader.take())
    reader.finish(len(lines))
    moves = join_programs(parts)
    return ProgramFile(path=path, dialect=dialect.name, moves=moves, lines=tuple(lines),
                       end_line=reader.end_line or 0, blending_lines=tuple(reader.blending))


def _rows(kind: list[int] | IntArray, joints: FloatArray, feed: list[float] | FloatArray,
          source: list[int] | IntArray, events: list[Event], width: int) -> JointProgram:
    joints = np.asarray(joints, dtype=np.float64).reshape(-1, width)
    return JointProgram(kind=np.asarray(kind, dtype=np.int64), stage=joints[:, :2], strokes=joints[:, 2:],
                        inverse_time=np.asarray(feed, dtype=np.float64), source=np.asarray(source, dtype=np.int64),
                        events=tuple(events))


class ProgramStream:
    """A program file read in chunks of lines, for a replay whose memory does not grow with the program.

    Iterate it for one :class:`~prs3_post.core.toolpath.JointProgram` per chunk with moves or events (events
    count rows from the chunk's start; ``source`` holds the file's line numbers); the modal state
    and the last position carry across chunks, so the chunks are exactly the rows :func:`load_program`
    reads, cut in pieces. After the iteration, ``end_line``, ``blending_lines`` and ``line_count`` are
    set. The whole file is checked for being text (empty, byte-order mark, control bytes, UTF-8)
    before its first line is read, as :func:`load_program` does.

    Raises (during the iteration)
    -----------------------------
    InputError
        As :func:`load_program`.
    """

    def __init__(self, path: str, dialect: Dialect, *, stage: bool = True, chunk_lines: int = CHUNK_LINES,
                 piece_bytes: int = _PIECE_BYTES, kinematics: Kinematics | None = None):
        self.path, self.dialect, self.stage, self.kinematics = path, dialect, stage, kinematics
        self.chunk_lines, self.piece_bytes = max(1, int(chunk_lines)), max(1, int(piece_bytes))
        self.end_line = 0
        self.blending_lines: tuple[int, ...] = ()
        self.line_count = 0
        self.checked_lines: int | None = None
        self.progress: Progress | None = None             # told the bytes read as the iteration reads them

    def _pieces(self, progress: Progress | None = None) -> Iterator[tuple[int, bytes]]:
        """(offset, bytes) pieces of the file, each ending at a line end (or the file's end)."""
        return iter_pieces(self.path, "a G-code program", self.piece_bytes, progress=progress)

    def check(self) -> int:
        """Check that the whole file is text, with :func:`~prs3_post.core.lexer.decode`'s errors in its
        order (iterating does it first, once); returns its number of lines (an upper bound on its moves).

        Raises
        ------
        InputError
        """
        if self.checked_lines is None:
            self.checked_lines = self._check_text()
        return self.checked_lines

    def _check_text(self) -> int:
        blank, mark, first_error, lines, ended = True, False, None, 0, True
        for offset, piece in self._pieces():
            lines += piece.count(b"\n")
            ended = piece.endswith(b"\n")
            blank = blank and not piece.strip()
            mark = mark or (offset == 0 and piece.startswith(b"\xef\xbb\xbf"))
            if first_error is None:
                try:
                    decode(piece, offset=offset)
                except LexError as exc:
                    first_error = exc
        for problem in ((EMPTY if blank else None), (BYTE_ORDER_MARK if mark else None)):
            if problem:
                raise InputError(problem, path=self.path)
        if first_error is not None:
            raise InputError(str(first_error), path=self.path) from first_error
        return lines + (0 if ended else 1)

    def __iter__(self) -> Iterator[JointProgram]:
        self.check()
        reader = _Reader(self.dialect, self.path, self.stage, self.kinematics)
        number = 1
        size = self.chunk_lines
        # bytes: lines of the regular shape are read undecoded; every block but the last holds `size` lines
        for at, block in line_blocks(self._pieces(self.progress), size):
            if block.count(b"\n") < size:                # the lines left at the end: read with the end below
                number += reader.block(number, block, at)
                continue
            reader.block(number, block, at)
            number += size
            if len(chunk := reader.take()) or chunk.events:
                yield chunk
        chunk = reader.take()
        reader.finish(number - 1)
        if len(chunk) or chunk.events:
            yield chunk
        self.end_line, self.blending_lines, self.line_count = reader.end_line or 0, tuple(reader.blending), number - 1


@dataclass(slots=True)
class _Block:
    """One line's words, sorted: what LinuxCNC executes for it."""

    seen: dict[str, str] = field(default_factory=dict)         # letter → word text (not G, M)
    g_codes: dict[str, int] = field(default_factory=dict)      # modal group → code
    m_codes: dict[str, int] = field(default_factory=dict)
    axes: dict[int, float] = field(default_factory=dict)       # axis index (X, Y, the joints) → value
    values: dict[str, float] = field(default_factory=dict)     # F S T P → value


class _Reader:
    """The modal state of LinuxCNC's interpreter, as far as prs3-post programs use it."""

    def __init__(self, dialect: Dialect, path: str, stage: bool, kinematics: Kinematics | None = None):
        self.dialect, self.path, self.stage = dialect, path, stage
        ax = dialect.axes
        given = Prs3Kinematics if kinematics is None else kinematics          # (no kinematics: the 3-PRS head's)
        self.letters = (ax.x, ax.y, *joint_letters(given.joint_names, given.default_letters, ax))
        self.names = ("stage X", "stage Y", *(f"actuator {name}" for name in given.joint_names))
        self.axis_index = {letter: i for i, letter in enumerate(self.letters)}
        self.axes_text = " ".join(self.letters if stage else self.letters[2:])
        self.bulk_letters = "NG" + "".join(self.letters) + "F"
        self.motion: int | None = None                # 0, 1 or None (after G80 / at start)
        self.inverse_time = False                      # G93 active
        self.spindle: float | None = None              # last S
        self.tool: int | None = None                   # last T
        self.position = np.full(len(self.letters), np.nan)
        if not stage:
            self.position[:2] = 0.0
        self.parts: list[JointProgram] = []            # rows since the last take(), in order
        self.kind: list[int] = []                      # rows of the careful reader, not yet in parts
        self.joints: list[FloatArray] = []
        self.feed: list[float] = []
        self.source: list[int] = []
        self.events: list[Event] = []                  # since the last take(), rows counted from there
        self.rows = 0                                  # rows since the last take()
        self.end_line: int | None = None
        self.percent = 0                               # % lines seen
        self.blending: list[int] = []
        self.code_seen = False
        self.number = 0

    def error(self, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.number)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        self.events.append(Event(before=self.rows, kind=kind, value=value, text=text))

    # ------------------------------------------------------------------ a chunk of lines
    def lines(self, first: int, lines: list[str], crlf: list[bool]) -> None:
        """Lines ``first``, ``first + 1``, ... (without endings; ``crlf``: each ended in CRLF).

        Runs of lines of the emitter's motion shape go to :meth:`bulk`; the others, and a run the
        bulk step refuses, to :meth:`line` one at a time.
        """
        if not lines:
            return
        values, fast = lex_columns(lines, self.bulk_letters)
        fast &= np.fromiter(map(len, lines), dtype=np.int64, count=len(lines)) < self.dialect.max_line_length
        self.runs(first, values, fast, lambda a, b: lines[a:b], lambda a, b: crlf[a:b])

    def block(self, first: int, data: bytes, offset: int) -> int:
        """Lines ``first``, ``first + 1``, ... as the file's bytes from ``offset`` on (whole lines; the last
        may end at the end of the file), as :meth:`lines` reads them decoded; returns their number.

        Runs of lines of the emitter's motion shape go to :meth:`bulk` without being decoded; the
        others are decoded (:func:`~prs3_post.core.lexer.decode`) and read by :meth:`line`. A
        piece with a CR goes to :meth:`lines` whole (its CRLF line ends count towards the lengths).
        """
        if b"\r" in data:
            lines, crlf = _split_lines(text_from_bytes_at(data, self.path, offset))
            self.lines(first, lines, crlf)
            return len(lines)
        values, fast, bounds = lex_column_block(data, self.bulk_letters)
        fast &= np.diff(bounds) - 1 < self.dialect.max_line_length      # ASCII where read: bytes are characters
        self.runs(first, values, fast, lambda a, b: _split_lines(text_from_bytes_at(
            data[bounds[a]:bounds[b]], self.path, offset + int(bounds[a])))[0], lambda a, b: [False] * (b - a))
        return len(fast)

    def runs(self, first: int, values: FloatArray, fast: BoolArray, text: Callable[[int, int], list[str]],
             crlf: Callable[[int, int], list[bool]]) -> None:
        """Lines ``first``... from :func:`~prs3_post.core.lexer.lex_columns` (``values``, ``fast``: read
        and short enough): runs of the motion shape to :meth:`bulk`, the others (and a run it refuses)
        to :meth:`line`, with the text of lines ``a:b`` from ``text(a, b)``, their CRLF flags from ``crlf``."""
        g = values[:, 1]
        fast &= np.isnan(g) | (g == 0.0) | (g == 1.0)
        some = values[:, 1].copy()                      # a G0/G1 or an axis word (not only N, nor blank): not all
        for column in range(2, values.shape[1]):         # NaN (column by column: a reduction along each row is slow)
            np.fmax(some, values[:, column], out=some)
        fast &= ~np.isnan(some)
        edges = np.flatnonzero(np.diff(fast.astype(np.int8))) + 1
        bounds = [0, *edges.tolist(), len(fast)]
        for a, b in itertools.pairwise(bounds):
            ended = self.end_line is not None or self.percent >= 2      # the careful reader says what is wrong
            if not (fast[a] and not ended and self.bulk(first + a, values[a:b])):
                for i, (line, cr) in enumerate(zip(text(a, b), crlf(a, b), strict=True)):
                    self.line(first + a + i, line, crlf=cr)

    def bulk(self, first: int, values: FloatArray) -> bool:
        """Lines ``first``... of the motion shape (``values`` (k, 5 + J): N, G, the axes X, Y and the J
        joints, F, NaN where absent), in bulk: True if done; False (state untouched) where any line would be an
        error."""
        width = len(self.letters)
        g, axes, feed = values[:, 1], values[:, 2:2 + width], values[:, 2 + width]
        start = -1.0 if self.motion is None else float(self.motion)
        motion = forward_fill(np.concatenate([[start], g]))[1:]
        has_f = ~np.isnan(feed)
        feeding = motion == 1.0
        position = forward_fill(np.vstack([self.position, axes]))[1:]
        if ((motion < 0).any() or (has_f & ~feeding).any() or not (feed[has_f] > 0).all()
                or (feeding.any() and (not self.inverse_time or (feeding & ~has_f).any()))
                or (not self.stage and not np.isnan(axes[:, :2]).all()) or np.isnan(position).any()):
            return False
        self.flush()
        k = len(values)
        self.parts.append(_rows(np.where(feeding, int(MoveKind.FEED), int(MoveKind.RAPID)), position,
                                np.where(feeding, feed, 0.0), np.arange(first, first + k), [], width))
        self.rows += k
        self.motion = int(motion[-1])
        self.position = position[-1].copy()
        self.code_seen = True
        self.number = first + k - 1
        return True

    def flush(self) -> None:
        """The careful reader's rows into ``parts`` (before a bulk run, or when taken)."""
        if self.kind:
            self.parts.append(_rows(self.kind, np.array(self.joints), self.feed, self.source, [], len(self.letters)))
            self.kind, self.joints, self.feed, self.source = [], [], [], []

    def take(self) -> JointProgram:
        """The rows and events since the last take (events count rows from the first of them)."""
        self.flush()
        parts, events = self.parts, self.events
        self.parts, self.events, self.rows = [], [], 0
        chunk = join_programs(parts)
        self.check_magnitudes(chunk)
        return JointProgram(kind=chunk.kind, stage=chunk.stage, strokes=chunk.strokes,
                            inverse_time=chunk.inverse_time, source=chunk.source, events=tuple(events))

    def check_magnitudes(self, chunk: JointProgram) -> None:
        """Every axis value within ±MAX_AXIS_MM: a far larger one is a typo, and the reports would print it
        digit by digit."""
        joints = np.column_stack([chunk.stage, chunk.strokes])      # (N, 2 + J) mm
        beyond = np.abs(joints) > MAX_AXIS_MM
        if beyond.any():
            row, column = np.argwhere(beyond)[0]
            raise InputError(f"{self.letters[column]} {joints[row, column]:.6g} mm is out of range (allowed: within "
                             f"±{MAX_AXIS_MM:g} mm)", path=self.path, line=int(chunk.source[row]))

    # ------------------------------------------------------------------ one line
    def line(self, number: int, line: str, *, crlf: bool = False) -> None:
        """One line without its ending; ``crlf``: it ended in a CR (``\\r\\n``), which LinuxCNC counts
        towards its line-length limit (the emitter allows one character less for CRLF, too)."""
        self.number = number
        if "\r" in line:                               # invisible in a message: say where, and what it means
            raise self.error(f"a CR character at column {line.index(chr(13)) + 1}, inside the line: LinuxCNC reads "
                             "LF or CRLF line ends (a file with CR-only line ends: save it with LF)")
        self.check_length(line, crlf)
        try:
            code, _ = split_comments(line, ((self.dialect.comments.open, self.dialect.comments.close),))
        except LexError as exc:
            raise self.error(str(exc)) from exc
        code = code.strip()
        if self.percent >= 2:
            if line.strip():
                raise self.error(f"text after the closing '%': {quote(line)} (LinuxCNC never reads it)")
            return
        if code == "%":
            self.percent_line()
            return
        if not code:
            return
        if self.end_line is not None:
            raise self.error(f"code after the program end (line {self.end_line}): {quote(code)} "
                             "(LinuxCNC never reads it)")
        self.code_seen = True
        self.words(self.lex(code))

    def check_length(self, line: str, crlf: bool) -> None:
        limit = self.dialect.max_line_length - (1 if crlf else 0)
        if len(line) > limit:
            ending = f" with a CRLF line ending (LinuxCNC counts the CR; {limit + 1} with LF)" if crlf else ""
            raise self.error(f"the line is {len(line)} characters, dialect {self.dialect.name} allows {limit}{ending}")

    def percent_line(self) -> None:
        """A ``%`` line: the opening one (first code), or the closing one (after the end)."""
        if self.percent == 0 and not self.code_seen:
            self.percent = 1                           # the opening %
            return
        if self.end_line is None:
            raise self.error("'%' before the program end (M2 or M30): only the first line and the lines "
                             "after the end may be '%'")
        self.percent = 2                               # the closing %: LinuxCNC reads no further

    def lex(self, code: str) -> tuple[Word, ...]:
        try:
            return lex_words(code)
        except LexError as exc:
            if exc.found[:1] in ("[", "#") or exc.found[1:].lstrip("+-")[:1] in ("[", "#"):
                raise self.error(f"not G-code: {exc}") from exc
            raise self.error(f"not G-code: cannot read {quote(code)} as words "
                             "(a letter and a number each, e.g. G1 X-1.5)") from exc

    # ------------------------------------------------------------------ one line's words
    def words(self, words: tuple[Word, ...]) -> None:
        """Check and execute one line's words: which words, then what they mean, in LinuxCNC's order."""
        if words[0][0] == "O":
            if len(words) > 1:
                raise self.error("an O (program number) word must be alone on its line")
            return
        block = _Block()
        for position, word in enumerate(words):
            self.check_letter(word[0])
            if word[0] in "GM":
                self.add_code(block, word)
            else:
                self.add_word(block, position, word)
        motion, moves = self.motion_of(block)
        self.check_feed(block, motion, moves)
        self.set_spindle_and_tool(block)
        self.execute_events(block)
        if block.g_codes.get("path control") == 64:
            self.blending.append(self.number)
        self.motion = motion
        if moves:
            assert motion is not None  # checked in motion_of: a move needs a motion mode
            self.move(motion, block.axes, block.values.get("F", 0.0))
        stop = block.m_codes.get("stop")
        if stop in (0, 1):
            self.event(EventKind.STOP if stop == 0 else EventKind.OPTIONAL_STOP)
        elif stop in (2, 30):
            self.end_line = self.number

    def check_letter(self, letter: str) -> None:
        """The letter is an axis of the dialect (and of the machine), or one of G M N F S T P O."""
        if letter in AXIS_LETTERS:
            if letter not in self.axis_index or (not self.stage and self.axis_index[letter] < 2):
                if letter in self.axis_index:
                    raise self.error(f"word '{letter}' is the stage {'XY'[self.axis_index[letter]]} axis of "
                                     f"dialect {self.dialect.name}, and the machine has no stage "
                                     f"(axes: {self.axes_text})")
                raise self.error(f"word '{letter}' is not an axis of dialect {self.dialect.name} "
                                 f"(axes: {self.axes_text})")
        elif letter not in _OTHER_LETTERS:
            raise self.error(f"word '{letter}' is not used in prs3-post programs (words read: G M N F S T P "
                             f"and the axes {self.axes_text})")

    def add_code(self, block: _Block, word: Word) -> None:
        """A G or M code: one the emitter writes, one per modal group."""
        letter, value, _ = word
        table = ALLOWED_G if letter == "G" else ALLOWED_M
        name = code_name(letter, value)
        if value != int(value) or int(value) not in table:
            allowed = " ".join(f"{letter}{c}" for c in sorted(table))
            raise self.error(f"{name} is not a code prs3-post programs use (allowed: {allowed})")
        group = table[int(value)]
        groups = block.g_codes if letter == "G" else block.m_codes
        if group in groups:
            other = code_name(letter, groups[group])
            raise self.error(f"{other} and {name} are in the same modal group ({group}): one per line")
        groups[group] = int(value)

    def add_word(self, block: _Block, position: int, word: Word) -> None:
        """Any other word: once per line; N first; O alone."""
        letter, value, text = word
        if letter in block.seen:
            raise self.error(f"word '{letter}' appears twice ({block.seen[letter]} and {text})")
        block.seen[letter] = text
        if letter == "N":
            if position != 0:
                raise self.error(f"the block number {text} must be the first word of the line")
        elif letter == "O":
            raise self.error("an O (program number) word must be alone on its line")
        elif letter in AXIS_LETTERS:
            block.axes[self.axis_index[letter]] = value
        else:
            block.values[letter] = value

    def motion_of(self, block: _Block) -> tuple[int | None, bool]:
        """The feed mode (G93/G94 first), the motion mode after this line, and whether it moves."""
        if "feed mode" in block.g_codes:
            self.inverse_time = block.g_codes["feed mode"] == 93
        motion = block.g_codes.get("motion", self.motion)
        if motion == 80:
            motion = None
        moves = bool(block.axes) or ("motion" in block.g_codes and block.g_codes["motion"] != 80)
        if block.axes and motion is None:
            raise self.error("axis words without a motion mode (G0 or G1)")
        if block.axes and "dwell" in block.g_codes:
            raise self.error("G4 (dwell) with axis words: the dwell and the move need their own lines")
        return motion, moves

    def check_feed(self, block: _Block, motion: int | None, moves: bool) -> None:
        """F only on G1 moves, > 0; every G1 under G93 with its F."""
        values = block.values
        if "F" in values:
            if not (moves and motion == 1):
                raise self.error("F word on a line without a G1 move (prs3-post programs carry F only on G1 lines)")
            if not values["F"] > 0:
                raise self.error(f"{block.seen['F']}: the feed must be > 0 (LinuxCNC raises F0 to 0.1 /min)")
        if moves and motion == 1:
            if not self.inverse_time:
                raise self.error("G1 under G94 (units per minute): prs3-post programs feed in G93 inverse time, "
                                 "where F = 1 / minutes of the move")
            if "F" not in values:
                raise self.error("G1 without F under G93 (inverse time needs an F word on every G1)")

    def set_spindle_and_tool(self, block: _Block) -> None:
        """S (≥ 0) and T (whole, ≥ 0) are remembered; P needs G4 or G64."""
        values, seen = block.values, block.seen
        if "S" in values:
            if values["S"] < 0:
                raise self.error(f"{seen['S']}: the spindle speed must be ≥ 0 rpm")
            self.spindle = values["S"]
        if "T" in values:
            if values["T"] < 0 or values["T"] != int(values["T"]):
                raise self.error(f"{seen['T']}: the tool number must be a whole number ≥ 0")
            self.tool = int(values["T"])
        if "P" in values and "dwell" not in block.g_codes and block.g_codes.get("path control") != 64:
            raise self.error(f"word 'P' ({seen['P']}) needs G4 (dwell) or G64 on the same line")

    def execute_events(self, block: _Block) -> None:
        """Tool change, spindle, coolant and dwell, in LinuxCNC's order of execution."""
        m_codes = block.m_codes
        if m_codes.get("tool change") == 6:
            if self.tool is None:
                raise self.error("M6 (tool change) without a tool number T")
            self.event(EventKind.TOOL_CHANGE, float(self.tool), f"T{self.tool}")
        spindle = m_codes.get("spindle")
        if spindle in (3, 4):
            if self.spindle is None or not self.spindle > 0:
                what = "M3 (spindle on)" if spindle == 3 else "M4 (spindle on, counter-clockwise)"
                raise self.error(f"{what} without a spindle speed S > 0")
            self.event(EventKind.SPINDLE_ON if spindle == 3 else EventKind.SPINDLE_ON_CCW, self.spindle)
        elif spindle == 5:
            self.event(EventKind.SPINDLE_OFF)
        coolant = m_codes.get("coolant")
        if coolant in (7, 8):
            self.event(EventKind.COOLANT_ON, 0.0, Coolant.from_m_code(coolant).value)
        elif coolant == 9:
            self.event(EventKind.COOLANT_OFF)
        if "dwell" in block.g_codes:
            p = block.values.get("P")
            if p is None or p < 0:
                raise self.error("G4 (dwell) needs a P word ≥ 0 "
                                 f"({'seconds' if self.dialect.dwell_unit == 's' else 'milliseconds'})")
            self.event(EventKind.DWELL, p / 1000.0 if self.dialect.dwell_unit == "ms" else p)

    def move(self, motion: int, axes: dict[int, float], feed: float) -> None:
        for index, value in axes.items():
            self.position[index] = value
        missing = [i for i in range(len(self.letters)) if np.isnan(self.position[i])]
        if missing:
            names = ", ".join(f"{self.letters[i]} ({self.names[i]})" for i in missing)
            raise self.error(f"the first move must set every axis ({self.axes_text}); missing: {names}")
        self.kind.append(int(MoveKind.FEED if motion == 1 else MoveKind.RAPID))
        self.joints.append(self.position.copy())
        self.feed.append(feed)
        self.source.append(self.number)
        self.rows += 1

    # ------------------------------------------------------------------ the end
    def finish(self, line_count: int) -> None:
        """The program ended (M2/M30) and had code; else the error."""
        if self.end_line is None:
            if not self.code_seen:
                raise InputError("not a G-code program: no code, only comments and blank lines", path=self.path)
            raise InputError(f"the program never ends: no M2 or M30 in its {line_count} lines (truncated file?)",
                             path=self.path)

