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
import math
from collections.abc import Iterator

from prs3_post.core.errors import InputError, LexError
from prs3_post.core.input_files import iter_pieces, lf_line_end_bytes, line_blocks
from prs3_post.core.lexer import (
    BYTE_ORDER_MARK,
    EMPTY,
    decode,
)
from prs3_post.core.toolpath import Toolpath
from prs3_post.part.workplane import WorkPlane
from prs3_post.readers.common import join_toolpaths
from prs3_post.readers.gcode.bulk import LineReader, refuse_rotary, rotary_hint, scan_bytes
from prs3_post.readers.gcode.summary import GcodeCounts, GcodeCycle, GcodeFile, GcodePlane
from prs3_post.readers.gcode.words import PECK_GAP_MM, ROTARY_HINT
from prs3_post.readers.protocol import SourceNotes, StreamDefaults

__all__ = [
    "CHUNK_LINES", "PECK_GAP_MM", "GcodeCounts", "GcodeCycle", "GcodeFile", "GcodePlane", "GcodeStream",
    "parse_gcode", "read_gcode",
]

#: Lines read per chunk by :class:`GcodeStream`.
CHUNK_LINES = 10_000
_PIECE_BYTES = 1 << 20


# --------------------------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------------------------
def read_gcode(path: str, *, tolerance: float, work_plane: WorkPlane | None = None,
               circle_tolerance: float) -> GcodeFile:
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
                circle_tolerance: float, chunk_lines: int = CHUNK_LINES) -> GcodeFile:
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
                 circle_tolerance: float, chunk_lines: int = CHUNK_LINES,
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
        self._cr_line_ends = False                     # set by _check: a piece has CR-only line ends
        self.summary: GcodeFile | None = None
        self.sha256: str | None = None                 # of the bytes read, once read (the header's)

    def _check(self) -> None:
        """The whole file: text (empty, byte-order mark, control bytes, UTF-8, in that order) and no
        rotary word (the first one's line is named); the file's bytes read once, each piece checked by
        :meth:`_check_piece`."""
        if self._text is not None:
            try:
                text = decode(lf_line_end_bytes(self._text.encode("utf-8")))
            except LexError as exc:
                raise InputError(str(exc), path=self.path) from exc
            self._scan(text, 1)
            return
        blank, problem, first = True, None, 1
        for offset, piece in iter_pieces(self.path, "a G-code program", self.piece_bytes):
            if offset == 0 and piece.startswith(b"\xef\xbb\xbf"):   # (a file with a mark is not blank)
                raise InputError(BYTE_ORDER_MARK, path=self.path)
            lf = lf_line_end_bytes(piece)
            if lf is not piece:                          # CR-only line ends: _pieces makes them LF too
                self._cr_line_ends, piece = True, lf
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
        pattern (one pass in C where it was built, :func:`scan_bytes`)."""
        control, high, lines, rotary = scan_bytes(piece)
        if control >= 0 or high:
            self._scan(decode(piece, offset=offset), first)     # raises LexError
        elif rotary >= 0:
            self._scan(piece.decode("ascii"), first)
        return lines

    def _scan(self, text: str, first: int) -> None:
        """Refuse what no line of the file may have (here: a rotary word) in a piece whose first line is
        line ``first`` (a hook: the 5-axis reader refuses expressions and parameters instead)."""
        if rotary_hint(text):
            for number, line in enumerate(text.split("\n"), start=first):
                if ROTARY_HINT.search(line):
                    refuse_rotary(line, number, self.path)

    def _reader(self) -> LineReader:
        """The interpreter of the lines (a hook: the 5-axis reader, ``readers.fivex.reader``, gives its own)."""
        return LineReader(self.path, self.work_plane, self.tolerance, self.circle_tolerance)

    def _pieces(self) -> Iterator[tuple[int, bytes]]:
        """The file's bytes in ``(offset, bytes)`` pieces that end at line ends (``text``: its UTF-8 bytes),
        CR and CRLF line ends made LF where there are CR-only ones (a CAM program is read, not run: its
        lines end as its system wrote them); once through, :attr:`sha256` is that of the bytes read."""
        digest = hashlib.sha256()
        if self._text is not None:
            data = self._text.encode("utf-8")
            digest.update(data)
            yield 0, lf_line_end_bytes(data)
        else:
            for offset, piece in iter_pieces(self.path, "a G-code program", self.piece_bytes, digest, self.progress):
                yield offset, lf_line_end_bytes(piece) if self._cr_line_ends else piece
        self.sha256 = digest.hexdigest()

    def __iter__(self) -> Iterator[Toolpath]:
        self._check()                                   # the whole text checked: its bytes are read below
        reader = self._reader()
        reader.tool_number_max = self.tool_number_max
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
