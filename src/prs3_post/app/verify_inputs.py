"""What `verify` and `preview` are given beside the program: the part or CAM file to compare with,
the part to draw, and whether the operation values given agree with what the program's header says.

Keys and values are a request's (:mod:`prs3_post.app.requests`): the front end names them its way.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.core.errors import InputError
from prs3_post.core.types import FloatArray

if TYPE_CHECKING:
    from prs3_post.app.job import JobSpec
    from prs3_post.app.verify import CamPart, ProgramContext
    from prs3_post.emit.header import ProgramHeader, SourceHeader
    from prs3_post.part.face import Face

__all__ = ["cam_part", "header_contradictions", "is_cl_file", "is_converted", "part_drawing", "recorded_part"]

#: An operation's keys given in degrees whose JobSpec value is in radians.
_DEGREE_KEYS = ("rotation", "ramp_angle")


def is_cl_file(path: str) -> bool:
    """Whether ``path`` starts as an APT CL file (CAM output, not a program for this machine); a file
    that cannot be read is not (the program reader names its problem)."""
    from prs3_post.core.input_files import open_input
    from prs3_post.readers.detect import DETECT_BYTES, detect_format

    try:
        with open_input(path, "a file") as stream:
            return detect_format(stream.read(DETECT_BYTES)) == "cl"
    except (InputError, OSError):
        return False


def is_five_axis_cam(path: str) -> bool:
    """Whether ``path`` is G-code without a prs3-post header whose first lines turn a rotary axis (A, B or
    C words): 5-axis CAM output, to be converted with ``--source``, not a program for this machine. A file
    that cannot be read is not (the program reader names its problem)."""
    from prs3_post.core.errors import LexError
    from prs3_post.core.input_files import open_input
    from prs3_post.core.lexer import split_comments
    from prs3_post.readers.detect import DETECT_BYTES, detect_format
    from prs3_post.readers.gcode.words import ROTARY

    try:
        with open_input(path, "a file") as stream:
            head = stream.read(max(DETECT_BYTES, _CAM_HEAD_BYTES))
    except (InputError, OSError):
        return False
    if detect_format(head[:DETECT_BYTES]) != "gcode" or b"(program: prs3-post" in head:
        return False
    for line in head.decode("utf-8", "replace").splitlines()[:-1]:
        try:
            code, _ = split_comments(line)
        except LexError:
            continue                                     # the program reader names what is wrong there
        if ROTARY.search(code):
            return True
    return False


#: Bytes of a header-less program looked at for rotary words (a CAM program's first moves).
_CAM_HEAD_BYTES = 65536


def is_converted(header: ProgramHeader | SourceHeader | None) -> bool:
    """Whether a program's header is that of a program converted from CAM input (``prs3-post convert``)."""
    from prs3_post.emit.header import SourceHeader

    return isinstance(header, SourceHeader)


def operation_values(spec: JobSpec) -> dict[str, Any]:
    """The operation's request keys that ``spec`` answers, in JobSpec units (angles in radians,
    positions as arrays, the face as an index or None)."""
    from prs3_post.toolpaths import SquareShape
    from prs3_post.toolpaths.work import HoleJob

    cut = spec.cutting
    values: dict[str, Any] = {
        "profile": spec.operation.value, "face": spec.face, "at": spec.at_uv, "at_xyz": spec.at_xyz,
        "units": spec.units, "up": spec.up, "tool_diameter": cut.tool_diameter, "tool": cut.tool_number,
        "feed": cut.feed, "plunge_feed": cut.plunge_feed, "spindle": cut.spindle_rpm, "coolant": cut.coolant.value,
    }
    work = spec.work
    if isinstance(work, HoleJob):
        h = work.params
        values |= {"depth": h.depth, "peck": h.peck, "reapproach_gap": h.reapproach_gap, "dwell": h.dwell,
                   "clearance": h.clearance, "retract": h.retract}
        return values
    p, shape = work.params, work.shape
    if isinstance(shape, SquareShape):
        values |= {"size": shape.size, "corner_radius": shape.corner_radius, "rotation": shape.rotation}
    else:
        values |= {"diameter": shape.diameter}
    values |= {"side": p.side.value, "depth": p.depth, "step_down": p.step_down, "direction": p.direction.value,
               "entry": p.entry.value, "ramp_angle": p.ramp_angle, "clearance": p.clearance, "retract": p.retract}
    return values


def _face_index(choice: str | int | None) -> int | None:
    text = str(choice)
    return None if text == "auto" else int(text) if text.isascii() and text.isdigit() else -1


def _as_spec_value(key: str, value: Any) -> Any:
    """A value as given, in JobSpec units (see :func:`operation_values`)."""
    if key in _DEGREE_KEYS:
        return math.radians(value)
    if key == "face":
        return _face_index(value)
    if key in ("at", "at_xyz"):
        return np.array(value, dtype=np.float64).reshape(-1, 2 if key == "at" else 3)
    return value


def _shown(key: str, recorded: Any) -> Any:
    """A header's value as a message shows it (degrees, ``u,v`` points, ``auto``)."""
    if key in _DEGREE_KEYS:
        return math.degrees(recorded)
    if isinstance(recorded, np.ndarray):
        return " ".join(",".join(f"{v:g}" for v in row) for row in recorded) or "none"
    return "auto" if recorded is None else recorded


def header_contradictions(recorded: Mapping[str, Any], given: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The keys given whose value is not the one the program's header records, each with the header's value
    as shown (``[("depth", 5.0)]``); ``recorded``: :func:`operation_values` or :func:`recorded_part`."""
    wrong = []
    for key, value in given.items():
        if key not in recorded:
            continue
        mine, header = _as_spec_value(key, value), recorded[key]
        same = np.array_equal(mine, header) if isinstance(header, np.ndarray) else mine == header
        if not same:
            wrong.append((key, _shown(key, header)))
    return wrong


def spec_contradictions(spec: JobSpec, given: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """:func:`header_contradictions` of an operation the header records (rebuilt as ``spec``)."""
    return header_contradictions(operation_values(spec), given)


def recorded_part(header: ProgramHeader | SourceHeader) -> dict[str, Any]:
    """The part's face, units and up axis a program's header records (a main job's header)."""
    from prs3_post.emit.header import ProgramHeader

    if not isinstance(header, ProgramHeader):
        raise TypeError("a converted program's header records no face")
    return {"face": header.face, "units": header.units, "up": header.up}


def cam_part(context: ProgramContext, part: str, *, units: str, up: str) -> CamPart:
    """The part a converted program cuts (for its clearance only: its path is the CAM file's)."""
    from prs3_post.app.verify import CamPart
    from prs3_post.emit.header import SourceHeader
    from prs3_post.part.stl import load_part

    header = context.header
    if not isinstance(header, SourceHeader):
        raise TypeError("not a converted program")
    mesh = load_part(part, units=units, up=up)
    return CamPart(triangles=np.asarray(mesh.triangles, dtype=np.float64), tool_length=header.tool_length,
                   setup=header.setup, tool_diameter=header.rapids_tool_diameter)


def part_drawing(part: str, face: int | None, *, units: str, up: str) -> tuple[FloatArray, Face]:
    """A part's triangles (part frame, mm) and its face ``face`` (None: the automatic choice), to draw."""
    from prs3_post.part.faces import find_faces, select_face
    from prs3_post.part.stl import load_part

    loaded = load_part(part, units=units, up=up)
    chosen, _ = select_face(find_faces(loaded), face)
    return loaded.triangles, chosen
