"""The program header written: the ``(key, value)`` comment entries of a :class:`~prs3_post.emit.header.ProgramHeader`
or :class:`~prs3_post.emit.header.SourceHeader` (the module docstring of :mod:`prs3_post.emit.header` shows them).
"""

from __future__ import annotations

import math

from prs3_post.core.numbers import degrees_text, exact_list, exact_text, fixed_list
from prs3_post.core.numbers import fixed as _fixed
from prs3_post.core.types import FloatArray
from prs3_post.emit.header import (
    HOLE_ITEMS,
    PROFILE_ITEMS,
    PROGRAM_KEY,
    ROUND_ITEMS,
    SQUARE_ITEMS,
    TOOL_ITEMS,
    OperationRecord,
    ProgramHeader,
    SourceHeader,
    ToolRecord,
)
from prs3_post.part.face import Face
from prs3_post.part.setup_transform import Setup
from prs3_post.toolpaths import SquareShape
from prs3_post.toolpaths.work import HoleJob, ProfileJob

__all__ = ["header_entries", "source_header_entries"]


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
        return HOLE_ITEMS
    return (*(SQUARE_ITEMS if isinstance(work.shape, SquareShape) else ROUND_ITEMS), *PROFILE_ITEMS)


def _join(items: tuple[tuple[str, str], ...], values: list[str]) -> str:
    return ", ".join(f"{name} {value}" + (f" {unit}" if unit else "")
                     for (name, unit), value in zip(items, values, strict=True))


def _positions(at_uv: FloatArray, at_xyz: FloatArray) -> str:
    parts = []
    if len(at_uv):
        parts.append("at face [u, v] " + ", ".join(exact_list(p, 4) for p in at_uv) + " mm")
    if len(at_xyz):
        parts.append("at part [x, y, z] " + ", ".join(exact_list(p, 4) for p in at_xyz) + " mm")
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
                 f"normal {fixed_list(face.normal, 6)}, origin {fixed_list(face.origin, 4)} mm"),
        ("", f"{record.work.operation.value} {_positions(record.at_uv, record.at_xyz)}"),
        ("parameters", _join(_items_of(record.work), _item_values(record.work))),
        ("tool", f"T{cut.tool_number} " + _join(TOOL_ITEMS, [
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
    conversion: its writer makes the header last and puts it first (:class:`prs3_post.core.output_files.HeadLast`).
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
        x_axis, z_axis = plane.rotation[:, 0], plane.rotation[:, 2]
        entries.append(("work plane", f"origin {exact_list(plane.origin, 4)} mm, x {exact_list(x_axis, 6)}, "
                                      f"z {exact_list(z_axis, 6)}"))
    entries += [
        ("setup", _setup_text(header.setup)),
        ("tool length", f"{exact_text(header.tool_length, 3)} mm, "
                        f"{'as given' if header.tool_length_given else 'the machine' + chr(39) + 's'}"),
        ("tolerance", f"{exact_text(header.tolerance, 3)} mm, angle {exact_text(header.angle_tolerance_deg, 2)} deg"),
        *([] if header.counts is None else [("counts", header.counts.text())]),
        *([("dynamics", header.dynamics)] if header.dynamics else []),
        *([("collision", header.collision)] if header.collision else []),
        ("units", "mm, G93 inverse time: F = 1/minutes of each move"),
    ]
    return tuple(entries)


def _setup_text(setup: Setup) -> str:
    return (f"part origin at machine {exact_list(setup.origin, 4)} mm, "
            f"rotation {exact_text(setup.rotation_deg, 4)} deg about z")
