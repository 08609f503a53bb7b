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
from prs3_post.geometry import MIN_FACE_WIDTH_MM, find_faces, project_onto_face, select_face
from prs3_post.ops.common import require_tolerance
from prs3_post.ops import Cutting, HoleParams, ProfileParams, RoundShape, SquareShape, plan_holes, plan_profile
from prs3_post.pipeline import PostResult, post_process
from prs3_post.readers.stl import load_part
from prs3_post.setup import Setup
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
class HoleJob:
    """A hole operation: drill at each position.

    Attributes
    ----------
    params : HoleParams
    """

    params: HoleParams

    @property
    def operation(self) -> Operation:
        """Always :attr:`Operation.HOLE`."""
        return Operation.HOLE


@dataclass(frozen=True, slots=True)
class ProfileJob:
    """A square or round profile at one position.

    Attributes
    ----------
    shape : SquareShape | RoundShape — which outline (and so which operation)
    params : ProfileParams
    """

    shape: SquareShape | RoundShape
    params: ProfileParams

    @property
    def operation(self) -> Operation:
        """:attr:`Operation.SQUARE` or :attr:`Operation.ROUND`, from the shape."""
        return Operation.SQUARE if isinstance(self.shape, SquareShape) else Operation.ROUND


@dataclass(frozen=True, slots=True)
class JobSpec:
    """Everything the main job needs; built by the CLI from its options (or from a program header).

    Attributes
    ----------
    part : str — STL path
    units : str — ``mm`` or ``inch`` (the STL's length unit)
    face : int | None — face index, None = automatic choice
    work : HoleJob | ProfileJob — the operation and its parameters
    at_uv : (K, 2) float — mm, feature positions in face (u, v); empty = see ``at_xyz``
    at_xyz : (K, 3) float — mm, feature positions in part coordinates, projected onto the face
    cutting : Cutting
    machine : Machine
    dialect : Dialect
    setup : Setup — where the part sits on the machine (:meth:`Setup.resolve` gives the machine's default)
    tolerance : float — mm, chordal tolerance of arcs and of axis-changing moves
    line_numbers, line_start, line_step : optional overrides of the dialect's block numbering
    up : str — the STL's up axis, turned to +z when it is read (``z``, ``y``, ``-x``...: ``readers.stl.UP_ROTATION``)
    """

    part: str
    units: str
    face: int | None
    work: HoleJob | ProfileJob
    at_uv: FloatArray
    at_xyz: FloatArray
    cutting: Cutting
    machine: Machine
    dialect: Dialect
    setup: Setup
    tolerance: float = 0.002
    line_numbers: bool | None = None
    line_start: int | None = None
    line_step: int | None = None
    up: str = "z"

    @property
    def operation(self) -> Operation:
        """What is cut (from :attr:`work`)."""
        return self.work.operation


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
    setup : Setup — the setup used
    triangles : (F, 3, 3) float — mm, the part's triangles in part coordinates (for pictures)
    """

    text: str
    face: Face
    face_note: str
    path_part: Toolpath
    post: PostResult
    setup: Setup
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
    work = spec.work
    if isinstance(work, HoleJob):
        return plan_holes(face, centres, work.params, spec.cutting)
    if len(centres) > 1:
        raise FeatureError(f"--profile {spec.operation.value} cuts one feature: give one --at or --at-xyz "
                           f"(got {len(centres)})")
    return plan_profile(face, centres[0], work.shape, work.params, spec.cutting, tolerance=spec.tolerance)


def run_job(spec: JobSpec) -> JobResult:
    """Load the part, choose the face, plan, post-process and emit.

    Raises
    ------
    InputError, FeatureError, ReachError, LimitError
    """
    require_tolerance(spec.tolerance)
    mesh = load_part(spec.part, units=spec.units, up=spec.up)
    faces = find_faces(mesh)
    try:  # automatic selection skips faces narrower than the tool
        face, note = select_face(faces, spec.face, min_width=max(MIN_FACE_WIDTH_MM, spec.cutting.tool_diameter))
    except FeatureError as error:                     # about this file's faces: say which file
        raise InputError(str(error), path=spec.part) from error
    path_part = plan(spec, face)
    post = post_process(spec.machine, path_part, spec.setup, tolerance=spec.tolerance)
    text = emit_program(post.program, spec.dialect, header=header(spec, face),
                        stage=spec.machine.stage.present, line_numbers=spec.line_numbers,
                        line_start=spec.line_start, line_step=spec.line_step)
    return JobResult(text=text, face=face, face_note=note, path_part=path_part, post=post, setup=spec.setup,
                     triangles=np.asarray(mesh.triangles, dtype=np.float64))


def _mm(values: FloatArray | tuple[float, ...], decimals: int = 4) -> str:
    return ", ".join(_fixed(v, decimals) for v in values)


def _fixed(value: float, decimals: int = 4) -> str:
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def header(spec: JobSpec, face: Face) -> tuple[tuple[str, str], ...]:
    """The program's header comments: what was made, from what, on which machine, in which units."""
    cut = spec.cutting
    op = spec.operation
    if isinstance(spec.work, HoleJob):
        h = spec.work.params
        params = (f"depth {_fixed(h.depth, 3)} mm, peck {_fixed(h.peck, 3)} mm, dwell {_fixed(h.dwell, 3)} s, "
                  f"clearance {_fixed(h.clearance, 3)} mm, retract {_fixed(h.retract, 3)} mm")
    else:
        s, p = spec.work.shape, spec.work.params
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
        ("part", f"{Path(spec.part).name}, units {spec.units}" + ("" if spec.up == "z" else f", up {spec.up}")),
        ("face", f"{face.index}: inclination {_fixed(math.degrees(face.inclination))} deg, "
                 f"normal ({_mm(face.normal, 6)}), origin ({_mm(face.origin)}) mm"),
        ("setup", f"part origin at machine ({_mm(spec.setup.origin)}) mm"),
        ("operation", f"{op.value} at face (u, v) " + ", ".join(f"({_mm(c)})" for c in centres) + " mm"),
        ("parameters", params),
        ("tool", f"T{cut.tool_number} diameter {_fixed(cut.tool_diameter, 3)} mm, feed {_fixed(cut.feed, 1)} mm/min, "
                 f"plunge {_fixed(cut.plunge_feed, 1)} mm/min, spindle {_fixed(cut.spindle_rpm, 0)} rpm, "
                 f"coolant {cut.coolant.value}"),
        ("units", "mm, G93 inverse time: F = 1/minutes of each move"),
    )
