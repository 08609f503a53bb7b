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

:func:`header_entries` writes the ``(key, value)`` pairs (the emitter puts them between the
dialect's comment delimiters); :func:`parse_header` reads them back from comment texts;
:func:`read_header` finds them at the top of a program file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.defaults import DEFAULT_CLEARANCE_MIN
from prs3_post.core.errors import InputError, Prs3Error, quoted
from prs3_post.core.input_files import open_input
from prs3_post.core.numbers import exact_text
from prs3_post.core.numbers import fixed as _fixed
from prs3_post.core.types import FloatArray
from prs3_post.machine.dialect import COMMENT_CONTINUATION
from prs3_post.part.face import Face
from prs3_post.part.setup_transform import Setup
from prs3_post.toolpaths import (
    Coolant,
    Cutting,
    Direction,
    Entry,
    HoleParams,
    ProfileParams,
    RoundShape,
    Side,
    SquareShape,
)
from prs3_post.toolpaths.common import MAX_TOLERANCE, MIN_TOLERANCE
from prs3_post.toolpaths.work import HoleJob, ProfileJob

if TYPE_CHECKING:
    from prs3_post.part.workplane import WorkPlane

#: The header's first key; a program without it has no header.
PROGRAM_KEY = "program"
#: Largest |coordinate| of a recorded position, mm (as the setup's origin).
MAX_POSITION_MM = 1e5
#: How many bytes of a program's start :func:`read_header` looks at (a header is about 1 KB).
HEAD_BYTES = 64 * 1024
#: Characters of a header value a message shows: a header line holds up to 252, and the part that is
#: wrong is often at its end; a longer value (a header is input) is cut.
HEADER_ECHO = 160


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
    collision : str — the ``collision`` entry convert writes (read back as written, its parentheses as the
        dialect left them: verify takes the tool diameter its rapids were checked with from it)
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
    collision: str = ""


def file_sha256(path: str) -> str:
    """Lower-case hex SHA-256 of a file's bytes.

    Raises
    ------
    InputError
        The file cannot be read.
    """
    with open_input(path, "a file") as stream:          # read in pieces: a part may be large
        digest = hashlib.sha256()
        try:
            for piece in iter(lambda: stream.read(1 << 20), b""):
                digest.update(piece)
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    return digest.hexdigest()


# ============================================================================ numbers




def degrees_text(radians: float, decimals: int) -> str:
    """An angle kept in radians, in degrees such that ``math.radians(float(text)) == radians``.

    >>> degrees_text(math.radians(15.0), 3), degrees_text(math.radians(3.0), 3)
    ('15.000', '3.000')
    """
    degrees = math.degrees(radians)
    candidate = degrees
    for _ in range(64):                                # radians() may not invert degrees(): nudge
        if math.radians(candidate) == radians:
            break
        candidate = float(np.nextafter(candidate, math.inf if math.radians(candidate) < radians else -math.inf))
    else:
        candidate = degrees
    for places in range(decimals, 25):
        text = _fixed(candidate, places)
        if math.radians(float(text)) == radians:
            return text
    return repr(candidate)


def _numbers(values: Iterable[float], decimals: int) -> str:
    """``[a, b, c]``, each exact (read back as the same float)."""
    return "[" + ", ".join(exact_text(float(v), decimals) for v in values) + "]"


def _shown(values: Iterable[float], decimals: int) -> str:
    """``[a, b, c]`` in fixed decimals, for people (not read back)."""
    return "[" + ", ".join(_fixed(float(v), decimals) for v in values) + "]"


# ============================================================================ writing


_HOLE_ITEMS = (("depth", "mm"), ("peck", "mm"), ("dwell", "s"), ("clearance", "mm"), ("retract", "mm"),
               ("reapproach gap", "mm"))
_SQUARE_ITEMS = (("size", "mm"), ("corner radius", "mm"), ("rotation", "deg"))
_ROUND_ITEMS = (("diameter", "mm"),)
_PROFILE_ITEMS = (("side", ""), ("depth", "mm"), ("step-down", "mm"), ("direction", ""), ("entry", ""),
                  ("ramp angle", "deg"), ("clearance", "mm"), ("retract", "mm"))
_TOOL_ITEMS = (("diameter", "mm"), ("feed", "mm/min"), ("plunge", "mm/min"), ("spindle", "rpm"), ("coolant", ""))


def _item_values(work: HoleJob | ProfileJob) -> list[str]:
    if isinstance(work, HoleJob):
        h = work.params
        return [exact_text(v, 3) for v in (h.depth, h.peck, h.dwell, h.clearance, h.retract, h.reapproach_gap)]
    s, p = work.shape, work.params
    if isinstance(s, SquareShape):
        shape = [exact_text(s.size, 3), exact_text(s.corner_radius, 3), degrees_text(s.rotation, 3)]
    else:
        shape = [exact_text(s.diameter, 3)]
    return [*shape, p.side.value, exact_text(p.depth, 3), exact_text(p.step_down, 3), p.direction.value,
            p.entry.value, degrees_text(p.ramp_angle, 3), exact_text(p.clearance, 3), exact_text(p.retract, 3)]


def _items_of(work: HoleJob | ProfileJob) -> tuple[tuple[str, str], ...]:
    if isinstance(work, HoleJob):
        return _HOLE_ITEMS
    return (*(_SQUARE_ITEMS if isinstance(work.shape, SquareShape) else _ROUND_ITEMS), *_PROFILE_ITEMS)


def _join(items: tuple[tuple[str, str], ...], values: list[str]) -> str:
    return ", ".join(f"{name} {value}" + (f" {unit}" if unit else "")
                     for (name, unit), value in zip(items, values, strict=True))


def _positions(at_uv: FloatArray, at_xyz: FloatArray) -> str:
    parts = []
    if len(at_uv):
        parts.append("at face [u, v] " + ", ".join(_numbers(p, 4) for p in at_uv) + " mm")
    if len(at_xyz):
        parts.append("at part [x, y, z] " + ", ".join(_numbers(p, 4) for p in at_xyz) + " mm")
    return " and ".join(parts) if parts else "at the face origin"


def header_entries(header: ProgramHeader, face: Face, *, description: str = "",
                   faces: tuple[Face, ...] = ()) -> tuple[tuple[str, str], ...]:
    """The ``(key, value)`` comment entries of ``header`` (the module docstring shows them).

    Parameters
    ----------
    header : ProgramHeader
    face : Face — the face worked on (its inclination, normal and origin are stated for people)
    description : str — the machine's one-line description
    faces : tuple of Face — each operation's face, for a header with ``operations``
    """
    entries = [
        (PROGRAM_KEY, header.version),
        ("machine", f"{header.machine} [{description}]" if description else header.machine),
        *_dialect_entries(header),
    ]
    entries.append(("part", f"{header.part_name}, units {header.units}, up {header.up}, sha256 {header.part_sha256}"))
    if header.operations:
        entries += [("setup", _setup_text(header.setup)), ("tools", _tools_text(header.tools)),
                    ("operations", str(len(header.operations)))]
        for number, (record, worked) in enumerate(zip(header.operations, faces, strict=True), start=1):
            entries += [(f"operation {number} {key}" if key else f"operation {number}", value)
                        for key, value in _operation_entries(record, worked)]
    else:
        record = OperationRecord(face=header.face, face_index=header.face_index, work=header.work,
                                 at_uv=header.at_uv, at_xyz=header.at_xyz, cutting=header.cutting)
        face_entry, *rest = _operation_entries(record, face)
        entries += [("face", face_entry[1]), ("setup", _setup_text(header.setup)),
                    *((key or "operation", value) for key, value in rest)]
        if header.tools:
            entries.append(("tools", _tools_text(header.tools)))
    entries += [
        ("tolerance", f"{exact_text(header.tolerance, 3)} mm"),
        ("units", "mm, G93 inverse time: F = 1/minutes of each move"),
    ]
    return tuple(entries)


def _operation_entries(record: OperationRecord, face: Face) -> list[tuple[str, str]]:
    """``face``, the operation (key ``""``), ``parameters`` and ``tool`` entries of one operation."""
    cut = record.cutting
    how = "chosen automatically" if record.face is None else "as given"
    return [
        ("face", f"{face.index}, {how}: inclination {_fixed(math.degrees(face.inclination), 4)} deg, "
                 f"normal {_shown(face.normal, 6)}, origin {_shown(face.origin, 4)} mm"),
        ("", f"{record.work.operation.value} {_positions(record.at_uv, record.at_xyz)}"),
        ("parameters", _join(_items_of(record.work), _item_values(record.work))),
        ("tool", f"T{cut.tool_number} " + _join(_TOOL_ITEMS, [
            exact_text(cut.tool_diameter, 3), exact_text(cut.feed, 1), exact_text(cut.plunge_feed, 1),
            exact_text(cut.spindle_rpm, 0), cut.coolant.value])),
    ]


def _tools_text(tools: tuple[ToolRecord, ...]) -> str:
    """``T1 diameter 6.000 mm, length 52.300 mm, IK length 172.300 mm and T2 ...`` (not ``;``: the
    dialects turn it into a comma)."""
    return " and ".join(f"T{t.number} diameter {exact_text(t.diameter, 3)} mm"
                     + ("" if t.length is None else f", length {exact_text(t.length, 3)} mm")
                     + f", IK length {exact_text(t.ik_length, 3)} mm" for t in tools)


def _dialect_entries(header: ProgramHeader | SourceHeader) -> list[tuple[str, str]]:
    """The machine and dialect entries (with their files, when given by path)."""
    numbering = []
    if header.line_numbers is not None:
        numbering.append(f"line numbers {'on' if header.line_numbers else 'off'}")
    if header.line_start is not None:
        numbering.append(f"first line number {header.line_start}")
    if header.line_step is not None:
        numbering.append(f"line number step {header.line_step}")
    entries = []
    if header.machine_file is not None:
        entries.append(("machine file", header.machine_file))
    entries.append(("dialect", ", ".join([header.dialect, *numbering])))
    if header.dialect_file is not None:
        entries.append(("dialect file", header.dialect_file))
    return entries


def source_header_entries(header: SourceHeader, *, description: str = "") -> tuple[tuple[str, str], ...]:
    """The ``(key, value)`` comment entries of a converted program's header (see :class:`SourceHeader`).

    Parameters
    ----------
    header : SourceHeader
    description : str — the machine's one-line description

    The counts (what the input held, what the program has) are only known at the end of a streamed
    conversion: its writer makes the header last and puts it first (:class:`prs3_post.emit.output_files.HeadLast`).
    """
    entries = [
        (PROGRAM_KEY, header.version),
        ("machine", f"{header.machine} [{description}]" if description else header.machine),
        *_dialect_entries(header),
        ("source", f"{header.source_name}, format {header.source_format}, units {header.source_units}, "
                   f"sha256 {header.source_sha256}"),
    ]
    if header.ignore:
        entries.append(("ignore", ", ".join(header.ignore)))
    if header.five_axis:
        entries.append(("five axis", f"{header.five_axis}, tcp on {','.join(header.tcp_on)}, "
                                     f"off {','.join(header.tcp_off)}"))
    if header.work_plane is not None:
        plane = header.work_plane
        entries.append(("work plane", f"origin {_numbers(plane.origin, 4)} mm, x {_numbers(plane.rotation[:, 0], 6)}, "
                                      f"z {_numbers(plane.rotation[:, 2], 6)}"))
    entries += [
        ("setup", _setup_text(header.setup)),
        ("tool length", f"{exact_text(header.tool_length, 3)} mm, "
                        f"{'as given' if header.tool_length_given else 'the machine' + chr(39) + 's'}"),
        ("tolerance", f"{exact_text(header.tolerance, 3)} mm, angle {exact_text(header.angle_tolerance_deg, 2)} deg"),
        *([] if header.counts is None else [("counts", header.counts.text())]),
        *([("collision", header.collision)] if header.collision else []),
        ("units", "mm, G93 inverse time: F = 1/minutes of each move"),
    ]
    return tuple(entries)


def _setup_text(setup: Setup) -> str:
    return (f"part origin at machine {_numbers(setup.origin, 4)} mm, "
            f"rotation {exact_text(setup.rotation_deg, 4)} deg about z")


# ============================================================================ reading


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"
_VECTOR = rf"\[\s*{_NUMBER}(?:\s*,\s*{_NUMBER})*\s*\]"
_ENTRY = re.compile(r"^\s*([a-z][a-z0-9 ]*?)\s*:\s?(.*?)\s*$", re.IGNORECASE)
_KEYS = ("program", "machine", "machine file", "dialect", "dialect file", "part", "face", "setup", "operation",
         "parameters", "tool", "tools", "operations", "tolerance", "units", "source", "ignore", "work plane",
         "tool length", "five axis", "counts", "collision")
_REQUIRED = ("program", "machine", "dialect", "part", "face", "setup", "operation", "parameters", "tool", "tolerance",
             "units")
#: The keys of a job of several operations (and ``operation K ...`` for each).
_REQUIRED_SEVERAL = ("program", "machine", "dialect", "part", "setup", "tools", "operations", "tolerance", "units")
_OPERATION_KEY = re.compile(r"operation [1-9][0-9]{0,3}(?: face| parameters| tool)?")
#: The entries of a converted program's header (:class:`SourceHeader`); ``ignore`` and ``work plane`` are optional.
_SOURCE_REQUIRED = ("program", "machine", "dialect", "source", "setup", "tool length", "tolerance", "units")


class _Bad(Exception):
    """One entry's value is not in the header's form (turned into an InputError with the line)."""


def _vector(text: str, count: int) -> tuple[float, ...]:
    values = tuple(float(v) for v in re.findall(_NUMBER, text, re.IGNORECASE))
    if len(values) != count:
        raise _Bad(f"expected [{count} numbers], got {quoted(text, HEADER_ECHO)}")
    return values


def _match(pattern: str, text: str) -> re.Match[str]:
    found = re.fullmatch(pattern, text, re.IGNORECASE)
    if found is None:
        raise _Bad(f"expected {_FORMS.get(pattern, 'the header form')}, got {quoted(text, HEADER_ECHO)}")
    return found


_SETUP = rf"part origin at machine ({_VECTOR}) mm, rotation ({_NUMBER}) deg about z"
_PART = r"(.*), units (mm|inch), up (-?[xyz]), sha256 ([0-9a-f]{64})"
_FACE = r"(\d+), (chosen automatically|as given): .*"
_OPERATION = (rf"(hole|square|round) (?:at the face origin|(?:at face \[u, v\] ((?:{_VECTOR}(?:, )?)+) mm)?"
              rf"(?: and )?(?:at part \[x, y, z\] ((?:{_VECTOR}(?:, )?)+) mm)?)")
_TOOL = r"T(\d+) (.*)"
_TOLERANCE = rf"({_NUMBER}) mm"
_COUNT = r"([1-9][0-9]{0,3})"
_FORMS = {
    _SETUP: "'part origin at machine [x, y, z] mm, rotation θ deg about z'",
    _PART: "'NAME, units mm|inch, up [-]x|y|z, sha256 HEX'",
    _FACE: "'N, chosen automatically|as given: ...'",
    _OPERATION: "'hole|square|round at face [u, v] [..] mm and/or at part [x, y, z] [..] mm, or at the face origin'",
    _TOOL: "'TN diameter .. mm, feed .. mm/min, ...'",
    _TOLERANCE: "'T mm'",
    _COUNT: "'N', the number of operations (1 to 9999)",
}


def _items(text: str, items: tuple[tuple[str, str], ...]) -> list[str]:
    """The values of ``name value [unit]`` items, in the fixed order."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != len(items):
        raise _Bad(f"expected {len(items)} items ({', '.join(n for n, _ in items)}), got {len(parts)}")
    values = []
    for part, (name, unit) in zip(parts, items, strict=True):
        found = re.fullmatch(rf"{re.escape(name)} (\S+)" + (rf" {re.escape(unit)}" if unit else ""), part,
                             re.IGNORECASE)
        if found is None:
            raise _Bad(f"expected '{name} VALUE{' ' + unit if unit else ''}', got {quoted(part, HEADER_ECHO)}")
        values.append(found.group(1))
    return values


def _float(text: str) -> float:
    if not re.fullmatch(_NUMBER, text, re.IGNORECASE):
        raise _Bad(f"expected a number, got {quoted(text, HEADER_ECHO)}")
    return float(text)


def _radians(text: str) -> float:
    return math.radians(_float(text))


def _work(operation: str, text: str) -> HoleJob | ProfileJob:
    op = operation.lower()
    try:
        if op == "hole":
            v = _items(text, _HOLE_ITEMS)
            return HoleJob(HoleParams(depth=_float(v[0]), peck=_float(v[1]), dwell=_float(v[2]),
                                      clearance=_float(v[3]), retract=_float(v[4]), reapproach_gap=_float(v[5])))
        shape: SquareShape | RoundShape
        if op == "square":
            v = _items(text, _SQUARE_ITEMS + _PROFILE_ITEMS)
            shape = SquareShape(size=_float(v[0]), corner_radius=_float(v[1]), rotation=_radians(v[2]))
            v = v[3:]
        else:
            v = _items(text, _ROUND_ITEMS + _PROFILE_ITEMS)
            shape = RoundShape(diameter=_float(v[0]))
            v = v[1:]
        return ProfileJob(shape, ProfileParams(
            side=Side(v[0].lower()), depth=_float(v[1]), step_down=_float(v[2]), direction=Direction(v[3].lower()),
            entry=Entry(v[4].lower()), ramp_angle=_radians(v[5]), clearance=_float(v[6]), retract=_float(v[7])))
    except (ValueError, Prs3Error) as error:           # an enum word or a value its class refuses
        raise _Bad(str(error)) from error


def _cutting(text: str) -> Cutting:
    found = _match(_TOOL, text)
    v = _items(found.group(2), _TOOL_ITEMS)
    try:
        return Cutting(tool_diameter=_float(v[0]), feed=_float(v[1]), plunge_feed=_float(v[2]),
                       spindle_rpm=_float(v[3]), coolant=Coolant(v[4].lower()), tool_number=int(found.group(1)))
    except (ValueError, Prs3Error) as error:
        raise _Bad(str(error)) from error


def _machine_name(text: str) -> str:
    """The machine entry's name, without the ``[...]`` after it."""
    machine = re.sub(r"\s*\[.*\]$", "", text).strip()
    if not machine:
        raise _Bad("no machine name")
    return machine


def _setup(text: str) -> Setup:
    found = _match(_SETUP, text)
    try:
        return Setup(_vector(found.group(1), 3), float(found.group(2)))  # type: ignore[arg-type]
    except Prs3Error as error:
        raise _Bad(str(error)) from error


def _dialect(text: str) -> tuple[str, bool | None, int | None, int | None]:
    name, *rest = [p.strip() for p in text.split(",")]
    numbers: bool | None = None
    start = step = None
    for item in rest:
        if found := re.fullmatch(r"line numbers (on|off)", item, re.IGNORECASE):
            numbers = found.group(1).lower() == "on"
        elif found := re.fullmatch(r"first line number (\d+)", item, re.IGNORECASE):
            start = int(found.group(1))
        elif found := re.fullmatch(r"line number step (\d+)", item, re.IGNORECASE):
            step = int(found.group(1))
        else:
            raise _Bad(f"expected 'NAME[, line numbers on|off][, first line number N][, line number step N]', "
                       f"got {quoted(text, HEADER_ECHO)}")
    return name, numbers, start, step


def parse_header(comments: Iterable[tuple[int, str]], *, path: str) -> ProgramHeader | SourceHeader | None:
    """Read a header from a program's comment texts.

    Parameters
    ----------
    comments : iterable of (line, text) — the comments at the top of the program, without their
        delimiters, in order (1-based line numbers)
    path : str — the program, for messages

    Returns
    -------
    ProgramHeader (the main job's), SourceHeader (a converted CAM file's: it has ``source`` and no
    ``part``), or None when there is no ``program: prs3-post ...`` entry (not a prs3-post header).

    Raises
    ------
    InputError
        With the line: a header entry that is missing, repeated or not in its form.
    """
    found: dict[str, tuple[int, str]] = {}
    last = 0
    for number, text in comments:
        entry = _ENTRY.match(text)
        if entry is None:
            continue
        key = entry.group(1).lower()
        if key not in _KEYS and not _OPERATION_KEY.fullmatch(key):
            continue
        if key in found:
            raise InputError(f"header: '{key}' appears twice (first on line {found[key][0]})", path=path, line=number)
        found[key] = (number, entry.group(2))
        last = number
    if PROGRAM_KEY not in found or not found[PROGRAM_KEY][1].lower().startswith("prs3-post"):
        return None
    if "source" in found and "part" not in found:
        return _source_header(found, path)
    several = "operations" in found
    required = _REQUIRED_SEVERAL if several else _REQUIRED
    missing = [k for k in required if k not in found]
    if missing:
        raise InputError(f"header: no {', '.join(repr(k) for k in missing)} entry (a prs3-post header has "
                         f"{', '.join(required)})", path=path, line=last)
    key = PROGRAM_KEY
    try:
        key = "machine"
        machine = _machine_name(found["machine"][1])
        key = "dialect"
        dialect, numbers, start, step = _dialect(found["dialect"][1])
        key = "part"
        part = _match(_PART, found["part"][1])
        key = "setup"
        setup = _setup(found["setup"][1])
        tools: tuple[ToolRecord, ...] = ()
        if "tools" in found:
            key = "tools"
            tools = _tools(found["tools"][1])
        operations: tuple[OperationRecord, ...] = ()
        if several:
            key = "operations"
            count = _match(_COUNT, found["operations"][1])
            prefixes = [f"operation {k} " for k in range(1, int(count.group(1)) + 1)]
            absent = [p + suffix for p in prefixes for suffix in ("face", "", "parameters", "tool")
                      if (p + suffix).strip() not in found]
            if absent:
                raise _Bad(f"{count.group(1)} operations, but no {', '.join(repr(k.strip()) for k in absent)} entry")
            records = []
            for prefix in prefixes:
                record, key = _operation_record(found, prefix)
                records.append(record)
            operations = tuple(records)
            first = operations[0]
        else:
            first, key = _operation_record(found, "")
        key = "tolerance"
        tolerance = float(_match(_TOLERANCE, found["tolerance"][1]).group(1))
        if not (math.isfinite(tolerance) and MIN_TOLERANCE <= tolerance <= MAX_TOLERANCE):   # as --tolerance
            raise _Bad(f"expected a tolerance from {MIN_TOLERANCE:g} to {MAX_TOLERANCE:g} mm (as --tolerance), "
                       f"got {quoted(found['tolerance'][1], HEADER_ECHO)}")
        checks = [(True, 1.0)] * max(1, len(operations))
        if "collision" in found:
            key = "collision"
            checks = _collision(found["collision"][1], len(checks))
        if several:
            operations = tuple(dataclasses.replace(r, collision_check=c, clearance_min=m)
                               for r, (c, m) in zip(operations, checks, strict=True))
    except _Bad as bad:
        key = getattr(bad, "key", key)                  # the entry of an operation that failed
        raise InputError(f"header: {key}: {bad}", path=path, line=found[key][0]) from bad
    return ProgramHeader(
        version=found[PROGRAM_KEY][1], machine=machine,
        machine_file=found["machine file"][1] if "machine file" in found else None,
        dialect=dialect, dialect_file=found["dialect file"][1] if "dialect file" in found else None,
        part_name=part.group(1), part_sha256=part.group(4).lower(), units=part.group(2).lower(),
        up=part.group(3).lower(), face=first.face, face_index=first.face_index, setup=setup, work=first.work,
        at_uv=first.at_uv, at_xyz=first.at_xyz, cutting=first.cutting,
        tolerance=tolerance, line_numbers=numbers, line_start=start, line_step=step, operations=operations,
        tools=tools, lines=tuple((k, v[0]) for k, v in found.items()), path=path,
        collision_check=checks[0][0], clearance_min=checks[0][1],
    )


_CLEAR = rf"clear of the part by at least ({_NUMBER}) mm: .*"
_ASKED_NOT_TO = r"not checked [(\[]asked not to[)\]]"


def _collision(text: str, count: int) -> list[tuple[bool, float]]:
    """Whether each of ``count`` operations was checked against the part, and with what clearance (mm),
    from the ``collision`` entry the main job writes: ``not checked (asked not to)`` (none was; a
    dialect may have turned the parentheses into brackets), ``clear of the part by at least 1.000 mm:
    ...``, ``not checked: WHY`` (asked, but not done: the clearance is not stated), or for several
    operations ``operation 1: ...; operation 2: not checked`` (``not checked`` alone: asked not to; a
    dialect may have turned the semicolons into commas)."""
    if re.fullmatch(_ASKED_NOT_TO, text, re.IGNORECASE):
        return [(False, 1.0)] * count
    pieces = [text]
    if count > 1:
        pieces = re.split(r"[;,]\s*(?=operation \d+:)", text, flags=re.IGNORECASE)
        numbered = [re.fullmatch(r"operation (\d+): (.*)", p, re.IGNORECASE | re.DOTALL) for p in pieces]
        if [None if n is None else int(n.group(1)) for n in numbered] != list(range(1, count + 1)):
            raise _Bad(f"expected 'operation 1: ...; operation 2: ...' for the {count} operations, "
                       f"got {quoted(text, HEADER_ECHO)}")
        pieces = [n.group(2) for n in numbered if n is not None]
    out = []
    for piece in pieces:
        if count > 1 and re.fullmatch(r"not checked", piece, re.IGNORECASE):
            out.append((False, 1.0))
        elif found := re.fullmatch(_CLEAR, piece, re.IGNORECASE | re.DOTALL):
            clearance = float(found.group(1))
            if not (math.isfinite(clearance) and 0.0 <= clearance <= MAX_POSITION_MM):
                raise _Bad(f"expected a clearance of 0 to {MAX_POSITION_MM:g} mm, "
                           f"got {quoted(found.group(1), HEADER_ECHO)}")
            out.append((True, clearance))
        elif re.match(r"not checked\b", piece, re.IGNORECASE):
            out.append((True, 1.0))
        else:
            raise _Bad(f"expected 'clear of the part by at least D mm: ...', 'not checked: WHY' or 'not checked "
                       f"(asked not to)', got {quoted(piece, HEADER_ECHO)}")
    return out


def _operation_record(found: dict[str, tuple[int, str]], prefix: str) -> tuple[OperationRecord, str]:
    """The operation whose entries are ``{prefix}face`` ... ``{prefix}tool``, and the last key read.
    A _Bad raised here carries the key of the entry that failed as its ``key`` attribute."""
    key = f"{prefix}face"
    try:
        face = _match(_FACE, found[key][1])
        key = prefix + "operation" if not prefix else prefix.strip()
        operation = _match(_OPERATION, found[key][1])
        at_uv = np.array([_vector(v, 2) for v in re.findall(_VECTOR, operation.group(2) or "")],
                         dtype=np.float64).reshape(-1, 2)
        at_xyz = np.array([_vector(v, 3) for v in re.findall(_VECTOR, operation.group(3) or "")],
                          dtype=np.float64).reshape(-1, 3)
        key = f"{prefix}parameters"
        work = _work(operation.group(1), found[key][1])
        key = f"{prefix}tool"
        cutting = _cutting(found[key][1])
        every = np.concatenate([at_uv.ravel(), at_xyz.ravel()])
        if not (np.isfinite(every).all() and np.abs(every).max(initial=0.0) <= MAX_POSITION_MM):
            raise _Bad(f"positions must be finite and within ±{MAX_POSITION_MM:g} mm")
    except _Bad as bad:
        bad.key = key                                   # type: ignore[attr-defined]
        raise
    record = OperationRecord(face=None if face.group(2).lower() == "chosen automatically" else int(face.group(1)),
                             face_index=int(face.group(1)), work=work, at_uv=at_uv, at_xyz=at_xyz, cutting=cutting)
    return record, key


_TOOL_RECORD = re.compile(rf"T(\d+) diameter ({_NUMBER}) mm(?:, length ({_NUMBER}) mm)?, IK length ({_NUMBER}) mm",
                          re.IGNORECASE)


def _tools(text: str) -> tuple[ToolRecord, ...]:
    records = []
    for part in re.split(r"\s+and\s+", text, flags=re.IGNORECASE):
        found = _TOOL_RECORD.fullmatch(part.strip())
        if found is None:
            raise _Bad(f"expected 'TN diameter D mm[, length L mm], IK length TL mm' for each tool (joined by "
                       f"'and'), got {quoted(part.strip(), HEADER_ECHO)}")
        number, diameter, length, ik_length = found.groups()
        values = [float(diameter), float(ik_length), *([] if length is None else [float(length)])]
        if not all(0.0 <= v <= MAX_POSITION_MM for v in values):
            raise _Bad(f"tool lengths and diameters must be within 0 to {MAX_POSITION_MM:g} mm, "
                       f"got {quoted(part.strip(), HEADER_ECHO)}")
        records.append(ToolRecord(number=int(number), diameter=float(diameter),
                                  length=None if length is None else float(length), ik_length=float(ik_length)))
    return tuple(records)


_SOURCE = r"(.*), format (cl|gcode), units (mm|inch|auto), sha256 ([0-9a-f]{64})"
_WORK_PLANE = rf"origin ({_VECTOR}) mm, x ({_VECTOR}), z ({_VECTOR})"
_TOOL_LENGTH = rf"({_NUMBER}) mm, (as given|the machine's)"
_SOURCE_TOLERANCE = rf"({_NUMBER}) mm, angle ({_NUMBER}) deg"
_FIVE_AXIS = r"(.+), tcp on ([GM][0-9.]+(?:,[GM][0-9.]+)*), off ([GM][0-9.]+(?:,[GM][0-9.]+)*)"
_COUNTS = (r"(\d+) records, (\d+) moves, (\d+) arcs to (\d+) rows, (\d+) cycle holes to (\d+) rows, "
           r"(\d+) comments, (\d+) program moves, (\d+) subdivisions, skipped (.+)")
_SKIPPED = re.compile(r"(.*\S) (\d+)")
_FORMS |= {
    _COUNTS: "'N records, N moves, N arcs to N rows, N cycle holes to N rows, N comments, N program moves, "
             "N subdivisions, skipped none|WORD N[, WORD N]...'",
    _FIVE_AXIS: "'SOURCE, tcp on CODES, off CODES'",
    _SOURCE: "'NAME, format cl|gcode, units mm|inch|auto, sha256 HEX'",
    _WORK_PLANE: "'origin [x, y, z] mm, x [..], z [..]'",
    _TOOL_LENGTH: "'L mm, as given|the machine's'",
    _SOURCE_TOLERANCE: "'T mm, angle A deg'",
}


def read_counts(text: str) -> SourceCounts:
    """The ``counts`` entry: the skipped words are split at the commas outside brackets (a word may
    hold a bracketed remark with commas)."""
    found = _match(_COUNTS, text)
    records, moves, arcs, arc_rows, holes, hole_rows, comments, program_moves, subdivisions = (
        int(v) for v in found.groups()[:9])
    skipped: list[tuple[str, int]] = []
    rest = found.group(10)
    if rest.lower() != "none":
        depth, start = 0, 0
        pieces = []
        for index, char in enumerate(rest):
            depth += (char in "[(") - (char in "])")
            if char == "," and depth == 0:
                pieces.append(rest[start:index])
                start = index + 1
        pieces.append(rest[start:])
        for piece in pieces:
            word = _SKIPPED.fullmatch(piece.strip())
            if word is None:
                raise _Bad(f"expected 'skipped none' or 'WORD N' for each skipped word, "
                           f"got {quoted(piece.strip(), HEADER_ECHO)}")
            skipped.append((word.group(1), int(word.group(2))))
    return SourceCounts(records=records, moves=moves, arcs=arcs, arc_rows=arc_rows, cycle_holes=holes,
                        cycle_rows=hole_rows, comments=comments, program_moves=program_moves,
                        subdivisions=subdivisions, skipped=tuple(skipped))


def _source_header(found: dict[str, tuple[int, str]], path: str) -> SourceHeader:
    """A converted program's header from its entries (see :func:`parse_header`)."""
    missing = [k for k in _SOURCE_REQUIRED if k not in found]
    last = max(number for number, _ in found.values())
    if missing:
        raise InputError(f"header: no {', '.join(repr(k) for k in missing)} entry (a converted program's header "
                         f"has {', '.join(_SOURCE_REQUIRED)})", path=path, line=last)
    key = "machine"
    try:
        machine = _machine_name(found["machine"][1])
        key = "dialect"
        dialect, numbers, start, step = _dialect(found["dialect"][1])
        key = "source"
        source = _match(_SOURCE, found["source"][1])
        ignore: tuple[str, ...] = ()
        if "ignore" in found:
            key = "ignore"
            ignore = tuple(w.strip().upper() for w in found["ignore"][1].split(","))
            if not all(re.fullmatch(r"[A-Z][A-Z0-9 _-]*", w) for w in ignore):
                raise _Bad(f"expected major words separated by commas, got {quoted(found['ignore'][1], HEADER_ECHO)}")
        five_axis, tcp_on, tcp_off = "", (), ()
        if "five axis" in found:
            key = "five axis"
            five = _match(_FIVE_AXIS, found["five axis"][1])
            five_axis, tcp_on, tcp_off = five.group(1), tuple(five.group(2).split(",")), tuple(five.group(3).split(","))
        plane = None
        if "work plane" in found:
            key = "work plane"
            planes = _match(_WORK_PLANE, found["work plane"][1])
            from prs3_post.part.workplane import WorkPlane, WorkPlaneError  # only a converted program's header has one

            try:
                plane = WorkPlane.from_vectors(_vector(planes.group(1), 3), _vector(planes.group(3), 3),
                                               _vector(planes.group(2), 3), name="work plane")
            except WorkPlaneError as error:
                raise _Bad(str(error)) from error
        key = "setup"
        setup = _setup(found["setup"][1])
        key = "tool length"
        length = _match(_TOOL_LENGTH, found["tool length"][1])
        tool_length = float(length.group(1))
        if not (math.isfinite(tool_length) and 0.0 < tool_length <= MAX_POSITION_MM):
            raise _Bad(f"expected a length > 0 mm, got {quoted(length.group(1), HEADER_ECHO)}")
        counts = None
        if "counts" in found:
            key = "counts"
            counts = read_counts(found["counts"][1])
        key = "tolerance"
        tolerances = _match(_SOURCE_TOLERANCE, found["tolerance"][1])
        tolerance, angle = float(tolerances.group(1)), float(tolerances.group(2))
        if not (math.isfinite(tolerance) and MIN_TOLERANCE <= tolerance <= MAX_TOLERANCE and math.isfinite(angle)
                and 0.0 < angle <= 90.0):
            raise _Bad(f"expected a tolerance from {MIN_TOLERANCE:g} to {MAX_TOLERANCE:g} mm (as --tolerance) and an "
                       "angle in (0, 90] deg, "
                       f"got {quoted(found['tolerance'][1], HEADER_ECHO)}")
    except _Bad as bad:
        raise InputError(f"header: {key}: {bad}", path=path, line=found[key][0]) from bad
    return SourceHeader(
        version=found[PROGRAM_KEY][1], machine=machine,
        machine_file=found["machine file"][1] if "machine file" in found else None,
        dialect=dialect, dialect_file=found["dialect file"][1] if "dialect file" in found else None,
        source_name=source.group(1), source_sha256=source.group(4).lower(), source_format=source.group(2).lower(),
        source_units=source.group(3).lower(), ignore=ignore, work_plane=plane, setup=setup, tool_length=tool_length,
        tool_length_given=length.group(2).lower() == "as given", tolerance=tolerance, angle_tolerance_deg=angle,
        line_numbers=numbers, line_start=start, line_step=step, lines=tuple((k, v[0]) for k, v in found.items()),
        path=path, five_axis=five_axis, tcp_on=tcp_on, tcp_off=tcp_off, counts=counts,
        collision=found["collision"][1] if "collision" in found else "",
    )


def header_comments(text: str, *, open_: str = "(", close: str = ")") -> list[tuple[int, str]]:
    """The comment texts of the lines at the top of a program, before its first line with code.

    Lines that are only ``%``, an ``O`` number (with a comment) or blank are passed over. A comment
    the emitter wrapped over several lines (continuation lines start with two spaces) comes back
    as one text, with the line number of its first line.
    """
    out: list[tuple[int, str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped == "%":
            continue
        if stripped.startswith(open_) and stripped.endswith(close) and stripped.count(open_) == 1:
            comment = stripped[len(open_):len(stripped) - len(close)]
            if comment.startswith(COMMENT_CONTINUATION) and out:
                out[-1] = (out[-1][0], f"{out[-1][1]} {comment.strip()}")
            else:
                out.append((number, comment))
            continue
        if re.fullmatch(r"O\d+\s*(\(.*\))?", stripped, re.IGNORECASE):
            continue
        break
    return out


def read_header(path: str, *, open_: str = "(", close: str = ")") -> ProgramHeader | SourceHeader | None:
    """The header of the program file at ``path``, or None when it has none (see :func:`parse_header`).

    Only the first :data:`HEAD_BYTES` bytes are looked at.

    Raises
    ------
    InputError
        The file cannot be read, or its header is malformed.
    """
    head = _read_head(path)
    text = head.decode("utf-8", errors="replace")
    if len(head) == HEAD_BYTES:                         # the last line may be cut: leave it out
        text = text[:text.rfind("\n") + 1]
    return parse_header(header_comments(text, open_=open_, close=close), path=path)


def _read_head(path: str) -> bytes:
    with open_input(path, "a G-code program") as stream:   # missing, a folder, a FIFO, a device: its clear message
        try:
            return stream.read(HEAD_BYTES)
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
