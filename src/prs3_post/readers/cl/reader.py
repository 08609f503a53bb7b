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
import itertools
import math
import re
from array import array
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE, FEED_RANGE_MM_MIN, MAX_SPINDLE_RPM, MM_PER_INCH
from prs3_post.core.errors import InputError
from prs3_post.core.input_files import iter_pieces, line_chunks
from prs3_post.core.lexer import bad_pairs, decimal_numbers
from prs3_post.core.toolpath import Coolant, Event, EventKind, MoveKind, Toolpath
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.part.stl import MAX_COORDINATE_MM
from prs3_post.part.workplane import rotate_rows
from prs3_post.readers.protocol import SourceNotes, StreamDefaults
from prs3_post.toolpaths.arcs import MAX_ARC_SEGMENTS, arc_points_3d, arc_segment_count, arc_sweep
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE
from prs3_post.toolpaths.cycles import MAX_PECKS, DrillCycle, Pecking, drill_rows, peck_count

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

#: Records that only drive a CAM system's display: skipped on purpose, and counted.
DISPLAY_WORDS: frozenset[str] = frozenset({"PAINT", "TOOL PATH"})
#: The NX listing trailer, skipped (and counted) after END-OF-PATH or FINI.
LISTING_TRAILER = "Tool Path Listing"
#: MSYS axes must be unit and orthogonal within this (they are printed with 7 decimals).
FRAME_TOLERANCE = 1e-5
#: A tool vector must have length 1 within this (it is then normalized).
AXIS_LENGTH_TOLERANCE = 1e-3
#: mm/min, the fastest feed per minute a CAM file may ask for (a kilometre a minute, as the command line's
#: feeds): more is a typo, and would make a program whose moves the controller cannot follow.
MIN_FEED_MM_MIN, MAX_FEED_MM_MIN = FEED_RANGE_MM_MIN
# A coordinate or length (GOTO/, CIRCLE/, MSYS/, CYCLE/) must lie within ±MAX_COORDINATE_MM, as an STL part's:
# a kilometre is far beyond any machine, so more is a typo or a unit error (bad input, not a point out of reach).

_KNOWN_WORDS = ("GOTO", "FROM", "GOHOME", "RAPID", "FEDRAT", "MULTAX", "TLAXIS", "MSYS", "UNITS", "LOADTL",
                "LOAD", "SELECT", "TLDATA", "SPINDL", "COOLNT", "CYCLE", "CIRCLE", "PPRINT", "END-OF-PATH",
                "FINI", "STOP", "OPSTOP")
_NUMBER_TEXT = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"   # ASCII digits (\\d takes ١ too)
_NUMBER = re.compile(rf"{_NUMBER_TEXT}\Z")
_NUMBER_LIST = re.compile(rf"[ \t]*{_NUMBER_TEXT}[ \t]*(?:,[ \t]*{_NUMBER_TEXT}[ \t]*)*\Z")
_TRAILER = re.compile(r"Tool Path Listing has \d+ lines\.\Z")
_FEED_UNITS = {"MMPM": (1.0, False), "IPM": (MM_PER_INCH, False), "MMPR": (1.0, True), "IPR": (MM_PER_INCH, True)}
_UNIT_WORDS = {"MM": "mm", "INCHES": "inch", "INCH": "inch"}
_RAPID, _FEED = int(MoveKind.RAPID), int(MoveKind.FEED)
#: A GOTO as CAM systems write nearly all of them: plain decimals, no spaces, no comment. Such lines,
#: one after another, are read in bulk (:meth:`_Reader.goto_run`); every other line record by record.
_DECIMAL = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)"
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


#: Records read inside a bulk run of GOTOs (:meth:`_Reader.lines`): a PPRINT (its text: a comment event
#: between the rows) and a FEDRAT (read by :meth:`_Reader.fedrat` where it stands), neither with a
#: ``$`` (continuation or comment).
_PLAIN_PPRINT = re.compile(r"PPRINT/([^$]*)")
_PLAIN_FEDRAT = re.compile(r"FEDRAT/[^$]*")
_CYCLE_KINDS = {"DRILL": Pecking.NONE, "DEEP": Pecking.FULL_RETRACT, "BRKCHP": Pecking.CHIP_BREAK}


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class ClFrame:
    """A local frame from an ``MSYS/`` record: p_part = origin + rotation @ p_local (mm).

    Attributes
    ----------
    line : int — the MSYS record's line (0: the identity frame before any MSYS)
    origin : (3,) float — mm, part coordinates of the local origin
    rotation : (3, 3) float — columns are the local x, y, z axes in part coordinates (orthonormal, det +1)
    """

    line: int
    origin: FloatArray
    rotation: FloatArray

    def to_part(self, local: FloatArray) -> FloatArray:
        """(N, 3) local points (mm) → (N, 3) part points (mm)."""
        return rotate_rows(local, self.rotation) + self.origin      # the same bits in chunks of any size

    def to_local(self, part: FloatArray) -> FloatArray:
        """(N, 3) part points (mm) → (N, 3) local points (mm): the inverse of :meth:`to_part`."""
        return (np.asarray(part, dtype=np.float64).reshape(-1, 3) - self.origin) @ self.rotation


@dataclass(frozen=True, slots=True)
class ClCycle:
    """A ``CYCLE/`` record as read, lengths in mm, and the holes drilled under it.

    Attributes
    ----------
    line : int — the CYCLE record's line
    words : tuple of str — the record's arguments as written (``DRILL``, ``RAPTO``, ``3.0000`` …)
    cycle : DrillCycle — what each hole does (see :mod:`prs3_post.toolpaths.cycles`)
    holes : int — GOTOs under this cycle (until ``CYCLE/OFF``)
    """

    line: int
    words: tuple[str, ...]
    cycle: DrillCycle
    holes: int


@dataclass(frozen=True, slots=True)
class ClToolData:
    """A ``TLDATA/`` record as written (the cutter's shape: diameter, corner radius, … in file units)."""

    line: int
    words: tuple[str, ...]

    @property
    def diameter(self) -> float | None:
        """File units: the record's first number (``TLDATA/MILL,10.0,0.0,50.0`` → 10.0; a CL number, so
        ``1.0E+01`` too), when it is one and finite and > 0; else None."""
        numbers = [word.strip() for word in self.words if _NUMBER.match(word.strip())]
        value = float(numbers[0]) if numbers else math.nan
        return value if 0.0 < value < math.inf else None


