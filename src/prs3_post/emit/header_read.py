"""The program header read back: :func:`parse_header` from a program's comment texts, :func:`read_header`
from the top of a program file (the module docstring of :mod:`prs3_post.emit.header` shows the entries).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable

import numpy as np

from prs3_post.core.errors import InputError, KeyedMessage, Prs3Error, quoted
from prs3_post.core.input_files import open_input
from prs3_post.emit.header import (
    HOLE_ITEMS,
    MAX_POSITION_MM,
    PROFILE_ITEMS,
    PROGRAM_KEY,
    ROUND_ITEMS,
    SQUARE_ITEMS,
    TOOL_ITEMS,
    OperationRecord,
    ProgramHeader,
    SourceCounts,
    SourceHeader,
    ToolRecord,
)
from prs3_post.machine.dialect import COMMENT_CONTINUATION
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

__all__ = ["HEADER_ECHO", "HEAD_BYTES", "cycle_time", "header_comments", "parse_header", "read_counts",
           "read_header"]

#: How many bytes of a program's start :func:`read_header` looks at (a header is about 1 KB).
HEAD_BYTES = 64 * 1024
#: Characters of a header value a message shows: a header line holds up to 252, and the part that is
#: wrong is often at its end; a longer value (a header is input) is cut.
HEADER_ECHO = 160


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"
_VECTOR = rf"\[\s*{_NUMBER}(?:\s*,\s*{_NUMBER})*\s*\]"
_ENTRY = re.compile(r"^\s*([a-z][a-z0-9 ]*?)\s*:\s?(.*?)\s*$", re.IGNORECASE)
_KEYS = ("program", "machine", "machine file", "dialect", "dialect file", "part", "face", "setup", "operation",
         "parameters", "tool", "tools", "operations", "tolerance", "units", "source", "ignore", "work plane",
         "tool length", "five axis", "counts", "dynamics", "collision", "accuracy")
_REQUIRED = ("program", "machine", "dialect", "part", "face", "setup", "operation", "parameters", "tool", "tolerance",
             "units")
#: The keys of a job of several operations (and ``operation K ...`` for each).
_REQUIRED_SEVERAL = ("program", "machine", "dialect", "part", "setup", "tools", "operations", "tolerance", "units")
_OPERATION_KEY = re.compile(r"operation [1-9][0-9]{0,3}(?: face| parameters| tool)?")
#: The entries of a converted program's header (:class:`SourceHeader`); ``ignore`` and ``work plane`` are optional.
_SOURCE_REQUIRED = ("program", "machine", "dialect", "source", "setup", "tool length", "tolerance", "units")


class _Bad(KeyedMessage):
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
            v = _items(text, HOLE_ITEMS)
            return HoleJob(HoleParams(depth=_float(v[0]), peck=_float(v[1]), dwell=_float(v[2]),
                                      clearance=_float(v[3]), retract=_float(v[4]), reapproach_gap=_float(v[5])))
        shape: SquareShape | RoundShape
        if op == "square":
            v = _items(text, SQUARE_ITEMS + PROFILE_ITEMS)
            shape = SquareShape(size=_float(v[0]), corner_radius=_float(v[1]), rotation=_radians(v[2]))
            v = v[3:]
        else:
            v = _items(text, ROUND_ITEMS + PROFILE_ITEMS)
            shape = RoundShape(diameter=_float(v[0]))
            v = v[1:]
        return ProfileJob(shape, ProfileParams(
            side=Side(v[0].lower()), depth=_float(v[1]), step_down=_float(v[2]), direction=Direction(v[3].lower()),
            entry=Entry(v[4].lower()), ramp_angle=_radians(v[5]), clearance=_float(v[6]), retract=_float(v[7])))
    except (ValueError, Prs3Error) as error:           # an enum word or a value its class refuses
        raise _Bad(str(error)) from error


def _cutting(text: str) -> Cutting:
    found = _match(_TOOL, text)
    v = _items(found.group(2), TOOL_ITEMS)
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
            raise _Bad(f"expected a tolerance from {MIN_TOLERANCE:g} to {MAX_TOLERANCE:g} mm (as {{tolerance}}), "
                       f"got {quoted(found['tolerance'][1], HEADER_ECHO)}", names_keys=("tolerance",))
        checks = [(True, 1.0)] * max(1, len(operations))
        if "collision" in found:
            key = "collision"
            checks = _collision(found["collision"][1], len(checks))
        if several:
            operations = tuple(dataclasses.replace(r, collision_check=c, clearance_min=m)
                               for r, (c, m) in zip(operations, checks, strict=True))
    except _Bad as bad:
        key = getattr(bad, "key", key)                  # the entry of an operation that failed
        raise InputError(f"header: {key}: {bad.carried()}", path=path, line=found[key][0],
                         names_keys=bad.names_keys) from bad
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
#: The ``dynamics`` entry (:func:`prs3_post.post.dynamics.dynamics_entry`): the cycle time and the feeds slowed,
#: or the machine has no dynamics.
_DYNAMICS = (rf"cycle time {_NUMBER} min = {_NUMBER} s, (?:no feed slowed by the axis speed limits|[1-9][0-9]* "
             r"moves? slowed to the axis speed limits, worst .+)|none in the machine file: .+")
_FORMS |= {
    _DYNAMICS: "'cycle time M min = S s, no feed slowed by the axis speed limits|N moves slowed to the axis "
               "speed limits, worst R x at LINE [AXIS]', or 'none in the machine file: ...'",
    _COUNTS: "'N records, N moves, N arcs to N rows, N cycle holes to N rows, N comments, N program moves, "
             "N subdivisions, skipped none|WORD N[, WORD N]...'",
    _FIVE_AXIS: "'SOURCE, tcp on CODES, off CODES'",
    _SOURCE: "'NAME, format cl|gcode, units mm|inch|auto, sha256 HEX'",
    _WORK_PLANE: "'origin [x, y, z] mm, x [..], z [..]'",
    _TOOL_LENGTH: "'L mm, as given|the machine's'",
    _SOURCE_TOLERANCE: "'T mm, angle A deg'",
}


_CYCLE_TIME = re.compile(rf"\(\s*dynamics\s*:\s*cycle time ({_NUMBER}) min = ({_NUMBER}) s", re.IGNORECASE)


def cycle_time(line: str) -> tuple[float, float] | None:
    """The cycle time a header's ``dynamics`` line states, in minutes and in seconds as written (the
    seconds have their own rounding); None where it states none.

    >>> cycle_time("(dynamics: cycle time 0.064 min = 3.9 s, no feed slowed by the axis speed limits)")
    (0.064, 3.9)
    >>> cycle_time("(dynamics: none in the machine file: feeds not checked against axis speeds, no cycle time)")
    """
    found = _CYCLE_TIME.match(line)
    return None if found is None else (float(found.group(1)), float(found.group(2)))


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
        dynamics = ""
        if "dynamics" in found:
            key = "dynamics"
            dynamics = _match(_DYNAMICS, found["dynamics"][1]).group(0)
        key = "tolerance"
        tolerances = _match(_SOURCE_TOLERANCE, found["tolerance"][1])
        tolerance, angle = float(tolerances.group(1)), float(tolerances.group(2))
        if not (math.isfinite(tolerance) and MIN_TOLERANCE <= tolerance <= MAX_TOLERANCE and math.isfinite(angle)
                and 0.0 < angle <= 90.0):
            raise _Bad(f"expected a tolerance from {MIN_TOLERANCE:g} to {MAX_TOLERANCE:g} mm (as {{tolerance}}) and an "
                       "angle in (0, 90] deg, "
                       f"got {quoted(found['tolerance'][1], HEADER_ECHO)}", names_keys=("tolerance",))
    except _Bad as bad:
        raise InputError(f"header: {key}: {bad.carried()}", path=path, line=found[key][0],
                         names_keys=bad.names_keys) from bad
    return SourceHeader(
        version=found[PROGRAM_KEY][1], machine=machine,
        machine_file=found["machine file"][1] if "machine file" in found else None,
        dialect=dialect, dialect_file=found["dialect file"][1] if "dialect file" in found else None,
        source_name=source.group(1), source_sha256=source.group(4).lower(), source_format=source.group(2).lower(),
        source_units=source.group(3).lower(), ignore=ignore, work_plane=plane, setup=setup, tool_length=tool_length,
        tool_length_given=length.group(2).lower() == "as given", tolerance=tolerance, angle_tolerance_deg=angle,
        line_numbers=numbers, line_start=start, line_step=step, lines=tuple((k, v[0]) for k, v in found.items()),
        path=path, five_axis=five_axis, tcp_on=tcp_on, tcp_off=tcp_off, counts=counts,
        dynamics=dynamics, collision=found["collision"][1] if "collision" in found else "",
        rapids_tool_diameter=_rapids_tool_diameter(found["collision"][1]) if "collision" in found else 0.0,
    )


def _rapids_tool_diameter(text: str) -> float:
    """mm: the tool diameter a converted program's ``collision`` entry says its rapids were checked
    with (:meth:`prs3_post.check.collision_rapids.RapidClearance.entry`, its parentheses perhaps
    brackets); 0 where it says none (the diameter unknown, or a program converted without a part:
    the tool is then its axis).

    >>> _rapids_tool_diameter("clear of the part by at least 1.000 mm: tool in rapids 2.000 mm [6.000 mm diameter]")
    6.0
    >>> _rapids_tool_diameter("not checked (no part given)")
    0.0
    """
    found = re.search(r"tool in rapids [^(\[]*[(\[]([0-9]+\.[0-9]+) mm diameter", text)
    return float(found.group(1)) if found else 0.0


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
