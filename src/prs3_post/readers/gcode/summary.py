"""What a G-code program read holds (:class:`GcodeFile`): its planes, cycles and the count of every line."""

from __future__ import annotations

from dataclasses import dataclass, field

from prs3_post.core.toolpath import Toolpath
from prs3_post.part.workplane import WorkPlane


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