@dataclass(frozen=True, slots=True)
class ClCounts:
    """What the file held, record by record: every record is counted once in ``by_word``.

    Attributes
    ----------
    records : int — records read (continuation lines joined; blank lines are not records)
    gotos : int — GOTO/ records (moves, arc ends and hole points)
    gotos_with_axis : int — of those, the ones that carry i,j,k
    moves : int — GOTO/, FROM/ and GOHOME/ records that became one row each
    arcs : int — CIRCLE/ records expanded
    arc_segments : int — rows the arcs became
    cycles : int — CYCLE/ records other than CYCLE/OFF
    cycle_holes : int — GOTOs drilled as holes
    cycle_rows : int — rows the holes became
    comments : int — PPRINT and ``$$`` comments (inline ones included)
    skipped : tuple of (str, int) — display-only and ignored records by word, skipped on purpose
    by_word : tuple of (str, int) — every record by major word (``$$`` for comment lines), sorted
    rows : int — rows of the toolpath
    """

    records: int
    gotos: int
    gotos_with_axis: int
    moves: int
    arcs: int
    arc_segments: int
    cycles: int
    cycle_holes: int
    cycle_rows: int
    comments: int
    skipped: tuple[tuple[str, int], ...]
    by_word: tuple[tuple[str, int], ...]
    rows: int


@dataclass(frozen=True, slots=True)
class ClFile:
    """A CL file read into a part-frame toolpath.

    Attributes
    ----------
    path : str — as given
    units : str — the file's length unit, ``mm`` or ``inch`` (everything here is converted to mm)
    toolpath : Toolpath — PART frame, mm; ``source`` is the 1-based line of each row's record
    counts : ClCounts
    frames : tuple of ClFrame — one per MSYS record, in order
    cycles : tuple of ClCycle
    tool_data : tuple of ClToolData
    end_lines : tuple of int — lines of END-OF-PATH and FINI records
    """

    path: str
    units: str
    toolpath: Toolpath
    counts: ClCounts
    frames: tuple[ClFrame, ...] = ()
    cycles: tuple[ClCycle, ...] = ()
    tool_data: tuple[ClToolData, ...] = ()
    end_lines: tuple[int, ...] = field(default=())


# --------------------------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------------------------
#: Lines read per chunk by :class:`ClStream` (a chunk's rows are handed out together).
CHUNK_LINES = 10_000
_PIECE_BYTES = 1 << 20


def read_cl(path: str, *, tolerance: float, units: str | None = None, ignore: frozenset[str] = frozenset(),
            circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE, apply_msys: bool = True) -> ClFile:
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
             ignore: frozenset[str] = frozenset(), circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE,
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
                 ignore: Iterable[str] = (), circle_tolerance: float = DEFAULT_CIRCLE_TOLERANCE,
                 chunk_lines: int = CHUNK_LINES, piece_bytes: int = _PIECE_BYTES, text: str | None = None,
                 apply_msys: bool = True):
        if units not in (None, "mm", "inch"):
            raise ValueError(f"ClStream: units must be 'mm', 'inch' or None, got {units!r}")
        if not (math.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"ClStream: tolerance must be > 0 mm, got {tolerance!r}")
        self.path, self.tolerance, self.units, self.circle_tolerance = path, tolerance, units, circle_tolerance
        self.ignored_words = tuple(ignore)             # as given (the program's header lists them so)
        self.ignore = frozenset(word.upper() for word in self.ignored_words)
        understood = sorted(self.ignore & {*_KNOWN_WORDS, *DISPLAY_WORDS})
        if understood:
            raise InputError(f"cannot ignore {', '.join(understood)}: the reader understands "
                             f"{'it' if len(understood) == 1 else 'them'} (only unknown major words can be ignored)",
                             path=path)
        self.chunk_lines, self.piece_bytes = max(1, int(chunk_lines)), max(1, int(piece_bytes))
        self._text = text                             # parse_cl: the text instead of the file
        self.apply_msys = apply_msys
        self.summary: ClFile | None = None
        self.sha256: str | None = None                 # of the bytes read, once read (the header's)

    def _pieces(self) -> Iterator[str]:
        """The file's text in pieces that end at line ends (a leading byte-order mark removed); once
        through, :attr:`sha256` is the hash of the bytes read (the last pass's: the records')."""
        digest = hashlib.sha256()
        if self._text is not None:
            digest.update(self._text.encode("utf-8"))
            yield self._text.removeprefix("\ufeff")
        else:
            for offset, piece in iter_pieces(self.path, "a CL file", self.piece_bytes, digest):
                if offset == 0 and piece.startswith(b"\xef\xbb\xbf"):
                    piece, offset = piece[3:], 3
                yield _text(piece, self.path, offset)
        self.sha256 = digest.hexdigest()

    def __iter__(self) -> Iterator[Toolpath]:
        file_units = _file_units(_unit_records(self._pieces(), self.path), self.path, self.units)
        reader = _Reader(self.path, MM_PER_INCH if file_units == "inch" else 1.0, self.ignore, self.tolerance,
                         self.circle_tolerance, self.apply_msys)
        number = 1
        for lines in line_chunks(self._pieces(), self.chunk_lines):
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


def join_toolpaths(parts: list[Toolpath]) -> Toolpath:
    """One toolpath of consecutive chunks (each chunk's events count rows from its own start)."""
    events: list[Event] = []
    rows = 0
    for part in parts:
        events += [Event(before=e.before + rows, kind=e.kind, value=e.value, text=e.text) for e in part.events]
        rows += len(part)
    if not parts:
        return Toolpath(kind=np.zeros(0, dtype=np.int64), tip=np.zeros((0, 3)), axis=np.zeros((0, 3)),
                        feed=np.zeros(0), source=np.zeros(0, dtype=np.int64))
    return Toolpath(kind=np.concatenate([p.kind for p in parts]), tip=np.concatenate([p.tip for p in parts]),
                    axis=np.concatenate([p.axis for p in parts]), feed=np.concatenate([p.feed for p in parts]),
                    source=np.concatenate([p.source for p in parts]), events=tuple(events),
                    source_file=parts[0].source_file)


# --------------------------------------------------------------------------------------------
# Records
# --------------------------------------------------------------------------------------------
class _Record(NamedTuple):
    line: int
    word: str                   # major word, upper case ("$$" for a comment line)
    rest: str | None            # the text after the slash (None without one; PPRINT: its text)
    text: str                   # the record as written (continuations joined), for messages
    comment: str | None         # inline $$ comment

    @property
    def args(self) -> tuple[str, ...]:
        """The arguments, stripped, as written (split on demand: GOTOs are read without it)."""
        return () if self.rest is None else tuple(arg.strip() for arg in self.rest.split(","))


def _text(data: bytes, path: str, offset: int = 0) -> str:
    """The text of (a piece of) a file; binary data and non-UTF-8 are refused (``offset``: of the piece).
    The control bytes are looked for by csrc/lex.c's one pass where it was built, else by numpy."""
    from prs3_post.core import native  # ctypes: loaded only where a file is read

    scanned = native.scan_text(data)
    if scanned is None:
        codes = np.frombuffer(data, dtype=np.uint8)
        control = np.flatnonzero(((codes < 32) & (codes != 9) & (codes != 10) & (codes != 13)) | (codes == 127))
        at = int(control[0]) if len(control) else -1
    else:
        at = scanned[0]
    if at >= 0:
        raise InputError(f"not a CL file: binary data (byte 0x{data[at]:02x} at offset {offset + at})", path=path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a CL file: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                         f"{offset + exc.start})", path=path) from exc


