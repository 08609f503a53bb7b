"""Read APT / CL data (text CLSF, as NX, Creo, CATIA and ISO-4343-style posts write it) into a Toolpath.

The result is a :class:`~prs3_post.core.toolpath.Toolpath` in the PART frame (every ``MSYS/`` applied;
or, asked for, in the CAM system's machine frame, as written) in mm, plus an accounting of every
record (:class:`ClCounts`), so that nothing in the file is lost without a trace. Every row and
event keeps the line of the record it came from. :func:`read_cl` reads a whole file;
:class:`ClStream` hands out the same rows a chunk of lines at a time, with memory that does not
grow with the file (runs of plain GOTO lines are read in bulk there: same rows, same errors).

Records
-------
A record is a line (blank lines are not records). A record whose text ends with a single ``$``
continues on the next line (the ``$`` is removed and the lines joined); a file that ends inside
such a record is a truncated record. ``$$`` starts a comment: a whole-line ``$$ text`` is a
comment record, and ``$$ text`` after a record is that record's comment; both become COMMENT
events. A record is ``WORD/arg,arg,...`` or a bare ``WORD``; arguments are numbers or minor words.

Major words understood (anything else is an error naming file:line, unless it is in ``ignore``):

- ``GOTO/x,y,z[,i,j,k]`` — a move; i,j,k (unit tool axis, tip → spindle) is modal when omitted.
  ``FROM/`` (the start point) and ``GOHOME/`` (back to the start) take the same values and are
  RAPID rows: the tool goes to the point the CAM system names, at rapid.
- ``RAPID`` — the next GOTO/GOHOME only is a RAPID row; all other moves feed.
- ``FEDRAT/f`` with the unit before or after the value: ``MMPM``, ``IPM`` (per minute),
  ``MMPR``, ``IPR`` (per revolution: times the spindle speed at each move); no unit: the file's
  length unit per minute.
- ``MULTAX[/ON|OFF]`` (multi-axis GOTOs; with ``OFF`` a GOTO must not carry i,j,k), ``TLAXIS/i,j,k``.
- ``MSYS/x0,y0,z0,xi,xj,xk,yi,yj,yk`` — the local frame of all following points and axes, relative
  to the part: origin, x axis, y axis, z = x × y. The axes must be orthogonal unit vectors within
  :data:`FRAME_TOLERANCE` (they are written with 7 decimals); they are then made exactly orthonormal.
  A later MSYS replaces the frame (it is not composed with the previous one).
- ``UNITS/MM|INCHES`` — the file's length unit, for the whole file. Without it, the caller's unit,
  else inches when a ``FEDRAT`` is in IPM/IPR (and none in MMPM/MMPR), else mm.
- ``LOADTL/n``, ``LOAD/TOOL,n`` — tool change (TOOL_CHANGE event; what follows the number, such
  as ``ADJUST,m``, a length-offset register, is not used: the IK uses the machine's tool length);
  ``SELECT/TOOL,n`` pre-selects the next tool (no event: the tool in the spindle does not change);
  ``TLDATA/...`` describes the cutter's shape (kept in :attr:`ClFile.tool_data`; it does not give
  the tool's gauge length).
- ``SPINDL/[RPM,]s[,CLW|CCLW]``, ``SPINDL/ON``, ``SPINDL/OFF`` — SPINDLE_ON (CLW, the default) or
  SPINDLE_ON_CCW (CCLW) / SPINDLE_OFF events; ``SPINDL/ON`` keeps the last direction.
- ``COOLNT/ON|FLOOD|MIST|OFF`` — COOLANT_ON (``text`` flood or mist) / COOLANT_OFF events.
- ``CYCLE/DRILL|DEEP|BRKCHP,...`` (also ``DRILL,DEEP`` and ``DRILL,BRKCHP``) with ``RAPTO,c``,
  ``FEDTO,d``, optional ``RTRCTO,r``, ``STEP,s``, ``DWELL,t`` and a feed ``MMPM|IPM|MMPR|IPR,f``;
  each GOTO until ``CYCLE/OFF`` is a hole point, expanded along its tool axis by
  :func:`prs3_post.toolpaths.cycles.drill_rows`. How the words are read: the GOTO point is the top of the
  hole; RAPTO = clearance above it where the rapid stops; FEDTO = depth below it (its sign is
  ignored: CAM systems write it either way, and a drill only goes down); RTRCTO = height above
  the point after the hole (default: RAPTO); STEP = depth per peck (DEEP, BRKCHP only; without
  STEP there is no peck depth, and the hole is drilled in one feed).
- ``CIRCLE/xc,yc,zc,i,j,k,r[,...]`` followed by its end GOTO — an arc from the current point,
  expanded within the chordal tolerance by :func:`prs3_post.toolpaths.arcs.arc_points_3d`. The tool moves
  **clockwise about (i,j,k)** (counter-clockwise about −(i,j,k)): that is the convention of the
  NX files in the corpus, where each arc is tangent to the moves around it (pinned by a test).
  Start and end must lie on the circle within ``circle_tolerance`` (radially, and at one height
  along the axis); the end GOTO may not change the tool axis.
- ``PPRINT/text`` (or ``PPRINT text``) and ``$$`` comments — COMMENT events, text kept as written.
- ``STOP`` — STOP event (M0); ``OPSTOP`` — OPTIONAL_STOP event (M1).
- ``END-OF-PATH`` ends a tool path (another may follow); ``FINI`` ends the file (only blank lines,
  or the listing trailer, may follow).

Display-only records (:data:`DISPLAY_WORDS`: ``PAINT/``, ``TOOL PATH/``) are skipped on purpose
and counted. NX listings end with ``Tool Path Listing has N lines.``; after END-OF-PATH or FINI
that trailer is skipped and counted too.

Numbers are decimals (``-12.5``, ``.5``, ``5.``, ``+3``) with an optional exponent
(``1.5E+02``): FORTRAN-formatted CL writers use exponents, and in CL text, unlike G-code, an
``E`` cannot be read as another word. ``nan``, ``inf``, a FORTRAN ``D`` exponent and values that
overflow are errors.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable, Iterator

from prs3_post.core.defaults import MM_PER_INCH
from prs3_post.core.errors import InputError
from prs3_post.core.input_files import iter_pieces, lf_line_ends, line_chunks
from prs3_post.core.toolpath import Toolpath
from prs3_post.core.types import Progress
from prs3_post.readers.cl.bulk import LineReader
from prs3_post.readers.cl.summary import ClCounts, ClCycle, ClFile, ClFrame, ClToolData
from prs3_post.readers.cl.syntax import (
    DISPLAY_WORDS,
    FRAME_TOLERANCE,
    KNOWN_WORDS,
    decoded_text,
    unit_records,
    units_of_file,
)
from prs3_post.readers.common import join_toolpaths
from prs3_post.readers.protocol import SourceNotes, StreamDefaults
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE

__all__ = [
    "DISPLAY_WORDS",
    "FRAME_TOLERANCE",
    "ClCounts",
    "ClCycle",
    "ClFile",
    "ClFrame",
    "ClToolData",
    "parse_cl",
    "read_cl",
]

# --------------------------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------------------------
#: Lines read per chunk by :class:`ClStream` (a chunk's rows are handed out together).
CHUNK_LINES = 10_000
_PIECE_BYTES = 1 << 20


def read_cl(path: str, *, tolerance: float, units: str | None = None, ignore: frozenset[str] = frozenset(),
            circle_tolerance: float, apply_msys: bool = True) -> ClFile:
    """Read a whole CL file (see the module docstring for what is understood).

    Parameters
    ----------
    path : str — shown unchanged in messages
    tolerance : float — mm, > 0, chordal tolerance of the expanded arcs
    units : str or None — ``mm`` or ``inch``: the file's length unit when it has no ``UNITS/``
        record (None: inches if its feeds are IPM/IPR, else mm)
    ignore : frozenset of str — major words to skip (and count) instead of refusing
    circle_tolerance : float — mm, how far an arc's start and end may be from its circle
    apply_msys : bool — True: points and axes in the part frame (every ``MSYS/`` applied); False:
        as written, in the CAM system's machine coordinate system (the MSYS frames are only recorded).
        NX writes GOTOs in its MCS and MSYS places the MCS in the model's absolute frame; a part
        machined from below in that frame (humman_4: MCS z = absolute −z) can only be set up on
        this machine in the MCS.

    Returns
    -------
    ClFile

    Raises
    ------
    InputError
        ``path:line: message`` naming what was found and what would be valid.
    """
    stream = ClStream(path, tolerance=tolerance, units=units, ignore=ignore, circle_tolerance=circle_tolerance,
                      apply_msys=apply_msys)
    return stream.whole()


def parse_cl(text: str, *, path: str, tolerance: float, units: str | None = None,
             ignore: frozenset[str] = frozenset(), circle_tolerance: float,
             chunk_lines: int = CHUNK_LINES, apply_msys: bool = True) -> ClFile:
    """Read CL text; ``path`` is only used in messages. Parameters as :func:`read_cl`."""
    return ClStream(path, tolerance=tolerance, units=units, ignore=ignore, circle_tolerance=circle_tolerance,
                    chunk_lines=chunk_lines, text=text, apply_msys=apply_msys).whole()


class ClStream(StreamDefaults):
    """A CL file read in chunks of lines, for a conversion whose memory does not grow with the file.

    Iterate it for one :class:`~prs3_post.core.toolpath.Toolpath` (part frame, mm) per chunk of
    ``chunk_lines`` lines that has rows or events (events count rows from the chunk's start;
    ``source`` holds the file's line numbers). The modal state, the position and a pending arc or
    cycle carry across chunks, so the chunks are exactly the rows of :func:`read_cl`, cut in pieces.
    Before the first chunk the whole file is read once, cheaply, to check that it is text and to
    find its length unit (``UNITS/`` and the feed units, which may come after the first point).
    After the iteration :attr:`summary` holds everything else (:class:`ClFile` with an empty toolpath).
    ``text`` reads that text instead of the file (``path`` then only names it in messages);
    ``apply_msys`` as in :func:`read_cl`.

    Raises (during the iteration)
    -----------------------------
    InputError
        As :func:`read_cl`.
    """

    def __init__(self, path: str, *, tolerance: float, units: str | None = None,
                 ignore: Iterable[str] = (), circle_tolerance: float,
                 chunk_lines: int = CHUNK_LINES, piece_bytes: int = _PIECE_BYTES, text: str | None = None,
                 apply_msys: bool = True):
        if units not in (None, "mm", "inch"):
            raise ValueError(f"ClStream: units must be 'mm', 'inch' or None, got {units!r}")
        if not (math.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"ClStream: tolerance must be > 0 mm, got {tolerance!r}")
        self.path, self.tolerance, self.units, self.circle_tolerance = path, tolerance, units, circle_tolerance
        self.ignored_words = tuple(ignore)             # as given (the program's header lists them so)
        self.ignore = frozenset(word.upper() for word in self.ignored_words)
        understood = sorted(self.ignore & {*KNOWN_WORDS, *DISPLAY_WORDS})
        if understood:
            raise InputError(f"cannot ignore {', '.join(understood)}: the reader understands "
                             f"{'it' if len(understood) == 1 else 'them'} (only unknown major words can be ignored)",
                             path=path)
        self.chunk_lines, self.piece_bytes = max(1, int(chunk_lines)), max(1, int(piece_bytes))
        self._text = text                             # parse_cl: the text instead of the file
        self.apply_msys = apply_msys
        self.summary: ClFile | None = None
        self.sha256: str | None = None                 # of the bytes read, once read (the header's)

    def _pieces(self, progress: Progress | None = None) -> Iterator[str]:
        """The file's text in pieces that end at line ends (a leading byte-order mark removed; CR and CRLF
        line ends made LF where there are CR-only ones); once through, :attr:`sha256` is the hash of the
        bytes read (the last pass's: the records'). ``progress``: told the bytes read."""
        digest = hashlib.sha256()
        if self._text is not None:
            digest.update(self._text.encode("utf-8"))
            yield lf_line_ends(self._text.removeprefix("\ufeff"))
        else:
            for offset, piece in iter_pieces(self.path, "a CL file", self.piece_bytes, digest, progress):
                if offset == 0 and piece.startswith(b"\xef\xbb\xbf"):
                    piece, offset = piece[3:], 3
                yield lf_line_ends(decoded_text(piece, self.path, offset))
        self.sha256 = digest.hexdigest()

    def __iter__(self) -> Iterator[Toolpath]:
        file_units = units_of_file(unit_records(self._pieces(), self.path), self.path, self.units)
        reader = LineReader(self.path, MM_PER_INCH if file_units == "inch" else 1.0, self.ignore, self.tolerance,
                            self.circle_tolerance, self.apply_msys)
        reader.tool_number_max = self.tool_number_max
        number = 1
        for lines in line_chunks(self._pieces(self.progress), self.chunk_lines):
            reader.lines(number, lines)
            number += len(lines)
            chunk = reader.take()
            if len(chunk) or chunk.events:
                yield chunk
        reader.close()
        chunk = reader.take()
        if len(chunk) or chunk.events:
            yield chunk
        self.summary = reader.summary(file_units)

    def whole(self) -> ClFile:
        """All chunks joined: the whole file's :class:`ClFile`."""
        chunks = list(self)
        assert self.summary is not None  # set by the iteration
        return ClFile(path=self.path, units=self.summary.units, toolpath=join_toolpaths(chunks),
                      counts=self.summary.counts, frames=self.summary.frames, cycles=self.summary.cycles,
                      tool_data=self.summary.tool_data, end_lines=self.summary.end_lines)

    def notes(self) -> SourceNotes:
        """The length unit given (else ``auto``) and the words ignored, for the program's header."""
        return SourceNotes(units=self.units or "auto", ignore=self.ignored_words)

    def tool_diameter(self) -> float:
        """mm: the tool diameter the file states, once read: the smallest of its ``TLDATA/`` records (their
        first number, in the file's units: ``TLDATA/MILL,10.0,0.0,50.0``), the one a rapid of the thinnest
        tool must clear; 0 where none is stated.

        Raises
        ------
        InputError
            A diameter outside :data:`~prs3_post.toolpaths.common.TOOL_DIAMETER_RANGE`, at its record.
        """
        summary = self.summary
        assert summary is not None  # set when the iteration ends
        scale = MM_PER_INCH if summary.units == "inch" else 1.0
        low, high = TOOL_DIAMETER_RANGE
        found = []
        for record in summary.tool_data:
            if record.diameter is None:
                continue
            diameter = record.diameter * scale
            if not low <= diameter <= high:
                raise InputError(f"TLDATA/ states a tool diameter of {diameter:.6g} mm: a tool for the check in "
                                 f"the rapids must be {low:g} to {high:g} mm", path=summary.path, line=record.line)
            found.append(diameter)
        return min(found, default=0.0)
