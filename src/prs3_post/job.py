"""The main job: an STL part, a face, one operation → a checked program in actuator space.

    STL ──► faces ──► chosen face ──► operation (hole | square | round) ──► post_process ──► emit

The only I/O is reading the STL (through :mod:`prs3_post.readers.stl`); the program comes back
as text for the CLI to write.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prs3_post import __version__
from prs3_post.config import Dialect, Machine
from prs3_post.emit.gcode import emit_program
from prs3_post.errors import FeatureError, InputError
from prs3_post.face import Face
from prs3_post.geometry import find_faces, project_onto_face, select_face
from prs3_post.ops.common import require_tolerance
from prs3_post.ops import Cutting, HoleParams, ProfileParams, RoundShape, SquareShape, plan_holes, plan_profile
from prs3_post.pipeline import PostResult, post_process
from prs3_post.readers.stl import load_part
from prs3_post.toolpath import Toolpath
from prs3_post.types import FloatArray


class Operation(enum.Enum):
    """What the machine cuts on the face."""

    HOLE = "hole"
    """Drill holes normal to the face, optionally pecking, at each --at point."""
    SQUARE = "square"
    """A square groove or wall (rounded corners allowed) in depth passes."""
    ROUND = "round"
    """A round groove or wall in depth passes."""


@dataclass(frozen=True, slots=True)
class JobSpec:
    """Everything the main job needs; built by the CLI from its options.

    Attributes
    ----------
    part : str — STL path
    units : str — ``mm`` or ``inch`` (the STL's length unit)
    face : int | None — face index, None = automatic choice
    operation : Operation
    at_uv : (K, 2) float — mm, feature positions in face (u, v); empty = see ``at_xyz``
    at_xyz : (K, 3) float — mm, feature positions in part coordinates, projected onto the face
    holes : HoleParams | None — for HOLE
    shape : SquareShape | RoundShape | None — for SQUARE / ROUND
    profile : ProfileParams | None — for SQUARE / ROUND
    cutting : Cutting
    machine : Machine
    dialect : Dialect
    part_origin : (3,) float | None — mm, machine coordinates of the part origin (None: machine default)
    tolerance : float — mm, chordal tolerance of arcs and of axis-changing moves
    line_numbers, line_start, line_step : optional overrides of the dialect's block numbering
    """

    part: str
    units: str
    face: int | None
    operation: Operation
    at_uv: FloatArray
    at_xyz: FloatArray
    holes: HoleParams | None
    shape: SquareShape | RoundShape | None
    profile: ProfileParams | None
    cutting: Cutting
    machine: Machine
    dialect: Dialect
    part_origin: tuple[float, float, float] | None = None
    tolerance: float = 0.002
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None

    def __post_init__(self) -> None:
        if self.operation is Operation.HOLE and self.holes is None:
            raise ValueError("JobSpec: a hole operation needs holes (HoleParams)")
        if self.operation is not Operation.HOLE and (self.shape is None or self.profile is None):
            raise ValueError(f"JobSpec: a {self.operation.value} operation needs shape and profile")


@dataclass(frozen=True, slots=True)
class JobResult:
    """What the main job made.

    Attributes
    ----------
    text : str — the program
    face : Face — the face worked on
    face_note : str — how that face was chosen
    path_part : Toolpath — the operation's toolpath in part coordinates
    post : PostResult — the machine-frame rows, IK, limits and the joint program
    part_origin : (3,) float — the setup used
    triangles : (F, 3, 3) float — mm, the part's triangles in part coordinates (for pictures)
    """

    text: str
    face: Face
    face_note: str
    path_part: Toolpath
    post: PostResult
    part_origin: FloatArray
    triangles: FloatArray


def positions(face: Face, at_uv: FloatArray, at_xyz: FloatArray) -> FloatArray:
    """Feature positions in face (u, v): the --at points, then the --at-xyz points projected onto the
    face (each must lie on its plane within 0.01 mm: a point off the face is a mistake, not a
    position to move silently); the face origin when neither is given. (K, 2) mm."""
    uv = [np.asarray(at_uv, dtype=np.float64).reshape(-1, 2)]
    xyz = np.asarray(at_xyz, dtype=np.float64).reshape(-1, 3)
    if len(xyz):
        uv.append(project_onto_face(face, xyz))
    out = np.concatenate(uv)
    return out if len(out) else np.zeros((1, 2))


def plan(spec: JobSpec, face: Face) -> Toolpath:
    """The operation's toolpath in part coordinates."""
    centres = positions(face, spec.at_uv, spec.at_xyz)
    if spec.operation is Operation.HOLE:
        return plan_holes(face, centres, spec.holes, spec.cutting)
    if len(centres) > 1:
        raise FeatureError(f"--profile {spec.operation.value} cuts one feature: give one --at or --at-xyz "
                           f"(got {len(centres)})")
    return plan_profile(face, centres[0], spec.shape, spec.profile, spec.cutting, tolerance=spec.tolerance)


def run_job(spec: JobSpec) -> JobResult:
    """Load the part, choose the face, plan, post-process and emit.

    Raises
    ------
    InputError, FeatureError, ReachError, LimitError
    """
    require_tolerance(spec.tolerance)
    mesh = load_part(spec.part, units=spec.units)
    faces = find_faces(mesh)
    try:
        face, note = select_face(faces, spec.face)
    except FeatureError as error:                     # about this file's faces: say which file
        raise InputError(str(error), path=spec.part) from error
    path_part = plan(spec, face)
    origin = np.asarray(spec.machine.part_origin if spec.part_origin is None else spec.part_origin, dtype=np.float64)
    post = post_process(spec.machine, path_part, origin, tolerance=spec.tolerance)
    text = emit_program(post.program, spec.dialect, header=header(spec, face, origin),
                        stage=spec.machine.stage.present, line_numbers=spec.line_numbers,
                        line_start=spec.line_start, line_step=spec.line_step)
    return JobResult(text=text, face=face, face_note=note, path_part=path_part, post=post, part_origin=origin,
                     triangles=np.asarray(mesh.triangles, dtype=np.float64))


def _mm(values: FloatArray | tuple[float, ...], decimals: int = 4) -> str:
    return ", ".join(_fixed(v, decimals) for v in values)


def _fixed(value: float, decimals: int = 4) -> str:
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def header(spec: JobSpec, face: Face, origin: FloatArray) -> tuple[tuple[str, str], ...]:
    """The program's header comments: what was made, from what, on which machine, in which units."""
    cut = spec.cutting
    op = spec.operation
    if op is Operation.HOLE:
        h = spec.holes
        params = (f"depth {_fixed(h.depth, 3)} mm, peck {_fixed(h.peck, 3)} mm, dwell {_fixed(h.dwell, 3)} s, "
                  f"clearance {_fixed(h.clearance, 3)} mm, retract {_fixed(h.retract, 3)} mm")
    else:
        s, p = spec.shape, spec.profile
        if isinstance(s, SquareShape):
            size = (f"size {_fixed(s.size, 3)} mm, corner radius {_fixed(s.corner_radius, 3)} mm, "
                    f"rotation {_fixed(math.degrees(s.rotation), 3)} deg")
        else:
            size = f"diameter {_fixed(s.diameter, 3)} mm"
        params = (f"{size}, side {p.side.value}, depth {_fixed(p.depth, 3)} mm, step-down {_fixed(p.step_down, 3)} mm, "
                  f"{p.direction.value}, {p.entry.value} entry")
    centres = positions(face, spec.at_uv, spec.at_xyz)
    return (
        ("program", f"prs3-post {__version__}"),
        ("machine", f"{spec.machine.name} ({spec.machine.description})"),
        ("part", f"{Path(spec.part).name}, units {spec.units}"),
        ("face", f"{face.index}: inclination {_fixed(math.degrees(face.inclination))} deg, "
                 f"normal ({_mm(face.normal, 6)}), origin ({_mm(face.origin)}) mm"),
        ("setup", f"part origin at machine ({_mm(origin)}) mm"),
        ("operation", f"{op.value} at face (u, v) " + ", ".join(f"({_mm(c)})" for c in centres) + " mm"),
        ("parameters", params),
        ("tool", f"T{cut.tool_number} diameter {_fixed(cut.tool_diameter, 3)} mm, feed {_fixed(cut.feed, 1)} mm/min, "
                 f"plunge {_fixed(cut.plunge_feed, 1)} mm/min, spindle {_fixed(cut.spindle_rpm, 0)} rpm, "
                 f"coolant {cut.coolant.value}"),
        ("units", "mm, G93 inverse time: F = 1/minutes of each move"),
    )