def _split_comment(line: str) -> tuple[str, str | None]:
    at = line.find("$$")
    if at < 0:
        return line, None
    return line[:at], line[at + 2:].strip()


#: Characters of a record (continuation lines joined) at most: far more than any CAM system writes
#: (a GOTO/ of six 20-digit numbers is about 130), few enough that a bad file is refused at once. The
#: CAM G-code reader holds a block (its code, without comments) to the same.
MAX_RECORD_CHARS = 65_536


class _Assembler:
    """Lines → records: continuations (a trailing single ``$``) joined, ``$$`` comments split off."""

    __slots__ = ("comment", "path", "pending", "size", "start")

    def __init__(self, path: str):
        self.path = path
        self.pending: list[str] = []
        self.size = 0                                # characters of the pending record so far
        self.start = 0
        self.comment: str | None = None

    def push(self, number: int, raw: str) -> _Record | None:
        """The record that line ``number`` completes, or None (blank line, or continued)."""
        code, comment = _split_comment(raw)
        code = code.strip()
        if not self.pending:
            self.start = number
            if not code:
                return None if comment is None else _Record(number, "$$", None, raw.strip(), comment)
        if comment is not None:
            self.comment = comment if self.comment is None else f"{self.comment} {comment}"
        self.size += len(code)
        if self.size > MAX_RECORD_CHARS:                 # before any work on it (a GOTO of millions of values)
            raise InputError(f"a record of {self.size:,} characters or more: longer than any CL record may be "
                             f"({MAX_RECORD_CHARS:,} at most); found {_quote(''.join(self.pending) + code)}",
                             path=self.path, line=self.start)
        if code.endswith("$"):
            self.pending.append(code[:-1])
            return None
        self.pending.append(code)
        joined = "".join(self.pending)
        comment, self.comment = self.comment, None
        self.pending, self.size = [], 0
        return _split(self.start, joined, comment)

    def close(self) -> None:
        """The end of the file: a continued record there is truncated."""
        if self.pending:
            raise InputError(f"truncated record: {_quote(''.join(self.pending))} continues with '$' but the file "
                             "ends (a continued record needs its next line)", path=self.path, line=self.start)


def _split(line: int, code: str, comment: str | None) -> _Record:
    word, slash, rest = code.partition("/")
    word = word.strip().upper()
    if word == "PPRINT" or (not slash and code.upper().startswith("PPRINT ")):
        text = rest if slash else code[len("PPRINT"):]
        return _Record(line, "PPRINT", text.strip(), code, comment)
    return _Record(line, word, rest if slash else None, code, comment)


def _quote(text: str, limit: int = 60) -> str:
    text = text.strip()
    return f"'{text[:limit]}...'" if len(text) > limit else f"'{text}'"


#: A line that may start a UNITS/ or FEDRAT/ record (the records that set the file's length unit).
_UNIT_LINE = re.compile(r"^[ \t]*(?:UNITS|FEDRAT)[ \t]*/", re.MULTILINE | re.IGNORECASE)


def _unit_records(pieces: Iterator[str], path: str) -> list[_Record]:
    """The UNITS/ and FEDRAT/ records of the whole file, found without reading every record (a FEDRAT/
    line that repeats an earlier one word for word, without ``$``, is left out: its feed unit is known
    already, and only the first line of each unit is used)."""
    found: list[_Record] = []
    first_line = 1
    carry, carry_line = "", 0                        # a continued record cut by a piece's end
    fedrat_lines: set[str] = set()                   # whole FEDRAT/ lines read already
    for piece in pieces:
        text = carry + piece
        if carry:
            first_line, carry = carry_line, ""
        number, counted_to = first_line, 0
        for match in _unit_lines(text):
            fedrat = match[0].lstrip(" \t").upper().startswith("F")
            if fedrat:
                end = text.find("\n", match.start())
                line = text[match.start():] if end < 0 else text[match.start():end]
                if "$" in line or end < 0:
                    fedrat = False                       # a continued record, or the piece's last line: read it
                elif line in fedrat_lines:
                    continue
            # line numbers and lines are taken from the match on, never from the piece's start: a piece
            # with many FEDRAT/ records costs linear, not quadratic, time
            number += text.count("\n", counted_to, match.start())
            counted_to = match.start()
            assembler = _Assembler(path)
            for offset, raw in enumerate(_lines_from(text, match.start())):
                record = assembler.push(number + offset, raw)
                if record is not None:
                    found.append(record)
                    if fedrat:
                        fedrat_lines.add(line)
                    break
            else:
                carry, carry_line = text[match.start():], number
                break
        if not carry:
            first_line += text.count("\n")
    return found


def _unit_lines(text: str) -> Iterator[re.Match[str]]:
    """``_UNIT_LINE.finditer(text)``, faster: in ASCII text only the lines where ``units`` or ``fedrat``
    (any case) occurs are tried (the pattern's scan of every line start is what the reader's first pass
    would spend its time on)."""
    if not text.isascii():                          # lower() keeps every position only in ASCII
        yield from _UNIT_LINE.finditer(text)
        return
    lower = text.lower()
    starts: set[int] = set()
    for word in ("units", "fedrat"):
        at = lower.find(word)
        while at >= 0:
            starts.add(text.rfind("\n", 0, at) + 1)
            at = lower.find(word, at + len(word))
    for start in sorted(starts):
        match = _UNIT_LINE.match(text, start)
        if match is not None:
            yield match


def _lines_from(text: str, start: int) -> Iterator[str]:
    """The lines of ``text`` from ``start`` on, without line ends (a final line end ends the last line)."""
    while start < len(text):
        end = text.find("\n", start)
        if end == -1:
            yield text[start:]
            return
        yield text[start:end]
        start = end + 1


def _file_units(records: list[_Record], path: str, caller: str | None) -> str:
    """The file's length unit: UNITS/, else the caller's, else implied by the feed units, else mm."""
    declared: tuple[str, int] | None = None
    feed_units: dict[str, int] = {}
    for record in records:
        if record.word == "UNITS":
            if len(record.args) != 1 or record.args[0].upper() not in _UNIT_WORDS:
                raise InputError(f"UNITS/ expects one of MM, INCHES; found {_quote(record.text)}",
                                 path=path, line=record.line)
            unit = _UNIT_WORDS[record.args[0].upper()]
            if declared is not None and declared[0] != unit:
                raise InputError(f"UNITS/{record.args[0]} contradicts UNITS/ at line {declared[1]} "
                                 f"({declared[0]}): one length unit per file", path=path, line=record.line)
            declared = (unit, record.line)
        elif record.word == "FEDRAT":
            for arg in record.args:
                if arg.upper() in _FEED_UNITS:
                    feed_units.setdefault("inch" if arg.upper().startswith("I") else "mm", record.line)
    if declared is not None:
        if caller is not None and caller != declared[0]:
            raise InputError(f"the file says UNITS/ {declared[0]} but {caller} was asked for: leave the unit out "
                             "or give the file's own", path=path, line=declared[1])
        return declared[0]
    if caller is not None:
        return caller
    if len(feed_units) == 2:
        raise InputError(f"feeds in both MMPM/MMPR (line {feed_units['mm']}) and IPM/IPR (line "
                         f"{feed_units['inch']}) and no UNITS/ record: the length unit of the file is "
                         "ambiguous; give it (mm or inch)", path=path)
    return "inch" if "inch" in feed_units else "mm"


