"""What a CL file read holds (:class:`ClFile`): its frames, cycles, tool data and the count of every record."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from prs3_post.core.toolpath import Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.part.workplane import rotate_rows
from prs3_post.readers.cl.syntax import NUMBER
from prs3_post.toolpaths.cycles import DrillCycle


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
        numbers = [word.strip() for word in self.words if NUMBER.match(word.strip())]
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
