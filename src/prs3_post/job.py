"""The main job: an STL part, a face, one operation → a checked program in actuator space.

    STL ──► faces ──► chosen face ──► operation (hole | square | round) ──► post_process ──► emit

The only I/O is reading the STL (through :mod:`prs3_post.readers.stl`); the program comes back
as text for the CLI to write.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prs3_post import __version__
from prs3_post.config import Dialect, Machine
from prs3_post.emit.gcode import emit_program
from prs3_post.errors import FeatureError, InputError, LimitError, ReachError
from prs3_post.face import Face
from prs3_post.geometry import MIN_FACE_WIDTH_MM, find_faces, project_onto_face, select_face
from prs3_post.ops import Cutting, plan_holes, plan_profile
from prs3_post.ops.common import require_tolerance
from prs3_post.ops.work import HoleJob, Operation, ProfileJob
from prs3_post.pipeline import PostResult, post_process
from prs3_post.placement import placement_error
from prs3_post.readers.header import ProgramHeader, file_sha256, header_entries
from prs3_post.readers.stl import load_part
from prs3_post.resolution import length_resolution
from prs3_post.setup import Setup
from prs3_post.tolerances import DEFAULT_TOLERANCE
from prs3_post.toolpath import Toolpath
from prs3_post.types import FloatArray


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
    tolerance: float = DEFAULT_TOLERANCE
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
    resolution = length_resolution(spec.dialect.decimals.length)   # what the program can show, mm
    if isinstance(work, HoleJob):
        return plan_holes(face, centres, work.params, spec.cutting, resolution=resolution)
    if len(centres) > 1:
        raise FeatureError(f"--profile {spec.operation.value} cuts one feature: give one --at or --at-xyz "
                           f"(got {len(centres)})")
    return plan_profile(face, centres[0], work.shape, work.params, spec.cutting, tolerance=spec.tolerance,
                        resolution=resolution)


def run_job(spec: JobSpec) -> JobResult:
    """Load the part, choose the face, plan, post-process and emit.

    Raises
    ------
    InputError, FeatureError
    PlacementLimitError, PlacementReachError
        The path breaks a limit or cannot be reached with this setup: the message says the setup and,
        where a translation of the part fits, that part origin (``suggested_origin``).
    """
    require_tolerance(spec.tolerance)
    mesh = load_part(spec.part, units=spec.units, up=spec.up)
    faces = find_faces(mesh)
    try:  # automatic selection skips faces narrower than the tool
        face, note = select_face(faces, spec.face, min_width=max(MIN_FACE_WIDTH_MM, spec.cutting.tool_diameter))
    except FeatureError as error:                     # about this file's faces: say which file
        raise InputError(str(error), path=spec.part) from error
    path_part = plan(spec, face)
    try:
        post = post_process(spec.machine, path_part, spec.setup, tolerance=spec.tolerance,
                            length_decimals=spec.dialect.decimals.length)
    except (LimitError, ReachError) as error:          # say the setup, and one that fits if there is one
        raise placement_error(error, spec.machine, path_part, spec.setup, tolerance=spec.tolerance,
                              length_decimals=spec.dialect.decimals.length) from error
    entries = header_entries(header_of(spec, file_sha256(spec.part)), face, description=spec.machine.description)
    text = emit_program(post.program, spec.dialect, header=entries,
                        stage=spec.machine.stage.present, line_numbers=spec.line_numbers,
                        line_start=spec.line_start, line_step=spec.line_step)
    return JobResult(text=text, face=face, face_note=note, path_part=path_part, post=post, setup=spec.setup,
                     triangles=np.asarray(mesh.triangles, dtype=np.float64))


def _file_given(source: str, kind: str, name: str) -> str | None:
    """The path a machine or dialect was given by, or None for a shipped one (``machines/NAME.toml``)."""
    return None if source == f"{kind}/{name}.toml" else source


def header_of(spec: JobSpec, part_sha256: str) -> ProgramHeader:
    """What the program header records of ``spec`` (the part by its file name and SHA-256)."""
    return ProgramHeader(
        version=f"prs3-post {__version__}", machine=spec.machine.name,
        machine_file=_file_given(spec.machine.source, "machines", spec.machine.name),
        dialect=spec.dialect.name, dialect_file=_file_given(spec.dialect.source, "dialects", spec.dialect.name),
        part_name=Path(spec.part).name, part_sha256=part_sha256, units=spec.units, up=spec.up, face=spec.face,
        face_index=-1 if spec.face is None else spec.face, setup=spec.setup, work=spec.work,
        at_uv=np.asarray(spec.at_uv, dtype=np.float64).reshape(-1, 2),
        at_xyz=np.asarray(spec.at_xyz, dtype=np.float64).reshape(-1, 3), cutting=spec.cutting,
        tolerance=spec.tolerance, line_numbers=spec.line_numbers, line_start=spec.line_start,
        line_step=spec.line_step,
    )


def spec_from_header(header: ProgramHeader, part: str, machine: Machine, dialect: Dialect) -> JobSpec:
    """The JobSpec a program header records, on the part file ``part`` (the caller checks that it is
    the recorded part) with the machine and dialect the header names (loaded by the caller)."""
    return JobSpec(
        part=part, units=header.units, face=header.face, work=header.work, at_uv=header.at_uv,
        at_xyz=header.at_xyz, cutting=header.cutting, machine=machine, dialect=dialect, setup=header.setup,
        tolerance=header.tolerance, line_numbers=header.line_numbers, line_start=header.line_start,
        line_step=header.line_step, up=header.up,
    )