def _number(text: str, what: str) -> float | str:
    """A float, or an error text."""
    if not _NUMBER.match(text):
        return f"{what}: {text!r} is not a number (expected a decimal like -12.5, .5 or 1.5E+02)"
    value = float(text)
    if not math.isfinite(value):
        return f"{what}: {_quote(text, 40)} is too large to be a finite number"
    return value


# --------------------------------------------------------------------------------------------
# Interpretation
# --------------------------------------------------------------------------------------------
@dataclass(slots=True)
class _Arc:
    line: int
    centre: FloatArray          # mm, local frame
    axis: FloatArray            # unit, local frame, as written (the tool goes clockwise about it)
    radius: float               # mm
    text: str


@dataclass(slots=True)
class _ActiveCycle:
    line: int
    words: tuple[str, ...]
    cycle: DrillCycle
    holes: int = 0


class _Reader:
    """The modal state of a CL file as the records go by; rows in the LOCAL frame (mm) with their frame."""

    def __init__(self, path: str, scale: float, ignore: frozenset[str], tolerance: float, circle_tolerance: float,
                 apply_msys: bool = True):
        self.path, self.scale, self.ignore, self.apply_msys = path, scale, ignore, apply_msys
        self.tolerance, self.circle_tolerance = tolerance, circle_tolerance
        self.line = 0
        # rows, flat (x, y, z per row): stdlib arrays append a row far faster than numpy blocks
        self.tip = array("d")                         # mm, local frame
        self.axis = array("d")                        # unit, local frame
        self.kind = array("q")
        self.feed = array("d")
        self.source = array("q")
        self.frame_of = array("q")                    # index into self.frames
        self.rows = 0                                 # rows so far (all chunks)
        self.chunk_start = 0                          # row index of the current chunk's first row
        self.events: list[Event] = []                 # this chunk's, ``before`` counted from its start
        self.assembler = _Assembler(path)
        self.frames: list[ClFrame] = [ClFrame(0, np.zeros(3), np.eye(3))]
        self.position: tuple[float, float, float] | None = None    # mm, local frame of the current MSYS
        self.tool_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
        self.rapid_next = False
        self.feed_value: float | None = None          # mm/min, or mm/rev when per_rev
        self.per_rev = False
        self.spindle_rpm = 0.0
        self.spindle_on = False
        self.spindle_kind = EventKind.SPINDLE_ON       # the direction: SPINDLE_ON_CCW for CCLW
        self.multax_on: bool | None = None
        self.arc: _Arc | None = None
        self.cycle: _ActiveCycle | None = None
        self.cycles: list[ClCycle] = []
        self.tool_data: list[ClToolData] = []
        self.end_lines: list[int] = []
        self.finished = False                         # FINI seen
        self.after_end = False                        # END-OF-PATH or FINI seen last
        self.by_word: Counter[str] = Counter()
        self.skipped: Counter[str] = Counter()
        #: plain FEDRAT lines read in bulk runs (:meth:`mark`) → the feed and per_rev they set
        self.fedrat_seen: dict[str, tuple[float | None, bool]] = {}
        self.records = self.gotos = self.gotos_with_axis = self.moves = 0
        self.arcs = self.arc_segments = self.cycle_holes = self.cycle_rows = self.comments = 0

    # ---- helpers
    def error(self, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.line)

    def numbers(self, record: _Record, args: tuple[str, ...] | None = None) -> list[float]:
        rest = record.rest
        if args is None and rest is not None and _NUMBER_LIST.match(rest):   # the common case, checked at once
            values = [float(text) for text in rest.split(",")]
            if "e" not in rest and "E" not in rest and len(rest) < 300:   # else it may overflow to inf
                return values
            if all(math.isfinite(v) for v in values):
                return values
        values = []
        for index, text in enumerate(record.args if args is None else args, start=1):
            if not text:
                raise self.error(f"truncated record {_quote(record.text)}: value {index} of {record.word}/ is empty")
            value = _number(text, f"{record.word}/ value {index}")
            if isinstance(value, str):
                raise self.error(value)
            values.append(value)
        return values

    def lengths(self, record: _Record, values: list[float], indices: Iterable[int]) -> None:
        """Refuse a coordinate or length ``values[i]`` (file units) beyond :data:`MAX_COORDINATE_MM`."""
        for index in indices:
            if not abs(values[index]) * self.scale <= MAX_COORDINATE_MM:        # inf and nan too
                raise self.error(self.length_message(record.args[index], f"{record.word}/ value {index + 1}"))

    def length_message(self, text: str, what: str) -> str:
        unit = "mm" if self.scale == 1.0 else "inch"
        return (f"{what}: {_quote(text, 40)} is out of range (allowed: within ±{MAX_COORDINATE_MM / self.scale:g} "
                f"{unit}; is the file in the right units?)")

    def unit_axis(self, values: list[float], what: str) -> tuple[float, float, float]:
        i, j, k = values
        length = math.sqrt(i * i + j * j + k * k)
        if length == 1.0:
            return i, j, k
        shown = ", ".join(f"{v:g}" for v in values)
        if length == 0.0:
            raise self.error(f"{what}: zero tool vector ({shown}); i,j,k must be a unit vector from the tool tip "
                             "toward the spindle")
        if abs(length - 1.0) > AXIS_LENGTH_TOLERANCE:
            raise self.error(f"{what}: tool vector ({shown}) has length {length:.6g}; i,j,k must be a unit vector "
                             f"(length 1 within {AXIS_LENGTH_TOLERANCE:g})")
        return i / length, j / length, k / length

    def add_row(self, point: tuple[float, float, float], axis: tuple[float, float, float], kind: int, feed: float,
                source: int) -> None:
        self.tip.extend(point)
        self.axis.extend(axis)
        self.kind.append(kind)
        self.feed.append(feed)
        self.source.append(source)
        self.frame_of.append(len(self.frames) - 1)
        self.rows += 1
        self.position = point

    def add_rows(self, tip: FloatArray, axis: tuple[float, float, float] | FloatArray, kind: int | np.ndarray,
                 feed: float | np.ndarray, source: int | np.ndarray) -> None:
        tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
        n = len(tip)
        self.tip.frombytes(tip.tobytes())
        self.axis.frombytes(np.broadcast_to(np.asarray(axis, dtype=np.float64), (n, 3)).tobytes())
        self.kind.frombytes(np.broadcast_to(np.asarray(kind, dtype=np.int64), (n,)).tobytes())
        self.feed.frombytes(np.broadcast_to(np.asarray(feed, dtype=np.float64), (n,)).tobytes())
        self.source.frombytes(np.broadcast_to(np.asarray(source, dtype=np.int64), (n,)).tobytes())
        self.frame_of.frombytes(np.full(n, len(self.frames) - 1, dtype=np.int64).tobytes())
        self.rows += n
        x, y, z = tip[-1].tolist()
        self.position = (x, y, z)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        self.events.append(Event(before=self.rows - self.chunk_start, kind=kind, value=value, text=text))

    def current_feed(self) -> float:
        """mm/min of a feed move now."""
        if self.feed_value is None:
            raise self.error("feed move before any FEDRAT/: the feed rate is unknown (give FEDRAT/ first, or "
                             "RAPID before the move)")
        if not self.per_rev:
            return self.feed_value
        if not (self.spindle_on and self.spindle_rpm > 0):
            raise self.error("feed per revolution (MMPR/IPR) while the spindle is off: the feed rate is unknown "
                             "(give SPINDL/ with a speed first, or a feed per minute)")
        return self.feed_per_minute(self.feed_value * self.spindle_rpm,
                                    f"the feed per revolution at {self.spindle_rpm:g} rpm")

    def feed_per_minute(self, feed: float, what: str) -> float:
        """``feed`` (mm/min) if within :data:`FEED_RANGE_MM_MIN`, else the error naming ``what`` made it."""
        if not MIN_FEED_MM_MIN <= feed <= MAX_FEED_MM_MIN:
            raise self.error(f"{what} is {feed:.6g} mm/min (allowed: "
                             f"{MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} mm/min)")
        return feed

    # ---- dispatch
    def record(self, record: _Record) -> None:
        self.line = record.line
        self.records += 1
        word = record.word
        if self.finished and not _TRAILER.match(record.text):
            raise self.error(f"{_quote(record.text)} after FINI: FINI ends the CL data")
        if word != "$$" and record.comment is not None:
            self.comments += 1
            self.event(EventKind.COMMENT, text=record.comment)
        if self.arc is not None and word not in ("GOTO", "$$", "PPRINT") and word not in DISPLAY_WORDS:
            raise self.error(f"CIRCLE/ at line {self.arc.line} must be followed by its end GOTO/, found "
                             f"{_quote(record.text)}")
        handler = _HANDLERS.get(word)
        if handler is not None:
            self.by_word[word] += 1
            self.after_end = False
            handler(self, record)
        elif word in DISPLAY_WORDS or word in self.ignore:
            self.by_word[word] += 1
            self.skipped[word] += 1
        elif _TRAILER.match(record.text):
            if not self.after_end:
                raise self.error(f"listing trailer {_quote(record.text)} before END-OF-PATH/FINI: not CL data")
            self.by_word[LISTING_TRAILER] += 1
            self.skipped[LISTING_TRAILER] += 1
        else:
            raise self.error(
                f"unknown major word {word[:40]!r} in {_quote(record.text)} (understood: {', '.join(_KNOWN_WORDS)}; "
                f"display-only, skipped: {', '.join(sorted(DISPLAY_WORDS))}; other words can be ignored on purpose "
                "by listing them as words to ignore)")

    # ---- motion
    def goto(self, record: _Record) -> None:
        values = self.numbers(record)
        if len(values) not in (3, 6):
            raise self.error(f"{record.word}/ has {len(values)} values: expected 3 (x,y,z) or 6 (x,y,z,i,j,k); "
                             f"found {_quote(record.text)}")
        if len(values) == 6 and self.multax_on is False:
            raise self.error(f"{record.word}/ with i,j,k under MULTAX/OFF: give x,y,z only, or MULTAX/ON first")
        self.lengths(record, values, range(3))
        scale = self.scale
        point = (values[0] * scale, values[1] * scale, values[2] * scale)
        if len(values) == 6:
            axis = self.unit_axis(values[3:], f"{record.word}/")
        else:
            axis = self.tool_axis
        if record.word == "GOTO":
            self.gotos += 1
            self.gotos_with_axis += len(values) == 6
        rapid = self.rapid_next or record.word != "GOTO"
        self.rapid_next = False                        # RAPID applies to the next motion record only
        if self.arc is not None:
            self.end_arc(point, axis, len(values) == 6)
            return
        self.tool_axis = axis
        if self.cycle is not None and record.word == "GOTO":
            self.hole(point, axis)
            return
        if self.cycle is not None:
            raise self.error(f"{record.word}/ inside the CYCLE/ of line {self.cycle.line}: close it with CYCLE/OFF "
                             "first")
        self.moves += 1
        if rapid:
            self.add_row(point, axis, _RAPID, 0.0, record.line)
        else:
            self.add_row(point, axis, _FEED, self.current_feed(), record.line)

    def rapid(self, record: _Record) -> None:
        if record.args:
            raise self.error(f"RAPID takes no values; found {_quote(record.text)}")
        self.rapid_next = True

    def circle(self, record: _Record) -> None:
        values = self.numbers(record)
        if len(values) < 7:
            raise self.error(f"CIRCLE/ has {len(values)} values: expected at least 7 (xc,yc,zc,i,j,k,r); found "
                             f"{_quote(record.text)}")
        self.lengths(record, values, (0, 1, 2, 6))
        if self.cycle is not None:
            raise self.error(f"CIRCLE/ inside the CYCLE/ of line {self.cycle.line}: close it with CYCLE/OFF first")
        if self.rapid_next:
            raise self.error("CIRCLE/ after RAPID: an arc is cut at the feed rate (put RAPID before a GOTO/ only)")
        if self.position is None:
            raise self.error("CIRCLE/ before any move: the arc has no start point")
        normal = np.array(values[3:6])
        length = float(np.linalg.norm(normal))
        if not length > 0:
            raise self.error("CIRCLE/ axis i,j,k is the zero vector: it must give the circle's axis direction")
        radius = values[6] * self.scale
        if not radius > 0:
            raise self.error(f"CIRCLE/ radius must be > 0, got {values[6]:g}")
        self.current_feed()
        self.arc = _Arc(record.line, np.array(values[:3]) * self.scale, normal / length, radius, record.text)

    def end_arc(self, end_point: tuple[float, float, float], axis: tuple[float, float, float], has_axis: bool) -> None:
        arc = self.arc
        assert arc is not None and self.position is not None  # only called with an arc pending
        if has_axis and math.dist(axis, self.tool_axis) > 1e-9:
            raise self.error(f"the end GOTO/ of the CIRCLE/ at line {arc.line} changes the tool axis: an arc is "
                             "cut with a constant tool axis (give the end point without i,j,k, or the same i,j,k)")
        start, end = np.array(self.position), np.array(end_point)
        for name, point in (("start", start), ("end", end)):
            offset = point - arc.centre
            height = float(offset @ arc.axis)
            radial = float(np.linalg.norm(offset - height * arc.axis))
            off_circle = radial - arc.radius
            if radial == 0.0:
                raise self.error(f"arc {name} point lies on the axis of CIRCLE/ at line {arc.line}, where an arc has "
                                 "no direction; start and end must lie on the circle")
            if abs(off_circle) > self.circle_tolerance:
                shown = ", ".join(f"{v / self.scale:.4f}" for v in point)
                raise self.error(
                    f"arc {name} point ({shown}) is {abs(off_circle):.4f} mm "
                    f"{'outside' if off_circle > 0 else 'inside'} "
                    f"the circle of CIRCLE/ at line {arc.line} (radius {arc.radius / self.scale:g}); start and end "
                    f"must lie on the circle within {self.circle_tolerance:g} mm")
            if name == "start":
                start_height = height
            elif abs(height - start_height) > self.circle_tolerance:
                raise self.error(
                    f"arc end point is {abs(height - start_height):.4f} mm off the plane of the arc's start, along "
                    f"the axis of CIRCLE/ at line {arc.line}; start and end must lie on one circle within "
                    f"{self.circle_tolerance:g} mm")
        sweep = arc_sweep(arc.centre, -arc.axis, start, end)
        count = arc_segment_count(max(float(np.linalg.norm(start - arc.centre)), arc.radius), sweep,
                                  tolerance=self.tolerance)
        if count > MAX_ARC_SEGMENTS:
            raise self.error(f"the arc of CIRCLE/ at line {arc.line} (radius {arc.radius / self.scale:g}) needs "
                             f"{count:,} segments within {self.tolerance:g} mm, more than {MAX_ARC_SEGMENTS:,}: "
                             "the circle is far larger than any part")
        # The corpus convention: the tool moves clockwise about (i, j, k), i.e. counter-clockwise about −(i, j, k).
        points = arc_points_3d(arc.centre, -arc.axis, start, end, tolerance=self.tolerance)[1:]
        source = np.full(len(points), arc.line, dtype=np.int64)
        source[-1] = self.line
        self.add_rows(points, self.tool_axis, int(MoveKind.FEED), self.current_feed(), source)
        self.arcs += 1
        self.arc_segments += len(points)
        self.arc = None

    def hole(self, point: tuple[float, float, float], axis: tuple[float, float, float]) -> None:
        assert self.cycle is not None  # only called inside a cycle
        tip, kind, bottom = drill_rows(np.array([point]), np.array([axis]), self.cycle.cycle)
        feed = np.where(kind == int(MoveKind.FEED), self.cycle.cycle.feed, 0.0)
        first = self.rows
        self.add_rows(tip, axis, kind, feed, self.line)
        if self.cycle.cycle.dwell > 0:
            self.events.append(Event(before=first - self.chunk_start + int(bottom[0]) + 1,
                                     kind=EventKind.DWELL, value=self.cycle.cycle.dwell))
        self.cycle.holes += 1
        self.cycle_holes += 1
        self.cycle_rows += len(tip)

    # ---- modal state
    def fedrat(self, record: _Record) -> None:
        unit: str | None = None
        values: list[str] = []
        for arg in record.args:
            if arg.upper() in _FEED_UNITS:
                if unit is not None:
                    raise self.error(f"FEDRAT/ with two units ({unit}, {arg.upper()}): give one")
                unit = arg.upper()
            else:
                values.append(arg)
        if len(values) != 1:
            raise self.error(f"FEDRAT/ expects one value and an optional unit (MMPM, IPM, MMPR, IPR) before or after "
                             f"it; found {_quote(record.text)}")
        (value,) = self.numbers(record, tuple(values))
        if not value > 0:
            raise self.error(f"FEDRAT/ must be > 0, got {values[0]}")
        if unit is None:
            self.feed_value, self.per_rev = value * self.scale, False
        else:
            factor, per_rev = _FEED_UNITS[unit]
            self.feed_value, self.per_rev = value * factor, per_rev
        if not self.per_rev and self.feed_value > MAX_FEED_MM_MIN:
            raise self.error(f"FEDRAT/ {values[0]} is {self.feed_value:.6g} mm/min, "
                             f"more than {MAX_FEED_MM_MIN:g} mm/min")
        if not self.per_rev and self.feed_value < MIN_FEED_MM_MIN:
            raise self.error(f"FEDRAT/ {values[0]} is {self.feed_value:.6g} mm/min, less than {MIN_FEED_MM_MIN:g} "
                             f"mm/min (allowed: {MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} mm/min)")

    def multax(self, record: _Record) -> None:
        setting = record.args[0].upper() if record.args else "ON"
        if len(record.args) > 1 or setting not in ("ON", "OFF"):
            raise self.error(f"MULTAX expects nothing, ON or OFF; found {_quote(record.text)}")
        self.multax_on = setting == "ON"

    def tlaxis(self, record: _Record) -> None:
        values = self.numbers(record)
        if len(values) != 3:
            raise self.error(f"TLAXIS/ has {len(values)} values: expected 3 (i,j,k); found {_quote(record.text)}")
        self.tool_axis = self.unit_axis(values, "TLAXIS/")

    def msys(self, record: _Record) -> None:
        values = self.numbers(record)
        if len(values) != 9:
            raise self.error(f"MSYS/ has {len(values)} values: expected 9 (origin x,y,z, x axis i,j,k, y axis i,j,k); "
                             f"found {_quote(record.text)}")
        x_axis, y_axis = np.array(values[3:6]), np.array(values[6:9])
        x_len, y_len, dot = float(np.linalg.norm(x_axis)), float(np.linalg.norm(y_axis)), float(x_axis @ y_axis)
        if abs(x_len - 1) > FRAME_TOLERANCE or abs(y_len - 1) > FRAME_TOLERANCE or abs(dot) > FRAME_TOLERANCE:
            raise self.error(
                f"MSYS/ axes are not orthogonal unit vectors: x axis ({', '.join(f'{v:g}' for v in values[3:6])}), "
                f"y axis ({', '.join(f'{v:g}' for v in values[6:9])}) have |x| = {x_len:.6g}, |y| = {y_len:.6g}, "
                f"x·y = {dot:.6g} (valid: |x| = |y| = 1 and x·y = 0 within {FRAME_TOLERANCE:g})")
        self.lengths(record, values, range(3))
        x_axis = x_axis / x_len
        y_axis = y_axis - (y_axis @ x_axis) * x_axis
        y_axis = y_axis / np.linalg.norm(y_axis)
        rotation = np.column_stack([x_axis, y_axis, np.cross(x_axis, y_axis)])
        self.frames.append(ClFrame(record.line, np.array(values[:3]) * self.scale, rotation))
        if not self.apply_msys:             # points stay as written: the frame is only recorded
            return
        previous = self.frames[-2]
        if self.position is not None:       # the same place, now seen from the new frame
            x, y, z = self.frames[-1].to_local(previous.to_part(np.array(self.position)))[0].tolist()
            self.position = (x, y, z)
        i, j, k = (rotation.T @ (previous.rotation @ np.array(self.tool_axis))).tolist()
        self.tool_axis = (i, j, k)

    def units(self, record: _Record) -> None:
        """Checked and applied to the whole file before the records are read (see _file_units)."""

    def tool_change(self, record: _Record) -> None:
        args = record.args
        if record.word == "LOAD" or record.word == "SELECT":
            if not args or args[0].upper() != "TOOL":
                raise self.error(f"{record.word}/ expects TOOL,n; found {_quote(record.text)}")
            args = args[1:]
        if not args:
            raise self.error(f"{record.word}/ without a tool number; found {_quote(record.text)}")
        (number,) = self.numbers(record, args[:1])
        if number < 0 or number != int(number):
            raise self.error(f"{record.word}/ tool number must be a whole number ≥ 0, got {args[0]}")
        if record.word != "SELECT":
            shape = f": TLDATA/{','.join(self.tool_data[-1].words)}" if self.tool_data else ""
            self.event(EventKind.TOOL_CHANGE, value=float(number), text=f"tool {int(number)}{shape}")

    def tldata(self, record: _Record) -> None:
        self.tool_data.append(ClToolData(record.line, record.args))

    def spindl(self, record: _Record) -> None:
        words = [arg.upper() for arg in record.args]
        if words in (["OFF"],):
            self.spindle_on = False
            self.event(EventKind.SPINDLE_OFF)
            return
        if words == ["ON"]:
            if not self.spindle_rpm > 0:
                raise self.error("SPINDL/ON before any spindle speed: give SPINDL/RPM,s,CLW first")
            self.spindle_on = True
            self.event(self.spindle_kind, value=self.spindle_rpm)
            return
        direction = "CLW"
        speed: list[str] = []
        for arg, upper in zip(record.args, words, strict=True):
            if upper in ("CLW", "CCLW"):
                direction = upper
            elif upper == "RPM":
                continue
            elif _NUMBER.match(arg) or not upper.isalpha():
                speed.append(arg)
            else:
                raise self.error(f"SPINDL/ word {arg!r} is not understood (valid: RPM, a speed, CLW, CCLW; or ON, "
                                 "OFF alone)")
        if len(speed) != 1:
            raise self.error(f"SPINDL/ expects one speed in rpm; found {_quote(record.text)}")
        (rpm,) = self.numbers(record, tuple(speed))
        if not rpm > 0:
            raise self.error(f"SPINDL/ speed must be > 0 rpm, got {speed[0]}")
        if rpm > MAX_SPINDLE_RPM:
            raise self.error(f"SPINDL/ speed {speed[0]} is more than {MAX_SPINDLE_RPM:g} rpm (allowed: above 0 to "
                             f"{MAX_SPINDLE_RPM:g} rpm)")
        self.spindle_rpm, self.spindle_on = rpm, True
        self.spindle_kind = EventKind.SPINDLE_ON_CCW if direction == "CCLW" else EventKind.SPINDLE_ON
        self.event(self.spindle_kind, value=rpm)

    def coolnt(self, record: _Record) -> None:
        words = {arg.upper() for arg in record.args}
        if words == {"OFF"}:
            self.event(EventKind.COOLANT_OFF)
        elif words and words <= {"ON", "FLOOD"}:
            self.event(EventKind.COOLANT_ON, text=Coolant.FLOOD.value)
        elif words in ({"MIST"}, {"MIST", "ON"}):
            self.event(EventKind.COOLANT_ON, text=Coolant.MIST.value)
        else:
            raise self.error(f"COOLNT/ expects ON, FLOOD, MIST or OFF; found {_quote(record.text)}")

    def cycle_record(self, record: _Record) -> None:
        words = [arg.upper() for arg in record.args]
        if words == ["OFF"]:
            if self.cycle is None:
                raise self.error("CYCLE/OFF without an active CYCLE/")
            active = self.cycle
            self.cycles.append(ClCycle(active.line, active.words, active.cycle, active.holes))
            self.cycle = None
            return
        if self.cycle is not None:
            raise self.error(f"CYCLE/ while the CYCLE/ of line {self.cycle.line} is active: close it with CYCLE/OFF")
        self.cycle = _ActiveCycle(record.line, record.args, self.parse_cycle(record, words))

    def parse_cycle(self, record: _Record, words: list[str]) -> DrillCycle:
        pecking: Pecking | None = None
        params: dict[str, float] = {}
        feed: float | None = None
        index = 0
        while index < len(words):
            word = words[index]
            if word in _CYCLE_KINDS:
                kind = _CYCLE_KINDS[word]
                if pecking is not None and kind is not Pecking.NONE and pecking is not Pecking.NONE:
                    raise self.error(f"CYCLE/ with two kinds of pecking; found {_quote(record.text)}")
                pecking = kind if pecking in (None, Pecking.NONE) else pecking
                index += 1
                continue
            if word in ("RAPTO", "FEDTO", "RTRCTO", "STEP", "DWELL", *_FEED_UNITS):
                if index + 1 >= len(words):
                    raise self.error(f"truncated record {_quote(record.text)}: {word} without its value")
                (value,) = self.numbers(record, (record.args[index + 1],))
                if word in _FEED_UNITS:
                    factor, per_rev = _FEED_UNITS[word]
                    feed = value * factor * (self.spindle_rpm if per_rev else 1.0)
                    if per_rev and not self.spindle_rpm > 0:
                        raise self.error(f"CYCLE/ feed in {word} before any spindle speed: give SPINDL/ first")
                else:
                    if word != "DWELL" and not abs(value) * self.scale <= MAX_COORDINATE_MM:
                        raise self.error(self.length_message(record.args[index + 1], f"CYCLE/ {word}"))
                    params[word] = value
                index += 2
                continue
            raise self.error(f"CYCLE/ word {record.args[index]!r} is not understood (valid: DRILL, DEEP, BRKCHP, "
                             "RAPTO, FEDTO, RTRCTO, STEP, DWELL, MMPM, IPM, MMPR, IPR with their values; OFF)")
        if pecking is None:
            raise self.error(f"CYCLE/ without a kind (DRILL, DEEP or BRKCHP); found {_quote(record.text)}")
        for needed in ("RAPTO", "FEDTO"):
            if needed not in params:
                raise self.error(f"CYCLE/ without {needed}: the cycle needs RAPTO (clearance) and FEDTO (depth); "
                                 f"found {_quote(record.text)}")
        if params["RAPTO"] < 0 or params.get("RTRCTO", 0.0) < 0:
            raise self.error("CYCLE/ RAPTO and RTRCTO are heights above the hole point and must be ≥ 0")
        if feed is None:
            feed = self.current_feed()
        if not feed > 0:
            raise self.error("CYCLE/ feed must be > 0")
        feed = self.feed_per_minute(feed, "CYCLE/ feed")
        peck = params.get("STEP", 0.0) * self.scale
        if pecking is not Pecking.NONE and "STEP" in params and not peck > 0:
            raise self.error(f"CYCLE/ STEP must be > 0, got {params['STEP']:g}")
        if peck > 0 and (count := peck_count(abs(params["FEDTO"]) * self.scale, peck)) > MAX_PECKS:
            raise self.error(f"CYCLE/ STEP {params['STEP']:g} would drill FEDTO {abs(params['FEDTO']):g} in "
                             f"{count:,} pecks, more than {MAX_PECKS:,}: use a larger STEP")
        if params.get("DWELL", 0.0) < 0:
            raise self.error(f"CYCLE/ DWELL must be ≥ 0 s, got {params['DWELL']:g}")
        return DrillCycle(
            depth=abs(params["FEDTO"]) * self.scale, clearance=params["RAPTO"] * self.scale,
            retract=params.get("RTRCTO", params["RAPTO"]) * self.scale, feed=feed,
            pecking=pecking if peck > 0 else Pecking.NONE, peck=peck, dwell=params.get("DWELL", 0.0))

    def comment_record(self, record: _Record) -> None:
        self.comments += 1
        self.event(EventKind.COMMENT, text=(record.comment if record.word == "$$" else record.rest) or "")

    def stop(self, record: _Record) -> None:
        if record.args:
            raise self.error(f"{record.word} takes no values; found {_quote(record.text)}")
        self.event(EventKind.OPTIONAL_STOP if record.word == "OPSTOP" else EventKind.STOP)

    def end(self, record: _Record) -> None:
        if record.args:
            raise self.error(f"{record.word} takes no values; found {_quote(record.text)}")
        if self.cycle is not None:
            raise self.error(f"{record.word} while the CYCLE/ of line {self.cycle.line} is active: close it with "
                             "CYCLE/OFF first")
        self.end_lines.append(record.line)
        self.after_end = True
        self.finished = record.word == "FINI"

    # ---- result
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
        kind = np.full(len(run), _FEED, dtype=np.int64)
        if self.rapid_next:
            kind[0] = _RAPID
            self.rapid_next = False
        feed = np.zeros(len(run))
        pprints = [(b, index) for b, index in marks if lines[index].startswith("PPRINT/")]
        # where no PPRINT is too long (refused where it stands), the PPRINTs in one go: no feed changes there
        together = all(len(lines[index]) <= MAX_RECORD_CHARS for _, index in pprints)
        # the feed of the rows between the marks: the FEDRAT before them (read in order, for its errors)
        feeds = [mark for mark in marks if not lines[mark[1]].startswith("PPRINT/")] if together else marks
        for (a, _), (b, index) in itertools.pairwise([(0, -1), *feeds, (len(run), -1)]):
            rows = range(max(a, 1) if kind[0] == _RAPID else a, b)
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
            end_start = max(end_mark, 1) if int(kind[0]) == _RAPID else end_mark
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

    def close(self) -> None:
        """The end of the file: nothing may be left open."""
        self.assembler.close()
        if self.records == 0:
            raise InputError("not a CL file: no records (the file is empty)", path=self.path)
        if self.arc is not None:
            self.line = self.arc.line
            raise self.error("CIRCLE/ at the end of the file: its end GOTO/ is missing")
        if self.cycle is not None:
            self.line = self.cycle.line
            raise self.error("CYCLE/ is not closed with CYCLE/OFF before the end of the file")

    def take(self) -> Toolpath:
        """The rows and events since the last take, in the PART frame (events count from the chunk's start)."""
        local = np.frombuffer(self.tip, dtype=np.float64).reshape(-1, 3)
        axis_local = np.frombuffer(self.axis, dtype=np.float64).reshape(-1, 3)
        frame = np.frombuffer(self.frame_of, dtype=np.int64)
        if self.apply_msys and len(frame) and frame[0] == frame[-1] and (frame == frame[0]).all():   # one MSYS
            one = self.frames[int(frame[0])]
            tip, axis = _turned(local, one.rotation, one.origin), _turned(axis_local, one.rotation, None)
        else:
            tip, axis = local.copy(), axis_local.copy()
            for index in np.unique(frame) if self.apply_msys else ():   # one transform per MSYS, its rows at once
                rows = frame == index
                tip[rows] = _turned(local[rows], self.frames[index].rotation, self.frames[index].origin)
                axis[rows] = _turned(axis_local[rows], self.frames[index].rotation, None)
        events = tuple(self.events)                    # counted from the chunk's start already
        chunk = Toolpath(kind=np.frombuffer(self.kind, dtype=np.int64), tip=tip, axis=axis,
                         feed=np.frombuffer(self.feed, dtype=np.float64),
                         source=np.frombuffer(self.source, dtype=np.int64), events=events,
                         source_file=self.path)
        self.tip, self.axis, self.kind = array("d"), array("d"), array("q")
        self.feed, self.source, self.frame_of = array("d"), array("q"), array("q")
        self.events = []
        self.chunk_start = self.rows
        return chunk

    def summary(self, units: str) -> ClFile:
        """Everything but the rows (an empty toolpath): units, counts, frames, cycles, tool data, ends."""
        counts = ClCounts(
            records=self.records, gotos=self.gotos, gotos_with_axis=self.gotos_with_axis, moves=self.moves,
            arcs=self.arcs, arc_segments=self.arc_segments, cycles=len(self.cycles), cycle_holes=self.cycle_holes,
            cycle_rows=self.cycle_rows, comments=self.comments, skipped=tuple(sorted(self.skipped.items())),
            by_word=tuple(sorted(self.by_word.items())), rows=self.rows)
        return ClFile(path=self.path, units=units, toolpath=join_toolpaths([]), counts=counts,
                      frames=tuple(self.frames[1:]), cycles=tuple(self.cycles), tool_data=tuple(self.tool_data),
                      end_lines=tuple(self.end_lines))


