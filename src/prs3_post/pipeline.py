"""From a part-frame toolpath to a checked actuator-space program.

    part toolpath ──► setup (part → machine) ──► subdivide axis changes ──► IK ──► reach
                  ──► drop moves the output cannot show ──► limits ──► G93 feeds ──► JointProgram

Pure: no files. The first failure is raised with the operation step (or source line) it came
from; nothing is emitted for a program that has one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.config import Machine
from prs3_post.errors import LimitError, ReachError
from prs3_post.kinematics import IKModel, IKResult, PoseError, inverse, unit_axes
from prs3_post.limits import LimitReport, check_limits, raise_first_violation
from prs3_post.linearize import subdivide_axis_changes
from prs3_post.resolution import visible_moves
from prs3_post.setup import Setup
from prs3_post.toolpath import JointProgram, MoveKind, Toolpath
from prs3_post.types import FloatArray


def place_toolpath(path: Toolpath, setup: Setup) -> Toolpath:
    """The part-frame toolpath in the machine frame: tips and axes carried through the setup."""
    return Toolpath(
        kind=path.kind, tip=setup.points_to_machine(path.tip), axis=setup.axes_to_machine(path.axis), feed=path.feed,
        source=path.source, events=path.events, source_labels=path.source_labels,
    )


@dataclass(frozen=True, slots=True)
class PostResult:
    """A checked program and what it was made from.

    Attributes
    ----------
    program : JointProgram — ready to emit
    path : Toolpath — the machine-frame toolpath after subdivision (one row per program row)
    ik : IKResult — per row
    limits : LimitReport — per row (all ok)
    """

    program: JointProgram
    path: Toolpath
    ik: IKResult
    limits: LimitReport


def model_for(machine: Machine) -> IKModel:
    """The IK model a machine runs: exact with a stage, head alone without one."""
    return IKModel.EXACT if machine.stage.present else IKModel.HEAD


def machine_path(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float = 0.002) -> Toolpath:
    """The part-frame toolpath placed on the machine, with unit axes, its axis-changing moves subdivided.

    Raises
    ------
    ReachError
        A zero or downward tool axis.
    """
    path = place_toolpath(path_part, setup)
    try:
        unit = unit_axes(path.tip, path.axis)
    except PoseError as error:
        raise ReachError(f"toolpath: {error}") from error
    path = Toolpath(kind=path.kind, tip=path.tip, axis=unit, feed=path.feed, source=path.source,
                    events=path.events, source_labels=path.source_labels)
    return subdivide_axis_changes(machine.geometry, path, tolerance=tolerance)


def post_process(machine: Machine, path_part: Toolpath, setup: Setup, *, tolerance: float = 0.002,
                 length_decimals: int | None = None) -> PostResult:
    """Turn a part-frame toolpath into a checked joint-space program.

    Parameters
    ----------
    machine : Machine
    path_part : Toolpath — part coordinates
    setup : Setup — part → machine transform
    tolerance : float — mm, tip deviation allowed on moves whose axis changes
    length_decimals : int, optional — digits after the point of the program's axis words: rows
        that would print no changed axis word are dropped (None: keep every row)

    Returns
    -------
    PostResult

    Raises
    ------
    ReachError
        A pose that does not assemble, or that a machine without a stage cannot reach.
    LimitError
        A point outside a machine limit, or a feed move with zero length.
    """
    path = machine_path(machine, path_part, setup, tolerance=tolerance)
    model = model_for(machine)
    ik = inverse(machine.geometry, path.tip, path.axis, model=model)
    _raise_unreachable(machine, path, ik, model)
    stage = ik.stage if model is IKModel.EXACT else np.zeros_like(ik.stage)
    if length_decimals is not None:                   # no move the program cannot show (a G1 without a word)
        keep = visible_moves(np.column_stack([stage, ik.strokes]), length_decimals, tip=path.tip, axis=path.axis)
        if not keep.all():
            path, stage = path.take(keep), stage[keep]
            ik = IKResult(stage=ik.stage[keep], strokes=ik.strokes[keep], link_angle=ik.link_angle[keep],
                          condition=ik.condition[keep], reachable=ik.reachable[keep])
    report = check_limits(machine, ik, path.axis)
    raise_first_violation(report, path.describe)
    return PostResult(
        program=JointProgram(
            kind=path.kind, stage=stage, strokes=ik.strokes, inverse_time=inverse_time(path),
            source=path.source, events=path.events, source_labels=path.source_labels,
        ),
        path=path,
        ik=ik,
        limits=report,
    )


def _raise_unreachable(machine: Machine, path: Toolpath, ik: IKResult, model: IKModel) -> None:
    bad = np.flatnonzero(~ik.reachable)
    if not len(bad):
        return
    row = int(bad[0])
    where = path.describe(row)
    tip = ", ".join(f"{v:.4f}" for v in path.tip[row])
    count = f" ({len(bad)} points unreachable in all)" if len(bad) > 1 else ""
    if model is IKModel.HEAD and np.isfinite(ik.stage[row]).all():
        dx, dy = ik.stage[row]
        raise ReachError(
            f"{where}: machine {machine.name} has no stage and its head alone misses the tip ({tip}) by "
            f"{np.hypot(dx, dy):.4f} mm (x {dx:.4f}, y {dy:.4f}){count}"
        )
    raise ReachError(f"{where}: the head cannot reach the tip ({tip}) mm with this axis: a link cannot reach "
                     f"its joint (check --part-origin){count}")


def inverse_time(path: Toolpath) -> FloatArray:
    """G93 F words: tip feed / tip path length of each FEED row (1/min); 0 for RAPID rows.

    Every move's tip path is the straight line between its end points (moves whose axis changes
    were subdivided until the joint-space line stays within tolerance of it).

    Raises
    ------
    LimitError
        A FEED row as the first row (no start point) or with zero length (no time to give it).
    """
    feed_rows = np.flatnonzero(path.kind == MoveKind.FEED)
    out = np.zeros(len(path))
    if not len(feed_rows):
        return out
    if feed_rows[0] == 0:
        raise LimitError(f"{path.describe(0)}: the program starts with a feed move; its start point is unknown")
    length = np.linalg.norm(path.tip[feed_rows] - path.tip[feed_rows - 1], axis=1)
    zero = np.flatnonzero(length < 1e-9)
    if len(zero):
        raise LimitError(f"{path.describe(int(feed_rows[zero[0]]))}: feed move of zero length")
    out[feed_rows] = path.feed[feed_rows] / length
    return out
