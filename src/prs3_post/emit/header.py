"""The program header: what a program was made from, written as comments and read back.

A program made by the main job opens with comment lines ``(key: value)`` that state everything
needed to rebuild its intent (the key order is fixed; ``machine file`` and ``dialect file`` only
appear for a machine or dialect given by path)::

    (program: prs3-post 0.1.0)
    (machine: patel2020 [Patel 2020 3-PRS head over an XY stage ...])
    (machine file: my/machine.toml)
    (dialect: linuxcnc)
    (dialect file: my/dialect.toml)
    (part: wedge.stl, units mm, up z, sha256 0f3a...)
    (face: 4, chosen automatically: inclination 26.5651 deg, normal [...], origin [...] mm)
    (setup: part origin at machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z)
    (operation: hole at face [u, v] [10.0000, 0.0000], [-10.0000, 5.0000] mm)
    (parameters: depth 8.000 mm, peck 3.000 mm, dwell 0.500 s, clearance 2.000 mm, ...)
    (tool: T1 diameter 6.000 mm, feed 300.0 mm/min, plunge 100.0 mm/min, spindle 3000 rpm, coolant flood)
    (tolerance: 0.002 mm)
    (units: mm, G93 inverse time: F = 1/minutes of each move)

With a tool table, a ``(tools: ...)`` entry follows ``tool``: each tool's number, diameter, its
table length and the length "TL" the IK used (``T1 diameter 6.000 mm, length 52.300 mm, IK length
172.300 mm``; tools joined by ``and``). A job of several operations writes, instead of ``face``,
``operation``, ``parameters`` and ``tool``: ``(tools: ...)`` after ``setup`` (without a tool table a
tool has no ``length`` item: its IK length is the machine's), ``(operations: N)``, and for each
operation K ``(operation K face: ...)``, ``(operation K: ...)``, ``(operation K parameters: ...)``,
``(operation K tool: ...)`` in the forms above.

Numbers are fixed decimals (``6.000``), with more decimals where that is what it takes to read
back the exact value the job used: a header read back gives the same job, bit for bit. Angles kept
in radians by the job are written in degrees such that converting them back gives the same radians.
A comment text may have been upper-cased by its dialect: keys and words are read in any case.

This module holds what a header states (:class:`ProgramHeader`, :class:`SourceHeader` and their parts);
:func:`prs3_post.emit.header_write.header_entries` writes the ``(key, value)`` pairs (the emitter puts
them between the dialect's comment delimiters); :func:`prs3_post.emit.header_read.parse_header` reads
them back from comment texts; :func:`prs3_post.emit.header_read.read_header` finds them at the top of
a program file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from prs3_post.core.defaults import DEFAULT_CLEARANCE_MIN
from prs3_post.core.types import FloatArray
from prs3_post.part.setup_transform import Setup
from prs3_post.toolpaths import Cutting
from prs3_post.toolpaths.work import HoleJob, ProfileJob

if TYPE_CHECKING:
    from prs3_post.part.workplane import WorkPlane

__all__ = ["HOLE_ITEMS", "MAX_POSITION_MM", "PROFILE_ITEMS", "PROGRAM_KEY", "ROUND_ITEMS", "SQUARE_ITEMS", "TOOL_ITEMS",
           "OperationRecord", "ProgramHeader", "SourceCounts", "SourceHeader", "ToolRecord"]

#: The header's first key; a program without it has no header.
PROGRAM_KEY = "program"
#: Largest |coordinate| of a recorded position, mm (as the setup's origin).
MAX_POSITION_MM = 1e5

#: The items of each entry that lists ``name value unit``, in their order (written and read).
HOLE_ITEMS = (("depth", "mm"), ("peck", "mm"), ("dwell", "s"), ("clearance", "mm"), ("retract", "mm"),
              ("reapproach gap", "mm"))
SQUARE_ITEMS = (("size", "mm"), ("corner radius", "mm"), ("rotation", "deg"))
ROUND_ITEMS = (("diameter", "mm"),)
PROFILE_ITEMS = (("side", ""), ("depth", "mm"), ("step-down", "mm"), ("direction", ""), ("entry", ""),
                 ("ramp angle", "deg"), ("clearance", "mm"), ("retract", "mm"))
TOOL_ITEMS = (("diameter", "mm"), ("feed", "mm/min"), ("plunge", "mm/min"), ("spindle", "rpm"), ("coolant", ""))


@dataclass(frozen=True, slots=True)
class OperationRecord:
    """One operation of a job's header (attributes as :class:`ProgramHeader`'s of the same names)."""

    face: int | None
    face_index: int
    work: HoleJob | ProfileJob
    at_uv: FloatArray
    at_xyz: FloatArray
    cutting: Cutting
    collision_check: bool = True
    clearance_min: float = DEFAULT_CLEARANCE_MIN


@dataclass(frozen=True, slots=True)
class ToolRecord:
    """A tool a program uses, as its header states it.

    Attributes
    ----------
    number : int — the T word
    diameter : float — mm
    length : float | None — mm, the tool table's Z (None: no tool table, the machine's tool length)
    ik_length : float — mm, the tool length "TL" the IK used (platform centre to tip)
    """

    number: int
    diameter: float
    length: float | None
    ik_length: float


class _HeaderLines:
    """``line()`` for both headers: where each entry was read (their ``lines`` field)."""

    __slots__ = ()
    lines: tuple[tuple[str, int], ...]

    def line(self, key: str) -> int | None:
        """The program line the ``key`` entry was read from (None when not read from a file)."""
        return dict(self.lines).get(key)


@dataclass(frozen=True, slots=True)
class ProgramHeader(_HeaderLines):
    """What a program says it was made from.

    Attributes
    ----------
    version : str — ``prs3-post 0.1.0``
    machine : str — the machine's name (the file's stem)
    machine_file : str | None — the machine file's path as given, when it was given by path
    dialect : str — the dialect's name
    dialect_file : str | None — the dialect file's path as given, when it was given by path
    part_name : str — the STL's file name (no folder)
    part_sha256 : str — lower-case hex SHA-256 of the STL file's bytes
    units : str — ``mm`` or ``inch``
    up : str — the STL's up axis (``z``, ``-y``, ...)
    face : int | None — the face asked for (None: the automatic choice)
    face_index : int — the face worked on
    setup : Setup
    work : HoleJob | ProfileJob
    at_uv : (K, 2) float — mm, positions given in face coordinates
    at_xyz : (K, 3) float — mm, positions given in part coordinates
    cutting : Cutting
    tolerance : float — mm
    line_numbers, line_start, line_step : the block-numbering overrides (None: the dialect's)
    operations : tuple of OperationRecord — every operation of a job of several (the fields above are
        the first's); empty for a job of one
    tools : tuple of ToolRecord — the tools used, with their lengths (empty: one operation, no tool table)
    collision_check : bool — the tool, holder and nose were checked against the part (the ``collision``
        entry; False: ``not checked (asked not to)``; an old header without it: True)
    clearance_min : float — mm, the clearance they were checked with (``clear of the part by at least
        1.000 mm: ...``; 1.0 where the entry does not state one)
    lines : tuple of (key, line) — where each key was read (1-based program lines; empty when written)
    path : str — the program it was read from (empty when written)
    """

    version: str
    machine: str
    machine_file: str | None
    dialect: str
    dialect_file: str | None
    part_name: str
    part_sha256: str
    units: str
    up: str
    face: int | None
    face_index: int
    setup: Setup
    work: HoleJob | ProfileJob
    at_uv: FloatArray
    at_xyz: FloatArray
    cutting: Cutting
    tolerance: float
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None
    operations: tuple[OperationRecord, ...] = ()
    tools: tuple[ToolRecord, ...] = ()
    lines: tuple[tuple[str, int], ...] = ()
    path: str = ""
    collision_check: bool = True
    clearance_min: float = DEFAULT_CLEARANCE_MIN


@dataclass(frozen=True, slots=True)
class SourceCounts:
    """What a converted program's input held and what the program has (the header's ``counts`` entry;
    the conversion report has the same numbers under the names given).

    Attributes
    ----------
    records : int — input records (CL records, G-code lines with code)
    moves : int — motion records that became one row each (``input_moves``)
    arcs, arc_rows : int — arcs expanded and the rows they became
    cycle_holes, cycle_rows : int — holes of drilling cycles and the rows they became
    comments : int — comments carried into the program
    program_moves : int — motion lines of the program (``emitted_moves``)
    subdivisions : int — rows inserted to keep axis-changing moves within tolerance
    skipped : tuple of (str, int) — records skipped on purpose, by word (as the comment shows the word)
    """

    records: int
    moves: int
    arcs: int
    arc_rows: int
    cycle_holes: int
    cycle_rows: int
    comments: int
    program_moves: int
    subdivisions: int
    skipped: tuple[tuple[str, int], ...] = ()

    def text(self) -> str:
        """The header entry's value (read back by :func:`parse_header`)."""
        skipped = ", ".join(f"{word} {count}" for word, count in self.skipped) or "none"
        return (f"{self.records} records, {self.moves} moves, {self.arcs} arcs to {self.arc_rows} rows, "
                f"{self.cycle_holes} cycle holes to {self.cycle_rows} rows, {self.comments} comments, "
                f"{self.program_moves} program moves, {self.subdivisions} subdivisions, skipped {skipped}")


@dataclass(frozen=True, slots=True)
class SourceHeader(_HeaderLines):
    """What a converted program (``prs3-post convert``) says it was made from: a CAM file, not a part.

    Written as::

        (program: prs3-post 0.1.0)
        (machine: patel2020 [...])
        (dialect: linuxcnc)
        (source: drill.clsf, format cl, units mm, sha256 0f3a...)
        (ignore: CUTCOM, THICK)                        only when words were ignored
        (five axis: haas-umc750, tcp on G234, off G49) only for a 5-axis G-code program
        (work plane: origin [x, y, z] mm, x [..], z [..])   only for G-code on a work plane
        (setup: part origin at machine [...] mm, rotation θ deg about z)
        (tool length: 175.000 mm, the machine's)      or "as given"
        (tolerance: 0.002 mm, angle 0.01 deg)
        (counts: 82 records, 33 moves, 2 arcs to 70 rows, ..., skipped PAINT 36)   see SourceCounts
        (dynamics: cycle time 0.412 min = 24.7 s, 3 moves slowed to ...)   as the main job's
        (collision: not checked [no part given])
        (units: mm, G93 inverse time: F = 1/minutes of each move)

    Attributes
    ----------
    version, machine, machine_file, dialect, dialect_file, setup, tolerance, line_numbers,
    line_start, line_step, lines, path : as :class:`ProgramHeader`
    source_name : str — the CAM file's name (no folder)
    source_sha256 : str — lower-case hex SHA-256 of its bytes
    source_format : str — ``cl`` or ``gcode``
    source_units : str — ``mm`` or ``inch``: the length unit a CL file without ``UNITS/`` was read in;
        ``auto``: the reader's own choice (CL: inches when the feeds are IPM/IPR; G-code: G20/G21)
    ignore : tuple of str — CL major words skipped on purpose
    work_plane : WorkPlane | None — where a G-code program's X, Y, Z were put in the part
    tool_length : float — mm, the tool length the IK used
    tool_length_given : bool — given for the conversion (False: the machine's)
    angle_tolerance_deg : float — degrees
    five_axis : str — a 5-axis G-code program's source convention (shipped name or file; "": not one)
    tcp_on, tcp_off : tuple of str — the codes that switched its TCP on and off
    counts : SourceCounts | None — what the input held and the program has (None: a program written
        before the header had them, or a header not yet complete)
    dynamics : str — the ``dynamics`` entry convert writes, as the main job's: the cycle time and the feeds
        slowed to the axis speed limits (:func:`prs3_post.post.dynamics.streamed_entry`; read back as written)
    collision : str — the ``collision`` entry convert writes (read back as written, its parentheses as the
        dialect left them)
    rapids_tool_diameter : float — mm, read back: the tool diameter the ``collision`` entry says the
        rapids were checked with (0: none stated: the diameter unknown, or converted without a part)
    """

    version: str
    machine: str
    machine_file: str | None
    dialect: str
    dialect_file: str | None
    source_name: str
    source_sha256: str
    source_format: str
    source_units: str
    ignore: tuple[str, ...]
    work_plane: WorkPlane | None
    setup: Setup
    tool_length: float
    tool_length_given: bool
    tolerance: float
    angle_tolerance_deg: float
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None
    lines: tuple[tuple[str, int], ...] = ()
    path: str = ""
    five_axis: str = ""
    tcp_on: tuple[str, ...] = ()
    tcp_off: tuple[str, ...] = ()
    counts: SourceCounts | None = None
    dynamics: str = ""
    collision: str = ""
    rapids_tool_diameter: float = 0.0