def _turned(rows: FloatArray, rotation: FloatArray, origin: FloatArray | None) -> FloatArray:
    """(N, 3) ``rotate_rows(rows, rotation)`` (+ ``origin``): in C where it was built (the same bits, one pass)."""
    from prs3_post.core import native  # ctypes: loaded only where rows are read

    turned = native.rows_to_part(rows, rotation, origin)
    if turned is not None:
        return turned
    return rotate_rows(rows, rotation) if origin is None else rotate_rows(rows, rotation) + origin


_HANDLERS = {
    "GOTO": _Reader.goto, "FROM": _Reader.goto, "GOHOME": _Reader.goto, "RAPID": _Reader.rapid,
    "CIRCLE": _Reader.circle, "FEDRAT": _Reader.fedrat, "MULTAX": _Reader.multax, "TLAXIS": _Reader.tlaxis,
    "MSYS": _Reader.msys, "UNITS": _Reader.units, "LOADTL": _Reader.tool_change, "LOAD": _Reader.tool_change,
    "SELECT": _Reader.tool_change, "TLDATA": _Reader.tldata, "SPINDL": _Reader.spindl, "COOLNT": _Reader.coolnt,
    "CYCLE": _Reader.cycle_record, "PPRINT": _Reader.comment_record, "$$": _Reader.comment_record,
    "STOP": _Reader.stop, "OPSTOP": _Reader.stop, "END-OF-PATH": _Reader.end, "FINI": _Reader.end,
}
