"""Read 3+2 CAM G-code (a tilted plane by ``G68.2``, or a 3-axis program on a work plane) into a Toolpath.

The result mirrors :mod:`prs3_post.readers.cl.reader`: a :class:`~prs3_post.core.toolpath.Toolpath` in the
PART frame, in mm, with the tool axis (unit, tip → spindle) of every row, plus an accounting of
every line (:class:`GcodeCounts`), streamed in chunks of lines (:class:`GcodeStream`). Every row and
event keeps its 1-based source line. Words are read by the shared lexer
(:mod:`prs3_post.core.lexer`), arcs expanded by :func:`prs3_post.toolpaths.arcs.arc_points_3d`, drilling
cycles by :func:`prs3_post.toolpaths.cycles.drill_rows`.

Frames
------
Program coordinates are in the *work plane* the caller gives (:class:`~prs3_post.part.workplane.WorkPlane`;
the part frame when none): ``p_part = origin + rotation @ p_program``, and the tool axis is the
plane's normal. ``G68.2`` defines a tilted plane inside it:

- ``G68.2 X Y Z I J K`` (``P0``, the default): origin X Y Z (absolute, even under G91) and Euler
  angles Z-X'-Z'' in degrees, ``R = Rz(I)·Rx(J)·Rz(K)`` (FANUC Series 30i Descriptions B-63942EN/02
  §5.44; LinuxCNC's G68.2 remap reads P0 the same way, its default order ``Q313``, the only one
  read here; :func:`~prs3_post.part.workplane.euler_zxz_deg`): ``I0 J30 K0`` tilts the plane 30° about
  X, normal (0, −sin 30°, cos 30°).
- ``G68.2 P3 Q1 X Y Z I J K`` then ``G68.2 P3 Q2 I J K`` on the next line (FANUC's two-vector form):
  origin and x direction, then the normal (z). The two must be 85° to 95° apart (FANUC); x is then
  made exactly perpendicular.
- ``G53.1`` turns the tool axis to the tilted plane's normal; it must come after ``G68.2`` and
  before any move in the plane (before it the tool axis would still be the outer plane's, which a
  program written for the tilted plane never means). ``G69`` cancels the tilted plane: the
  coordinates and the tool axis are the outer plane's again. A second ``G68.2`` needs ``G69`` first.

When the plane changes, the current position is kept (the same point, seen in the new plane).

Words and codes
---------------
- ``G0 G1`` (X Y Z), ``G2 G3`` in ``G17 G18 G19`` (I J K centre offsets from the start, or R: the
  shorter arc, R < 0 the longer; full circles with I J K; helices with a move along the plane's
  normal; P turns): expanded within ``tolerance``; the end must lie on the circle through the start
  within ``circle_tolerance``. G2 is clockwise seen from the positive end of the plane's normal
  axis (Z, Y, X for G17, G18, G19).
- ``G81 G82 G83 G73`` with X Y (the hole), Z (bottom), R (retract plane), Q (G83/G73: peck), P
  (G82: dwell, s); Z R Q P stay until the cycle ends; ``G98`` (back to the level where the cycle
  started, or R if higher) / ``G99`` (back to R); ``G80`` or any other motion code ends the cycle.
  Under G91, R is measured from the Z where the cycle starts and Z from R, as LinuxCNC does. The
  holes are drilled along the plane's normal (in a tilted plane: along the tilted normal).
  Pecks retract 0.254 mm (0.010 inch, LinuxCNC's G83/G73 ``delta``) above the previous depth.
  Cycles are read in G17 only: the hole goes along the plane's Z, the tool axis.
- ``G20 G21`` (inch, mm), ``G90 G91``, ``G93 G94`` (under G93 every feed move needs its own F,
  1/minute), ``F S T``, ``M6`` (T), ``M3 M4 M5``, ``M7 M8 M9``, ``M0 M1``, ``M2 M30`` (only comments,
  blank lines and ``%`` may follow), ``G4 P`` (dwell, s), comments (``(...)`` and ``;``, kept as
  COMMENT events), ``N`` (first word), ``%`` lines, ``O`` words alone on their line.
- Codes that only state what the reader assumes anyway: ``G40`` (no cutter compensation), ``G43 H``
  / ``G49`` (the coordinates are read as the tool tip either way: the IK uses the machine's tool
  length), ``G54`` (the program's coordinates are the work plane's), ``G94``, ``G91.1`` (arc
  centres I J K relative to the start: the only way they are read; ``G90.1`` is refused).

Anything else is an error naming the file and line and what would be valid: another word or code,
an ``E`` word (``1e-05`` reads as ``1`` then ``E-05``), a number that is not a plain decimal
(``nan``), an expression or parameter (``[``, ``#``), a word twice on a line, two codes of one group.
A program with rotary words (A, B, C: a 5-axis program) is refused before anything else is read,
naming the first such line.

Before the position is fully known (the machine's start is not in the program), rapids that give
only some axes (``G0 Z50`` then ``G0 X0 Y0``) are merged into one rapid to the first point whose
three coordinates are known (counted in :attr:`GcodeCounts.start_rapids`); a feed move, an arc or a
cycle needs the full position.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import re
from array import array
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, overload

import numpy as np

from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE, MAX_SPINDLE_RPM, MM_PER_INCH
from prs3_post.core.errors import InputError, LexError
from prs3_post.core.input_files import iter_pieces, line_blocks
from prs3_post.core.lexer import (
    BYTE_ORDER_MARK,
    EMPTY,
    LINE_COMMENT,
    LINE_OTHER,
    LINE_READ,
    Word,
    code_name,
    decode,
    forward_fill,
    lex_block_lines,
    lex_columns,
    lex_words,
    quote,
    split_comments,
)
from prs3_post.core.toolpath import Coolant, Event, EventKind, MoveKind, Toolpath
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.part.workplane import WorkPlane, euler_zxz_deg
from prs3_post.readers.cl.reader import MAX_FEED_MM_MIN, MAX_RECORD_CHARS, MIN_FEED_MM_MIN, join_toolpaths
from prs3_post.readers.protocol import SourceNotes, StreamDefaults
from prs3_post.toolpaths.arcs import MAX_ARC_SEGMENTS, arc_points_3d, arc_segment_count, arc_sweep
from prs3_post.toolpaths.cycles import MAX_PECKS, DrillCycle, Pecking, drill_rows, peck_count

if TYPE_CHECKING:
    from prs3_post.core import native

__all__ = [
    "CHUNK_LINES", "PECK_GAP_MM", "GcodeCounts", "GcodeCycle", "GcodeFile", "GcodePlane", "GcodeStream",
    "parse_gcode", "read_gcode",
]

#: Lines read per chunk by :class:`GcodeStream`.
CHUNK_LINES = 10_000
_PIECE_BYTES = 1 << 20
#: mm, how far above the previous depth a peck's rapid stops (G83), or how far G73 lifts: LinuxCNC's
#: ``delta`` of 0.010 inch.
PECK_GAP_MM = 0.254
#: FANUC's G68.2 P3: the x direction and the normal must be 85° to 95° apart.
_P3_MAX_COSINE = math.cos(math.radians(85.0))
_RAPID, _FEED = int(MoveKind.RAPID), int(MoveKind.FEED)

# G codes by modal group (the value as a float: G68.2 is 68.2)
_G_GROUPS: dict[float, str] = {
    0: "motion", 1: "motion", 2: "motion", 3: "motion", 80: "motion", 81: "motion", 82: "motion",
    83: "motion", 73: "motion", 4: "dwell", 17: "plane", 18: "plane", 19: "plane", 20: "units", 21: "units",
    90: "distance", 91: "distance", 93: "feed mode", 94: "feed mode", 98: "return", 99: "return",
    68.2: "tilt", 69: "tilt", 53.1: "tilt", 40: "compensation", 43: "length offset", 49: "length offset",
    54: "coordinate system", 91.1: "arc distance",
}
_M_GROUPS: dict[float, str] = {
    0: "stop", 1: "stop", 2: "stop", 30: "stop", 3: "spindle", 4: "spindle", 5: "spindle", 6: "tool change",
    7: "coolant", 8: "coolant", 9: "coolant",
}
_CODES_READ = ("G0 G1 G2 G3 G4 G17 G18 G19 G20 G21 G40 G43 G49 G53.1 G54 G68.2 G69 G73 G80 G81 G82 G83 G90 "
               "G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 M9 M30")
#: Why some codes CAM posts write are not read (the message says it before the codes that are).
_HINTS = {
    **dict.fromkeys(("G28", "G30"), "a return to the machine's reference point is no position on the part; "
                    "leave it out (the converted program starts and ends at the machine's safe position)"),
    "G53": "machine coordinates are no position on the part",
    **dict.fromkeys(("G43.4", "G43.5", "G234", "M428"), "tool centre point control belongs to 5-axis programs"),
    **dict.fromkeys(("G41", "G42"), "cutter compensation: have the CAM system write the tool centre path"),
    **dict.fromkeys(("G10", "G52", "G92"), "an offset set by the program; put the coordinates in the work plane"),
    "G95": "feed per revolution: have the CAM system write a feed per minute (G94)",
    "G90.1": "absolute arc centres: have the CAM system write I J K relative to the start (G91.1)",
}
_VALUE_LETTERS = "XYZIJKRPQFSTH"
_WORDS_READ = "G M N X Y Z I J K R P Q F S T H; O alone on its line"
_CYCLES = {81.0: Pecking.NONE, 82.0: Pecking.NONE, 83.0: Pecking.FULL_RETRACT, 73.0: Pecking.CHIP_BREAK}
#: The letters of the bulk path, in the order a regular motion line writes them.
_BULK_LETTERS = "NGXYZF"
#: A blank line, or one with only comments (closed, not nested), which the bulk path passes as events.
_QUIET = re.compile(r"[ \t]*(?:\([^()]*\)[ \t]*)*(?:;.*)?")
#: A line that is one comment in parentheses, nothing else: its text (what split_comments reads there).
_ONE_COMMENT = re.compile(r"\(([^()]*)\)")
#: A rotary word (A, B, C and a number) somewhere in a line: a 5-axis program (checked on the code
#: without comments).
_ROTARY = re.compile(r"(?<![A-Za-z_<\[#])([ABCabc])[ \t]*(-?[ \t]*[0-9.][0-9. \t]*)")
_ROTARY_HINT = re.compile(r"[ABCabc][ \t]*-?[ \t]*[0-9.]")
# the plane of G17, G18, G19: (first, second, normal) axis indexes, right-handed (first × second = normal)
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
_AXES = "XYZ"
_OFFSETS = "IJK"


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class GcodePlane:
    """A tilted plane a ``G68.2`` defined.

    Attributes
    ----------
    line : int — the G68.2 line (the ``Q2`` line of the two-vector form)
    words : str — the G68.2 words as written (both lines of the two-vector form, joined by ``; ``)
    plane : WorkPlane — the tilted plane in PART coordinates (mm; the caller's work plane applied)
    """

    line: int
    words: str
    plane: WorkPlane


@dataclass(frozen=True, slots=True)
class GcodeCycle:
    """A canned-cycle line (``G81``/``G82``/``G83``/``G73``) and the holes drilled under it.

    Attributes
    ----------
    line : int — the line with the cycle's G code
    code : str — ``G81`` …
    holes : int — holes drilled by this line and the lines that repeat it (axis words only)
    """

    line: int
    code: str
    holes: int


@dataclass(frozen=True, slots=True)
class GcodeCounts:
    """What the program held, line by line (field names as :class:`~prs3_post.readers.cl.reader.ClCounts`).

    Attributes
    ----------
    records : int — lines with code (not blank, not only a comment, not ``%``; ``O`` lines included)
    lines : int — lines in the file: ``records + comment_lines + blank_lines`` + the ``%`` lines
    moves : int — G0/G1 lines that became one row each
    start_rapids : int — rapids merged into the first fully known position (module docstring)
    arcs : int — G2/G3 moves expanded
    arc_segments : int — rows the arcs became
    cycles : int — canned-cycle lines (with G81/G82/G83/G73)
    cycle_holes : int — holes drilled
    cycle_rows : int — rows the holes became
    planes : int — G68.2 planes defined
    comments : int — comments (each one an event)
    comment_lines : int — lines with comments and no code
    blank_lines : int — empty lines and lines of spaces
    skipped : tuple of (str, int) — lines read but without anything to do: ``%`` and ``O`` lines
    by_word : tuple of (str, int) — every G and M code as written (``G1``, ``M3``), sorted
    rows : int — rows of the toolpath
    """

    records: int
    lines: int
    moves: int
    start_rapids: int
    arcs: int
    arc_segments: int
    cycles: int
    cycle_holes: int
    cycle_rows: int
    planes: int
    comments: int
    comment_lines: int
    blank_lines: int
    skipped: tuple[tuple[str, int], ...]
    by_word: tuple[tuple[str, int], ...]
    rows: int


@dataclass(frozen=True, slots=True)
class GcodeFile:
    """A 3+2 G-code program read into a part-frame toolpath.

    Attributes
    ----------
    path : str — as given
    units : str — ``mm`` or ``inch``: the program's length unit at its first move (G20/G21;
        everything here is converted to mm); ``mm`` when it has no move
    toolpath : Toolpath — PART frame, mm; ``source`` is the 1-based line of each row
    counts : GcodeCounts
    work_plane : WorkPlane — the plane the program's coordinates are in (outside any G68.2)
    planes : tuple of GcodePlane — one per G68.2
    cycles : tuple of GcodeCycle
    end_lines : tuple of int — the line of M2/M30 (empty when the program has none)
    """

    path: str
    units: str
    toolpath: Toolpath
    counts: GcodeCounts
    work_plane: WorkPlane
    planes: tuple[GcodePlane, ...] = ()
    cycles: tuple[GcodeCycle, ...] = ()
    end_lines: tuple[int, ...] = field(default=())


# --------------------------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------------------------
def read_gcode(path: str, *, tolerance: float, work_plane: WorkPlane | None = None,
               circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE) -> GcodeFile:
    """Read a whole 3+2 G-code file (see the module docstring for what is understood).

    Parameters
    ----------
    path : str — shown unchanged in messages
    tolerance : float — mm, > 0, chordal tolerance of the expanded arcs
    work_plane : WorkPlane or None — where the program's X, Y, Z are in the part (None: the part frame)
    circle_tolerance : float — mm, how far an arc's end may be from the circle through its start

    Returns
    -------
    GcodeFile

    Raises
    ------
    InputError
        ``path:line: message`` naming what was found and what would be valid.
    """
    return GcodeStream(path, tolerance=tolerance, work_plane=work_plane, circle_tolerance=circle_tolerance).whole()


def parse_gcode(text: str, *, path: str, tolerance: float, work_plane: WorkPlane | None = None,
                circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE, chunk_lines: int = CHUNK_LINES) -> GcodeFile:
    """Read G-code text; ``path`` is only used in messages. Parameters as :func:`read_gcode`."""
    return GcodeStream(path, tolerance=tolerance, work_plane=work_plane, circle_tolerance=circle_tolerance,
                       chunk_lines=chunk_lines, text=text).whole()


class GcodeStream(StreamDefaults):
    """A G-code file read in chunks of lines, for a conversion whose memory does not grow with the file.

    Iterate it for one :class:`~prs3_post.core.toolpath.Toolpath` (part frame, mm) per chunk of
    ``chunk_lines`` lines that has rows or events (events count rows from the chunk's start;
    ``source`` holds the file's line numbers). The modal state and the position carry across
    chunks, so the chunks are exactly the rows of :func:`read_gcode`, cut in pieces. Before the
    first chunk the whole file is read once, cheaply, to check that it is text and has no rotary
    words. After the iteration :attr:`summary` holds everything else (:class:`GcodeFile` with an
    empty toolpath). ``text`` reads that text instead of the file (``path`` then only names it).

    Raises (during the iteration)
    -----------------------------
    InputError
        As :func:`read_gcode`.
    """

    def __init__(self, path: str, *, tolerance: float, work_plane: WorkPlane | None = None,
                 circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE, chunk_lines: int = CHUNK_LINES,
                 piece_bytes: int = _PIECE_BYTES, text: str | None = None):
        if not (math.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"GcodeStream: tolerance must be > 0 mm, got {tolerance!r}")
        if not (math.isfinite(circle_tolerance) and circle_tolerance > 0):
            raise ValueError(f"GcodeStream: circle_tolerance must be > 0 mm, got {circle_tolerance!r}")
        self.path, self.tolerance, self.circle_tolerance = path, tolerance, circle_tolerance
        self.work_plane_given = work_plane                # the program's header states it when given
        self.work_plane = work_plane if work_plane is not None else WorkPlane.identity()
        self.chunk_lines, self.piece_bytes = max(1, int(chunk_lines)), max(1, int(piece_bytes))
        self._text = text
        self.summary: GcodeFile | None = None
        self.sha256: str | None = None                 # of the bytes read, once read (the header's)

    def _check(self) -> None:
        """The whole file: text (empty, byte-order mark, control bytes, UTF-8, in that order) and no
        rotary word (the first one's line is named); the file's bytes read once, each piece checked by
        :meth:`_check_piece`."""
        if self._text is not None:
            try:
                text = decode(self._text.encode("utf-8"))
            except LexError as exc:
                raise InputError(str(exc), path=self.path) from exc
            self._scan(text, 1)
            return
        blank, problem, first = True, None, 1
        for offset, piece in iter_pieces(self.path, "a G-code program", self.piece_bytes):
            if offset == 0 and piece.startswith(b"\xef\xbb\xbf"):   # (a file with a mark is not blank)
                raise InputError(BYTE_ORDER_MARK, path=self.path)
            blank = blank and not piece.strip()
            if problem is None:
                try:
                    first += self._check_piece(piece, offset, first)
                except LexError as exc:                  # reported unless the file is blank after all
                    problem = exc
            if problem is not None and not blank:
                break
        if blank:
            raise InputError(EMPTY, path=self.path)
        if problem is not None:
            raise InputError(str(problem), path=self.path) from problem

    def _check_piece(self, piece: bytes, offset: int, first: int) -> int:
        """A piece of the file from ``offset`` (a line start), whose first line is line ``first``:
        checked as :func:`~prs3_post.core.lexer.decode` checks it, then :meth:`_scan`-ned; returns
        its LFs. Bytes that are plain ASCII and have no rotary hint are not decoded, nor scanned by a
        pattern (one pass in C where it was built, :func:`_scan_bytes`)."""
        control, high, lines, rotary = _scan_bytes(piece)
        if control >= 0 or high:
            self._scan(decode(piece, offset=offset), first)     # raises LexError
        elif rotary >= 0:
            self._scan(piece.decode("ascii"), first)
        return lines

    def _scan(self, text: str, first: int) -> None:
        """Refuse what no line of the file may have (here: a rotary word) in a piece whose first line is
        line ``first`` (a hook: the 5-axis reader refuses expressions and parameters instead)."""
        if _rotary_hint(text):
            for number, line in enumerate(text.split("\n"), start=first):
                if _ROTARY_HINT.search(line):
                    _refuse_rotary(line, number, self.path)

    def _reader(self) -> _Reader:
        """The interpreter of the lines (a hook: the 5-axis reader, ``readers.fivex.reader``, gives its own)."""
        return _Reader(self.path, self.work_plane, self.tolerance, self.circle_tolerance)

    def _pieces(self) -> Iterator[tuple[int, bytes]]:
        """The file's bytes in ``(offset, bytes)`` pieces that end at line ends (``text``: its UTF-8 bytes);
        once through, :attr:`sha256` is theirs."""
        digest = hashlib.sha256()
        if self._text is not None:
            data = self._text.encode("utf-8")
            digest.update(data)
            yield 0, data
        else:
            yield from iter_pieces(self.path, "a G-code program", self.piece_bytes, digest)
        self.sha256 = digest.hexdigest()

    def __iter__(self) -> Iterator[Toolpath]:
        self._check()                                   # the whole text checked: its bytes are read below
        reader = self._reader()
        number = 1
        for offset, block in line_blocks(self._pieces(), self.chunk_lines):
            number += reader.read_block(number, block, offset)
            chunk = reader.take()
            if len(chunk) or chunk.events:
                yield chunk
        reader.close(number - 1)
        self.summary = reader.summary()

    def whole(self) -> GcodeFile:
        """All chunks joined: the whole file's :class:`GcodeFile`."""
        chunks = list(self)
        assert self.summary is not None  # set by the iteration
        s = self.summary
        return GcodeFile(path=s.path, units=s.units, toolpath=join_toolpaths(chunks), counts=s.counts,
                         work_plane=s.work_plane, planes=s.planes, cycles=s.cycles, end_lines=s.end_lines)

    def notes(self) -> SourceNotes:
        """The work plane given, for the program's header."""
        return SourceNotes(work_plane=self.work_plane_given)


#: Bytes of :data:`_ROTARY_HINT`: what may follow a letter in a rotary word.
_ROTARY_NEXT = np.zeros(256, dtype=bool)
_ROTARY_NEXT[list(b" \t-.0123456789")] = True
_ROTARY_HINT_BYTES = re.compile(_ROTARY_HINT.pattern.encode("ascii"))


def _rotary_hint(text: str) -> bool:
    """``_ROTARY_HINT.search(text) is not None``, in bulk (:func:`_rotary_at`)."""
    return _rotary_at(text.encode("utf-8")) >= 0


def _rotary_at(data: bytes) -> int:
    """Where ``_ROTARY_HINT`` first matches in ``data`` (bytes of UTF-8 text), or -1: only the letters
    followed by a byte that can continue a rotary word (a letter in a comment's word, ``pass``, is
    followed by another letter) are tried with the pattern."""
    data += b"\n"
    codes = np.frombuffer(data, dtype=np.uint8)
    lower = codes | np.uint8(0x20)                      # A B C a b c: a b c (and no other byte)
    lower -= np.uint8(ord("a"))
    letters = np.flatnonzero(lower < 3)
    maybe = letters[_ROTARY_NEXT[codes[letters + 1]]].tolist()
    return next((at for at in maybe if _ROTARY_HINT_BYTES.match(data, at) is not None), -1)


def _scan_bytes(data: bytes) -> tuple[int, bool, int, int]:
    """(the offset of the first control byte :func:`~prs3_post.core.lexer.decode` refuses or -1, a
    byte not ASCII, the LFs, :func:`_rotary_at`): csrc/lex.c's one pass where it was built, else numpy."""
    from prs3_post.core import native  # ctypes: loaded only where a file is read

    scanned = native.scan_text(data)
    return _scan_bytes_numpy(data) if scanned is None else scanned


def _scan_bytes_numpy(data: bytes) -> tuple[int, bool, int, int]:
    """:func:`_scan_bytes` with numpy (the reference of csrc/lex.c's prs3_scan_text)."""
    codes = np.frombuffer(data, dtype=np.uint8)
    control = np.flatnonzero(((codes < 32) & (codes != 9) & (codes != 10) & (codes != 13)) | (codes == 127))
    return (int(control[0]) if len(control) else -1, bool((codes >= 128).any()), data.count(b"\n"),
            _rotary_at(data))


def _refuse_rotary(line: str, number: int, path: str) -> None:
    """Raise the 5-axis refusal if ``line``'s code (without comments) has a rotary word."""
    try:
        code, _ = split_comments(line)
    except LexError:
        return                                           # the careful reader names what is wrong there
    match = _ROTARY.search(code)
    if match is None:
        return
    word = (match[1] + match[2]).upper().replace(" ", "").replace("\t", "")
    raise InputError(f"5-axis program: rotary word '{word}' (A, B and C words turn rotary axes); the 3+2 reader "
                     "reads programs whose tool axis is set by G68.2/G53.1 or by the work plane, so it refuses this "
                     "program rather than misread it", path=path, line=number)


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


# --------------------------------------------------------------------------------------------
# Interpretation
# --------------------------------------------------------------------------------------------
@dataclass(slots=True)
class _Block:
    """One line's words, sorted by kind (value: as written, text: for messages)."""

    g: dict[str, tuple[float, str]] = field(default_factory=dict)      # group → (code value, text)
    m: dict[str, tuple[float, str]] = field(default_factory=dict)
    values: dict[str, tuple[float, str]] = field(default_factory=dict)  # letter → (value, text)
    used: set[str] = field(default_factory=set)

    def take(self, letter: str) -> float | None:
        """The value of ``letter``'s word (None without one), marked as used."""
        word = self.values.get(letter)
        if word is None:
            return None
        self.used.add(letter)
        return word[0]


@dataclass(slots=True)
class _Cycle:
    """The active canned cycle: its code, sticky words (program units as written) and where it began."""

    code: float
    line: int
    initial_z: float                  # mm, plane coordinates: the level where the cycle began (G98)
    fresh: bool = True                # after G80 or another motion code (not another cycle code): the
                                      # first hole starts by going up to R if below it
    z: float | None = None            # the sticky words, as written
    r: float | None = None
    q: float | None = None
    p: float | None = None
    holes: int = 0


@dataclass(slots=True)
class _PendingP3:
    line: int
    text: str
    origin: FloatArray                # mm, outer plane
    x_direction: FloatArray


class _Reader:
    """The modal state of a program as the lines go by; rows in the coordinates of their plane (mm)."""

    def __init__(self, path: str, work_plane: WorkPlane, tolerance: float, circle_tolerance: float):
        self.path, self.tolerance, self.circle_tolerance = path, tolerance, circle_tolerance
        # what :meth:`sort` accepts (the 5-axis reader, a subclass, adds its codes and rotary words)
        self.g_groups, self.m_groups, self.value_letters = _G_GROUPS, _M_GROUPS, _VALUE_LETTERS
        self.reader_name, self.codes_read, self.words_read = "the 3+2 G-code reader", _CODES_READ, _WORDS_READ
        self.hints = _HINTS
        self.number = 0
        # rows, flat (x, y, z per row), in the coordinates of plane ``plane_of`` (index into planes)
        self.tip, self.kind, self.feed = array("d"), array("q"), array("d")
        self.source, self.plane_of = array("q"), array("q")
        self.rows = 0
        self.chunk_start = 0
        self.block_lines: int | None = None            # lines of the last block read (read_block)
        self.events: list[Event] = []
        self.base = work_plane
        self.frames: list[WorkPlane] = [work_plane]     # index 0: the work plane; then one per G68.2
        self.frame = 0
        self.tilt: GcodePlane | None = None            # the active G68.2
        self.tilt_ready = True                         # False between G68.2 and G53.1
        self.pending_p3: _PendingP3 | None = None
        self.planes: list[GcodePlane] = []
        self.position = [math.nan, math.nan, math.nan]  # mm, current plane; NaN: not known yet
        self.start_pending = False                     # a merged start rapid waits for the full position
        # modal state
        self.motion: float | None = None
        self.plane = 17
        self.scale = 1.0                               # mm per program unit
        self.units_at_first_move: str | None = None
        self.absolute = True
        self.inverse_time = False
        self.retract_to_r = False                      # G99 (else G98)
        self.feed_word: float | None = None            # F as written (program units per minute)
        self.spindle_rpm = 0.0
        self.spindle_on = False
        self.spindle_kind = EventKind.SPINDLE_ON       # the direction: SPINDLE_ON_CCW after M4
        self.tool: int | None = None
        self.cycle: _Cycle | None = None
        self.cycles: list[GcodeCycle] = []
        self.percent = 0                               # % lines seen (1: opening, 2: closing)
        self.percent_opened = 0                        # the opening % line's number
        self.code_seen = False
        self.end_line: int | None = None
        # counts
        self.by_word: Counter[str] = Counter()
        self.skipped: Counter[str] = Counter()
        self.records = self.moves = self.start_rapids = self.arcs = self.arc_segments = 0
        self.cycle_holes = self.cycle_rows = self.comments = self.comment_lines = self.blank_lines = 0

    # ---- helpers
    def error(self, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.number)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        self.events.append(Event(before=self.rows - self.chunk_start, kind=kind, value=value, text=text))

    def add_rows(self, tip: FloatArray, kind: int | np.ndarray, feed: float | np.ndarray,
                 source: int | np.ndarray) -> None:
        """Rows (n, 3) mm in the current plane's coordinates."""
        tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
        n = len(tip)
        self.tip.frombytes(tip.tobytes())
        self.kind.frombytes(np.broadcast_to(np.asarray(kind, dtype=np.int64), (n,)).tobytes())
        self.feed.frombytes(np.broadcast_to(np.asarray(feed, dtype=np.float64), (n,)).tobytes())
        self.source.frombytes(np.broadcast_to(np.asarray(source, dtype=np.int64), (n,)).tobytes())
        self.plane_of.frombytes(np.full(n, self.frame, dtype=np.int64).tobytes())
        self.rows += n
        self.position = tip[-1].tolist()
        if self.units_at_first_move is None:
            self.units_at_first_move = "inch" if self.scale != 1.0 else "mm"

    # ---- lines, chunks, the end
    def lines(self, first: int, lines: list[str]) -> None:
        """Read ``lines`` (without line ends), the first of which is line ``first`` of the file.

        Runs of regular motion lines (``N.. G0/G1 X.. Y.. Z.. F..``, :func:`~prs3_post.core.lexer.lex_columns`),
        with the blank and comment-only lines between them, go to :meth:`bulk`; the others, and a run
        the bulk step refuses, to :meth:`line` one at a time.
        """
        if not lines:
            return
        values, fast = lex_columns(lines, _BULK_LETTERS)
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
        values, kinds, bounds, spans = lex_block_lines(data, _BULK_LETTERS, rows=self.block_lines)
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
        quiet[maybe] = [_QUIET.fullmatch(lines[i]) is not None for i in np.flatnonzero(maybe).tolist()]
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
            one_comment = _ONE_COMMENT.fullmatch
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

    def take(self) -> Toolpath:
        """The rows and events since the last take, in the PART frame (events count from the chunk's start)."""
        local = np.frombuffer(self.tip, dtype=np.float64).reshape(-1, 3)
        plane_of = np.frombuffer(self.plane_of, dtype=np.int64)
        if len(plane_of) and plane_of[0] == plane_of[-1] and (plane_of == plane_of[0]).all():   # one plane
            frame = self.frames[int(plane_of[0])]
            tip, axis = _to_part(frame, local), np.broadcast_to(frame.normal, local.shape)
        else:
            tip = np.zeros_like(local)
            axis = np.zeros_like(local)
            for index in np.unique(plane_of):          # one transform per plane, all its rows at once
                rows = plane_of == index
                tip[rows] = _to_part(self.frames[index], local[rows])
                axis[rows] = self.frames[index].normal
        events = tuple(self.events)                    # counted from the chunk's start already
        chunk = Toolpath(kind=np.frombuffer(self.kind, dtype=np.int64), tip=tip, axis=axis,
                         feed=np.frombuffer(self.feed, dtype=np.float64),
                         source=np.frombuffer(self.source, dtype=np.int64), events=events,
                         source_file=self.path)
        self.tip, self.kind, self.feed = array("d"), array("q"), array("d")
        self.source, self.plane_of = array("q"), array("q")
        self.events = []
        self.chunk_start = self.rows
        return chunk

    def close(self, line_count: int) -> None:
        """The end of the file: nothing may be left open."""
        self.number = line_count
        if self.pending_p3 is not None:
            self.number = self.pending_p3.line
            raise self.error("G68.2 P3 Q1 at the end of the file: its Q2 line (the normal, I J K) is missing")
        if self.start_pending:
            raise self.error("the program ends before its first rapid has all of X, Y and Z: the start position "
                             "of the moves is unknown")
        if not self.code_seen:
            raise InputError("not a G-code program: no code (only comments, blank lines or '%')", path=self.path)
        if self.percent == 1:                          # what LinuxCNC calls 'File ended with no percent sign'
            raise self.error(f"the program opens with '%' (line {self.percent_opened}) but the file ends without "
                             "its closing '%': a program cut short? (a program that opens with '%' ends with '%')")
        if self.cycle is not None:
            self.end_cycle()

    def summary(self) -> GcodeFile:
        counts = GcodeCounts(
            records=self.records, lines=self.number, moves=self.moves, start_rapids=self.start_rapids,
            arcs=self.arcs, arc_segments=self.arc_segments, cycles=len(self.cycles), cycle_holes=self.cycle_holes,
            cycle_rows=self.cycle_rows, planes=len(self.planes), comments=self.comments,
            comment_lines=self.comment_lines, blank_lines=self.blank_lines,
            skipped=tuple(sorted(self.skipped.items())), by_word=tuple(sorted(self.by_word.items())), rows=self.rows)
        return GcodeFile(path=self.path, units=self.units_at_first_move or "mm", toolpath=join_toolpaths([]),
                         counts=counts, work_plane=self.base, planes=tuple(self.planes), cycles=tuple(self.cycles),
                         end_lines=() if self.end_line is None else (self.end_line,))

    # ---- one line
    def line(self, number: int, line: str) -> None:
        self.number = number
        try:
            code, comments = split_comments(line)
        except LexError as exc:
            raise self.error(str(exc)) from exc
        for text in comments:
            self.comments += 1
            self.event(EventKind.COMMENT, text=text.strip())
        code = code.strip()
        if len(code) > MAX_RECORD_CHARS:                 # before its words are read (millions of them)
            raise self.error(f"a block of {len(code):,} characters besides its comments: longer than any G-code "
                             f"block may be ({MAX_RECORD_CHARS:,} at most)")
        if not code:
            if comments:
                self.comment_lines += 1
            else:
                self.blank_lines += 1
            return
        if self.percent >= 2:
            raise self.error(f"text after the closing '%': {quote(code)} (the program ends at the '%')")
        if code == "%":
            self.percent_line()
            return
        if self.end_line is not None:
            raise self.error(f"code after the program end (M2/M30 at line {self.end_line}): {quote(code)}")
        try:
            words = lex_words(code)
        except LexError as exc:
            raise self.error(str(exc)) from exc
        self.code_seen = True
        self.records += 1
        if words[0][0] == "O":
            if len(words) > 1:
                raise self.error(f"an O word (program number) must be alone on its line, found {quote(code)}")
            self.skipped["O"] += 1
            return
        self.block(self.sort(words))

    def percent_line(self) -> None:
        self.skipped["%"] += 1
        if self.percent == 0 and not self.code_seen:
            self.percent, self.percent_opened = 1, self.number   # the opening %
        elif self.percent == 1 or self.end_line is not None:
            self.percent = 2                           # the closing %: nothing but blank lines after it
        else:
            raise self.error("'%' in the middle of the program: '%' opens the program (first line) and closes it")

    def sort(self, words: tuple[Word, ...]) -> _Block:
        """The words of one line by kind, checked: known letters and codes, one code per group, each
        letter once, N first."""
        block = _Block()
        for position, (letter, value, text) in enumerate(words):
            if not math.isfinite(value):
                raise self.error(f"word {text[:24]!r}: the number is too large")
            if letter == "G" or letter == "M":
                groups = self.g_groups if letter == "G" else self.m_groups
                group = groups.get(value)
                if group is None:
                    name = code_name(letter, value)
                    hint = f": {self.hints[name]}" if name in self.hints else ""
                    raise self.error(f"code {name} is not read by {self.reader_name}{hint} (codes read: "
                                     f"{self.codes_read})")
                codes = block.g if letter == "G" else block.m
                if group in codes:
                    raise self.error(f"{codes[group][1]} and {text} on one line: both are {letter} codes of the "
                                     f"{group} group (one per line)")
                codes[group] = (value, text)
                self.by_word[code_name(letter, value)] += 1
            elif letter == "N":
                if position:
                    raise self.error(f"the line number {text} must be the first word of the line")
            elif letter in self.value_letters:
                if letter in block.values:
                    raise self.error(f"{block.values[letter][1]} and {text} on one line: a word may appear once")
                block.values[letter] = (value, text)
            elif letter == "E":
                raise self.error(f"word {text!r} is not G-code: E is not read here, and a number with an exponent "
                                 "(1e-05) must be written as a plain decimal (0.00001)")
            elif letter == "O":
                raise self.error(f"an O word (program number) must be alone on its line, found {text!r}")
            else:
                raise self.error(f"word {text!r} is not read by {self.reader_name} (words read: {self.words_read})")
        return block

    # ---- one line's words, in LinuxCNC's order of execution
    def block(self, block: _Block) -> None:
        g = {group: value for group, (value, _) in block.g.items()}
        m = {group: value for group, (value, _) in block.m.items()}
        if self.pending_p3 is not None and g.get("tilt") != 68.2:
            raise self.error(f"G68.2 P3 Q1 at line {self.pending_p3.line} must be followed by its G68.2 P3 Q2 line "
                             "(the normal, I J K)")
        if "feed mode" in g:
            self.inverse_time = g["feed mode"] == 93
        feed = block.take("F")
        if feed is not None:
            if not feed > 0:
                raise self.error(f"F must be > 0, got {block.values['F'][1]}")
            if not self.inverse_time and feed * self.scale > MAX_FEED_MM_MIN:
                raise self.error(f"{block.values['F'][1]} is {feed * self.scale:.6g} mm/min, more than "
                                 f"{MAX_FEED_MM_MIN:g} mm/min")
            if not self.inverse_time and feed * self.scale < MIN_FEED_MM_MIN:
                raise self.error(f"{block.values['F'][1]} is {feed * self.scale:.6g} mm/min, less than "
                                 f"{MIN_FEED_MM_MIN:g} mm/min (allowed: {MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} "
                                 "mm/min)")
            self.feed_word = feed
        speed = block.take("S")
        if speed is not None:
            if speed < 0:
                raise self.error(f"S must be ≥ 0 rpm, got {block.values['S'][1]}")
            if speed > MAX_SPINDLE_RPM:
                raise self.error(f"{block.values['S'][1]} is more than {MAX_SPINDLE_RPM:g} rpm (allowed: 0 to "
                                 f"{MAX_SPINDLE_RPM:g} rpm)")
            self.spindle_rpm = speed
            if self.spindle_on and "spindle" not in m:
                self.event(self.spindle_kind, value=speed)
        tool = block.take("T")
        if tool is not None:
            if tool < 0 or tool != int(tool):
                raise self.error(f"T must be a whole tool number ≥ 0, got {block.values['T'][1]}")
            self.tool = int(tool)
        if "tool change" in m:
            if self.tool is None:
                raise self.error("M6 without a tool number: give T on this line or before")
            self.event(EventKind.TOOL_CHANGE, value=float(self.tool), text=f"tool {self.tool}")
        if "spindle" in m:
            self.spindle(m["spindle"])
        if "coolant" in m:
            code = m["coolant"]
            if code == 9:
                self.event(EventKind.COOLANT_OFF)
            else:
                self.event(EventKind.COOLANT_ON, text=Coolant.from_m_code(code).value)
        if "dwell" in g:
            seconds = block.take("P")
            if seconds is None or seconds < 0:
                raise self.error("G4 needs P, the dwell in seconds (≥ 0)")
            self.event(EventKind.DWELL, value=seconds)
        if "plane" in g:
            self.plane = int(g["plane"])
        if "units" in g:
            self.scale = MM_PER_INCH if g["units"] == 20 else 1.0
        if "distance" in g:
            self.absolute = g["distance"] == 90
        if "return" in g:
            self.retract_to_r = g["return"] == 99
        if "length offset" in g and g["length offset"] == 43:
            block.take("H")
        if "tilt" in g:
            self.tilt_code(g["tilt"], block)
        self.motion_block(g.get("motion"), block)
        unused = [block.values[letter][1] for letter in block.values if letter not in block.used]
        if unused:
            raise self.error(f"word {unused[0]!r} is not used by any code on this line ({_USES[unused[0][0]]})")
        if "stop" in m:
            code = m["stop"]
            if code in (0, 1):
                self.event(EventKind.OPTIONAL_STOP if code == 1 else EventKind.STOP)
            else:
                if self.cycle is not None:
                    self.end_cycle()
                self.end_line = self.number

    def spindle(self, code: float) -> None:
        if code == 5:
            self.spindle_on = False
            self.event(EventKind.SPINDLE_OFF)
            return
        if not self.spindle_rpm > 0:
            raise self.error(f"{code_name('M', code)} without a spindle speed: give S (rpm) on this line or before")
        self.spindle_on = True
        self.spindle_kind = EventKind.SPINDLE_ON_CCW if code == 4 else EventKind.SPINDLE_ON
        self.event(self.spindle_kind, value=self.spindle_rpm)

    # ---- planes
    def tilt_code(self, code: float, block: _Block) -> None:
        if code == 53.1:
            if self.tilt is None:
                raise self.error("G53.1 without a tilted plane: G53.1 turns the tool axis to the plane of a G68.2, "
                                 "which must come first")
            self.tilt_ready = True
            return
        if code == 69:
            if self.cycle is not None:
                raise self.error(f"G69 while the canned cycle of line {self.cycle.line} is active: end it with G80 "
                                 "first")
            if self.tilt is not None:
                self.change_frame(0)
            self.tilt, self.tilt_ready = None, True
            return
        if "motion" in block.g:
            raise self.error("G68.2 must be on a line without motion codes (its X Y Z are the plane's origin)")
        if self.cycle is not None:
            raise self.error(f"G68.2 while the canned cycle of line {self.cycle.line} is active: end it with G80 "
                             "first")
        form = block.take("P")
        form = 0.0 if form is None else form
        if form not in (0.0, 3.0):
            raise self.error(f"G68.2 P{form:g} is not read: the reader reads P0 (Euler angles X Y Z I J K, the "
                             "default) and P3 (two vectors: Q1 X Y Z I J K, then Q2 I J K)")
        text = " ".join(t for _, t in block.values.values())
        if self.tilt is not None and self.pending_p3 is None:
            raise self.error(f"G68.2 while the tilted plane of line {self.tilt.line} is active: cancel it with G69 "
                             "first")
        origin = np.array([block.take(a) or 0.0 for a in _AXES]) * self.scale
        vector = np.array([block.take(a) or 0.0 for a in _OFFSETS])
        if form == 0.0:
            order = block.take("Q")
            if order is not None and order != 313:
                raise self.error(f"G68.2 Q{order:g}: the Euler angles are read in the order Z-X-Z only (Q313, "
                                 "the default)")
            self.set_tilt(WorkPlane(origin, euler_zxz_deg(*vector.tolist())), f"G68.2 {text}")
            return
        which = block.take("Q")
        if which == 1.0 and self.pending_p3 is None:
            self.pending_p3 = _PendingP3(self.number, f"G68.2 {text}", origin, vector)
            return
        if which != 2.0 or self.pending_p3 is None:
            raise self.error("G68.2 P3 is two lines: Q1 X Y Z I J K (origin, x direction), then Q2 I J K (the "
                             f"normal); found Q{which if which is None else f'{which:g}'}")
        if any(a in block.values for a in _AXES):
            raise self.error("G68.2 P3 Q2 takes no X, Y or Z: the origin is on the Q1 line")
        first = self.pending_p3
        self.pending_p3 = None
        x_length, z_length = float(np.linalg.norm(first.x_direction)), float(np.linalg.norm(vector))
        if z_length == 0.0:
            raise self.error("G68.2 P3 Q2: the normal I J K is the zero vector (it must be the plane's z direction, "
                             "the tool axis)")
        if x_length == 0.0:
            self.number = first.line
            raise self.error("G68.2 P3 Q1: the x direction I J K is the zero vector")
        cosine = float(first.x_direction @ vector) / (x_length * z_length)
        if abs(cosine) > _P3_MAX_COSINE:
            angle = math.degrees(math.acos(max(-1.0, min(1.0, cosine))))   # clip: rounding past ±1
            raise self.error(f"G68.2 P3: the x direction (line {first.line}) and the normal are {angle:.2f}° apart; "
                             "they must be perpendicular (85° to 95°)")
        z = vector / z_length
        x = first.x_direction / x_length - cosine * z
        x /= np.linalg.norm(x)
        self.set_tilt(WorkPlane(first.origin, np.column_stack([x, np.cross(z, x), z])), f"{first.text}; G68.2 {text}")

    def set_tilt(self, inner: WorkPlane, text: str) -> None:
        plane = GcodePlane(self.number, text, self.base.compose(inner, name=f"G68.2 at line {self.number}"))
        self.planes.append(plane)
        self.frames.append(plane.plane)
        self.change_frame(len(self.frames) - 1)
        self.tilt, self.tilt_ready = plane, False

    def change_frame(self, index: int) -> None:
        """Make plane ``index`` current; the position stays the same point (unknown if any axis is)."""
        if np.isfinite(self.position).all():
            part = self.frames[self.frame].to_part(np.array(self.position))
            self.position = self.frames[index].to_local(part)[0].tolist()
        else:
            if self.start_pending:
                raise self.error("the plane changes before the first rapid has all of X, Y and Z: give the full "
                                 "start position first")
            self.position = [math.nan] * 3
        self.frame = index

    # ---- motion
    def motion_block(self, code: float | None, block: _Block) -> None:
        has_axes = any(a in block.values for a in _AXES)
        if code is not None:
            if code in _CYCLES:
                if self.cycle is None or self.cycle.code != code:
                    level = None                       # another cycle without G80: the same initial level (G98)
                    if self.cycle is not None:
                        level = self.cycle.initial_z
                        self.end_cycle()
                    self.start_cycle(code, level)
            elif self.cycle is not None:
                self.end_cycle()
            self.motion = code
        if not has_axes:
            if code in _CYCLES:
                raise self.error(f"{code_name('G', code)} without a hole position: give X, Y (and Z, R)")
            return
        if "tilt" in block.g and block.g["tilt"][0] == 68.2:
            return                                      # X Y Z were the plane's origin
        if self.motion is None or self.motion == 80:
            raise self.error("axis words without a motion mode: give G0, G1, G2, G3 or a canned cycle"
                             if self.motion is None else "axis words after G80: give G0, G1, G2 or G3 first")
        if not self.tilt_ready:
            assert self.tilt is not None  # tilt_ready is False only after a G68.2
            raise self.error(f"a move in the tilted plane of G68.2 (line {self.tilt.line}) before G53.1: give G53.1 "
                             "first, which turns the tool axis to the plane's normal")
        if self.motion in _CYCLES:
            self.hole(block)
        elif self.motion in (2.0, 3.0):
            self.arc(block)
        else:
            self.move(block)

    def target(self, block: _Block) -> list[float]:
        """The end point of a move, mm in the current plane (NaN where still unknown)."""
        end = list(self.position)
        for index, letter in enumerate(_AXES):
            value = block.take(letter)
            if value is None:
                continue
            value *= self.scale
            if self.absolute:
                end[index] = value
            elif math.isnan(end[index]):
                raise self.error(f"incremental {letter} (G91) while the {letter} position is not known yet: give the "
                                 "first position under G90")
            else:
                end[index] += value
        return end

    def feed_for(self, length: float) -> float:
        """mm/min of a feed move of ``length`` mm."""
        word = self.feed_word
        code = code_name("G", self.motion or 0.0)
        if self.inverse_time:
            raise self.error(f"{code} under G93 (inverse time) without F: every feed move under G93 needs its own "
                             "F (1/minute)")
        if word is None:
            raise self.error(f"{code} before any F: the feed rate is unknown (give F, in units per minute)")
        return word * self.scale

    def inverse_time_feed(self, block: _Block, length: float) -> float | None:
        """Under G93: mm/min that makes the move of ``length`` mm take 1/F minutes (F of this line)."""
        if not self.inverse_time:
            return None
        word = block.values.get("F")
        if word is None:
            return self.feed_for(length)               # raises the G93 message
        if length == 0.0:
            raise self.error(f"{code_name('G', self.motion or 0.0)} of zero length under G93 (inverse time): its "
                             "time 1/F cannot be kept by a move that goes nowhere")
        feed = word[0] * length
        if not MIN_FEED_MM_MIN <= feed <= MAX_FEED_MM_MIN:       # what F means for this move, in mm/min
            raise self.error(f"{word[1]} under G93 (inverse time) makes this {length:.6g} mm move {feed:.6g} mm/min "
                             f"(allowed: {MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} mm/min)")
        return feed

    def move(self, block: _Block) -> None:
        end = self.target(block)
        rapid = self.motion == 0.0
        if not all(math.isfinite(v) for v in end):
            if not rapid:
                raise self.error(f"{code_name('G', self.motion or 1.0)} while the position is not fully known: the "
                                 "first moves must give X, Y and Z (a rapid may give them over several lines)")
            self.position = end
            self.start_pending = True
            self.start_rapids += 1
            return
        self.start_pending = False
        self.moves += 1
        if rapid:
            self.add_rows(np.array(end), _RAPID, 0.0, self.number)
            return
        length = math.dist(end, self.position)
        feed = self.inverse_time_feed(block, length)
        self.add_rows(np.array(end), _FEED, feed if feed is not None else self.feed_for(length), self.number)

    def arc(self, block: _Block) -> None:
        code = code_name("G", self.motion or 2.0)
        if not np.isfinite(self.position).all():
            raise self.error(f"{code} while the position is not fully known: the arc has no start point")
        first, second, normal_axis = _PLANES[self.plane]
        plane_name = f"G{self.plane}"
        offset_letters = (_OFFSETS[first], _OFFSETS[second])
        wrong = _OFFSETS[normal_axis]
        if wrong in block.values:
            raise self.error(f"{block.values[wrong][1]} in {plane_name}: the arc centre's offsets in {plane_name} "
                             f"are {offset_letters[0]} and {offset_letters[1]}")
        start = np.array(self.position)
        end = np.array(self.target(block))
        radius_word = block.take("R")
        offsets = [block.take(letter) for letter in offset_letters]
        turns_word = block.take("P")
        turns = 1 if turns_word is None else turns_word
        if turns < 1 or turns != int(turns):
            raise self.error(f"{code} P (turns) must be a whole number ≥ 1, got {block.values['P'][1]}")
        centre = start.copy()
        a, b = start[[first, second]], end[[first, second]]
        if radius_word is not None:
            if any(v is not None for v in offsets):
                raise self.error(f"{code} with both R and {'/'.join(offset_letters)}: give the centre one way")
            radius = abs(radius_word) * self.scale
            chord = b - a
            half = float(np.linalg.norm(chord)) / 2.0
            if half == 0.0:
                raise self.error(f"{code} with R and its end at its start: R cannot make a full circle (give the "
                                 f"centre with {offset_letters[0]} {offset_letters[1]})")
            if radius == 0.0:
                raise self.error(f"{code} R must not be 0")
            if half > radius + self.circle_tolerance:
                raise self.error(f"{code} end point is {2 * half:.4f} mm from its start, more than the diameter "
                                 f"{2 * radius:.4f} of R{radius_word:g}: the end is not on a circle of that radius")
            height = math.sqrt(max(radius * radius - half * half, 0.0))   # clip: a chord a hair over 2R
            left = np.array([-chord[1], chord[0]]) / (2.0 * half)
            side = (1.0 if self.motion == 3.0 else -1.0) * (1.0 if radius_word > 0 else -1.0)
            centre[[first, second]] = (a + b) / 2.0 + side * height * left
        else:
            if all(v is None for v in offsets):
                raise self.error(f"{code} without its centre: give {offset_letters[0]} and/or {offset_letters[1]} "
                                 f"(offsets from the start in {plane_name}) or R")
            centre[[first, second]] = a + np.array([v or 0.0 for v in offsets]) * self.scale
            radius = float(np.linalg.norm(a - centre[[first, second]]))
            if radius == 0.0:
                raise self.error(f"{code} centre offsets are zero: the arc has no radius")
            end_radius = float(np.linalg.norm(b - centre[[first, second]]))
            if abs(end_radius - radius) > self.circle_tolerance:
                shown = " ".join(f"{_AXES[i]}{end[i] / self.scale:.4f}" for i in range(3))
                raise self.error(f"{code} end point ({shown}) is {abs(end_radius - radius):.4f} mm "
                                 f"{'outside' if end_radius > radius else 'inside'} the circle through its start "
                                 f"(radius {radius / self.scale:.4f}); the end must lie on the circle within "
                                 f"{self.circle_tolerance:g} mm")
        axis = np.zeros(3)
        axis[normal_axis] = 1.0 if self.motion == 3.0 else -1.0      # G3: counter-clockwise about the normal
        try:
            sweep = arc_sweep(centre, axis, start, end) + 2.0 * math.pi * (int(turns) - 1)
            count = arc_segment_count(radius, sweep, tolerance=self.tolerance)
            if count > MAX_ARC_SEGMENTS:
                raise self.error(f"{code} (radius {radius / self.scale:g}, {int(turns)} turns) needs {count:,} "
                                 f"segments within {self.tolerance:g} mm, more than {MAX_ARC_SEGMENTS:,}")
            points = arc_points_3d(centre, axis, start, end, tolerance=self.tolerance, turns=int(turns) - 1)[1:]
        except ValueError as exc:                        # the start or end on the arc's axis
            raise self.error(f"{code} start or end is at the arc's centre: the arc has no direction there") from exc
        length = math.hypot(sweep * radius, float(end[normal_axis] - start[normal_axis]))
        feed = self.inverse_time_feed(block, length)
        self.add_rows(points, _FEED, feed if feed is not None else self.feed_for(length), self.number)
        self.arcs += 1
        self.arc_segments += len(points)

    # ---- canned cycles
    def start_cycle(self, code: float, initial_z: float | None) -> None:
        if self.inverse_time:
            raise self.error(f"{code_name('G', code)} under G93 (inverse time): canned cycles need a feed per minute "
                             "(G94)")
        if not np.isfinite(self.position).all():
            raise self.error(f"{code_name('G', code)} while the position is not fully known: the cycle starts from "
                             "the current position (give X, Y and Z first)")
        self.cycle = _Cycle(code, self.number, self.position[2] if initial_z is None else initial_z,
                            fresh=initial_z is None)

    def end_cycle(self) -> None:
        cycle = self.cycle
        assert cycle is not None  # only called with a cycle active
        self.cycles.append(GcodeCycle(cycle.line, code_name("G", cycle.code), cycle.holes))
        self.cycle = None

    def hole(self, block: _Block) -> None:
        cycle = self.cycle
        assert cycle is not None  # motion is a cycle code only while one is active
        code = code_name("G", cycle.code)
        if self.inverse_time:
            raise self.error(f"{code} under G93 (inverse time): canned cycles need a feed per minute (G94)")
        if self.plane != 17:
            raise self.error(f"{code} in G{self.plane}: canned cycles are read in G17 only, where the hole goes "
                             "along Z, the tool axis (in G18/G19 it would go sideways)")
        for letter in "ZRQP":
            value = block.take(letter)
            if value is not None:
                setattr(cycle, letter.lower(), value)
        if cycle.z is None or cycle.r is None:
            raise self.error(f"{code} needs Z (the hole's bottom) and R (the retract plane)")
        pecking = _CYCLES[cycle.code]
        if pecking is not Pecking.NONE and (cycle.q is None or not cycle.q > 0):
            raise self.error(f"{code} needs Q > 0, the depth of each peck")
        if cycle.code != 82 and "P" in block.values:
            raise self.error(f"{code} takes no P (only G82 dwells at the bottom)")
        if cycle.p is not None and cycle.p < 0:
            raise self.error(f"{code} P (dwell) must be ≥ 0 s, got {cycle.p:g}")
        current = list(self.position)
        x, y = current[0], current[1]
        for index, letter in enumerate("XY"):
            value = block.take(letter)
            if value is not None:
                shifted = value * self.scale + (0.0 if self.absolute else current[index])
                x, y = (shifted, y) if index == 0 else (x, shifted)
        level = current[2]
        if self.absolute:
            r, z = cycle.r * self.scale, cycle.z * self.scale
        else:
            r = level + cycle.r * self.scale
            z = r + cycle.z * self.scale
        if not z < r:
            raise self.error(f"{code} bottom Z {z / self.scale:g} is not below the retract plane R {r / self.scale:g}: "
                             "the hole goes down the tool axis, from R to Z")
        feed = self.feed_for(0.0)
        # LinuxCNC's preliminary motion: a fresh cycle goes up to R first if it is below it (and that is
        # the level G98 returns to); then across to the hole, at the current level (G99) or the cycle's
        # initial level (G98), then down to R
        before: list[list[float]] = []
        if cycle.fresh and level < r:
            before.append([current[0], current[1], r])
            level = cycle.initial_z = r
        cycle.fresh = False
        level = level if self.retract_to_r else cycle.initial_z
        before.append([x, y, level])
        if before[0] == current:                         # a move that goes nowhere
            del before[0]
        clear = r if self.retract_to_r else max(cycle.initial_z, r)
        if pecking is not Pecking.NONE and (count := peck_count(r - z, (cycle.q or 0.0) * self.scale)) > MAX_PECKS:
            raise self.error(f"{code} Q{cycle.q:g} would drill {(r - z) / self.scale:g} from R to Z in "
                             f"{count:,} pecks, more than {MAX_PECKS:,}: use a larger Q")
        drill = DrillCycle(depth=r - z, clearance=0.0, retract=clear - r, feed=feed, pecking=pecking,
                           peck=(cycle.q or 0.0) * self.scale, gap=PECK_GAP_MM,
                           dwell=(cycle.p or 0.0) if cycle.code == 82 else 0.0)
        tip, kind, bottom = drill_rows(np.array([[x, y, r]]), np.array([[0.0, 0.0, 1.0]]), drill)
        if level == r:                                   # the cycle's first rapid goes nowhere
            tip, kind, bottom = tip[1:], kind[1:], bottom - 1
        rows = np.vstack([np.array(before).reshape(-1, 3), tip])
        kinds = np.concatenate([np.full(len(before), _RAPID), kind])
        first = self.rows
        self.add_rows(rows, kinds, np.where(kinds == _FEED, feed, 0.0), self.number)
        if drill.dwell > 0:
            self.events.append(Event(before=first - self.chunk_start + len(before) + int(bottom[0]) + 1,
                                     kind=EventKind.DWELL,
                                     value=drill.dwell))
        cycle.holes += 1
        self.cycle_holes += 1
        self.cycle_rows += len(rows)


_FILL_CODES = np.array([_RAPID, _FEED], dtype=np.int64)


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


def _to_part(frame: WorkPlane, local: FloatArray) -> FloatArray:
    """``frame.to_part(local)``: (N, 3) mm, in C where it was built (the same bits, one pass)."""
    from prs3_post.core import native  # ctypes: loaded only where rows are read

    tip = native.rows_to_part(local, frame.rotation, frame.origin)
    return frame.to_part(local) if tip is None else tip


def _fill_moves(values: FloatArray, moves: BoolArray, state: FloatArray, scale: float,
                first: int) -> native.FilledMoves | None:
    """The rows of a run of bulk lines (:meth:`_Reader.bulk`), its state after them and its G0 and G1
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
    return (position, np.where(feeding, _FEED, _RAPID).astype(np.int64), np.where(feeding, given_feed * scale, 0.0),
            first + np.flatnonzero(moves), after, np.array([rapids, len(codes) - rapids], dtype=np.int64))


#: What each value word is for, for the message about a word no code on its line uses.
_USES = {
    "X": "X Y Z go with a motion code or G68.2", "Y": "X Y Z go with a motion code or G68.2",
    "Z": "X Y Z go with a motion code or G68.2", "I": "I J K go with G2/G3 or G68.2",
    "J": "I J K go with G2/G3 or G68.2", "K": "I J K go with G2/G3 or G68.2",
    "R": "R goes with G2/G3 or a canned cycle", "P": "P goes with G4, G82, G2/G3 (turns) or G68.2",
    "Q": "Q goes with G83/G73 or G68.2 P3", "H": "H goes with G43",
}

