"""Between two operations of a job: the tool rises along its axis to a safe height, the axis turns
there (a reorientation checked like any move), and the tool goes over to the next operation's start.

The rows are made in the machine frame (:data:`MACHINE_FRAME`) and post-processed with each tool's
length, so that a tool change between the lift and the turn is where the program changes it.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.toolpath import MoveKind, Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.machine.loading import Machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.linearize import slerp, subdivide_axis_changes
from prs3_post.post.pipeline import PostResult, post_process

__all__ = ["MACHINE_FRAME", "REORIENT_STEP", "post_transition", "safe_height", "transition_paths"]


def safe_height(triangles: FloatArray, setup: Setup, retract: float) -> float:
    """mm, machine z of the transitions between operations: the part's highest point plus ``retract``,
    the largest of the operations' (the tool tip there is above every point of the part, and so is
    the whole tool, whose axis points up)."""
    top = float(setup.points_to_machine(triangles.reshape(-1, 3))[:, 2].max())
    return top + retract


#: rad, the largest axis turn between two rows of a reorientation before subdivision checks it.
REORIENT_STEP = math.radians(5.0)


def transition_paths(before: Toolpath, after: Toolpath, lengths: tuple[float, float], height: float, *,
                     labels: tuple[str, str]) -> tuple[Toolpath, Toolpath]:
    """The rows between two operations (machine frame), as two pieces: (lift, turn and approach).

    ``before``'s last row is the first operation's end (its retract height above its face), ``after``'s
    first row the second's start (above its first feature). The lift (first tool) goes up along the
    current axis until the next tool's tip would be at ``height`` (at least), so that it is there
    after the change. The second piece (next tool) turns the axis
    there with the tip fixed, on the great circle, as RAPID rows every :data:`REORIENT_STEP` at most
    (its first row repeats the lift's end pose, for the subdivision to start from: drop it after
    IK), then goes over to ``height`` above the next start; the next operation's first row goes down.

    Parameters
    ----------
    before, after : Toolpath — machine frame, unit axes
    lengths : (first, next) float — mm, tool lengths "TL"
    height : float — mm, machine z of the transition
    labels : (lift label, turn label)
    """
    tip_a, axis_a = before.tip[-1], before.axis[-1]
    tip_b, axis_b = after.tip[0], after.axis[0]
    longer = max(0.0, lengths[1] - lengths[0])
    # the next tool's tip (at the same joints: longer·axis below) at ``height``; axis_z > 0: a tool points up
    rise = max(0.0, (height + longer * axis_a[2] - tip_a[2]) / axis_a[2])
    lifted = tip_a + rise * axis_a
    rows = 1 if rise > 0.0 else 0                                  # already there: no lift
    lift = _rapids(np.tile(lifted, (rows, 1)), np.tile(axis_a, (rows, 1)), labels[0])
    turn_at = lifted - (lengths[1] - lengths[0]) * axis_a          # the next tool's tip, same joints
    angle = math.acos(min(1.0, max(-1.0, float(axis_a @ axis_b))))
    steps = max(1, math.ceil(angle / REORIENT_STEP))
    fractions = np.linspace(0.0, 1.0, steps + 1)
    axes = slerp(np.tile(axis_a, (steps + 1, 1)), np.tile(axis_b, (steps + 1, 1)), fractions)
    over = max(0.0, (height - tip_b[2]) / axis_b[2])
    tips = np.vstack([np.tile(turn_at, (steps + 1, 1)), tip_b + over * axis_b])
    turn = _rapids(tips, np.vstack([axes, axis_b]), labels[1])
    return lift, turn


def _rapids(tip: FloatArray, axis: FloatArray, label: str) -> Toolpath:
    """RAPID rows at the given poses, all of step ``label``."""
    count = len(tip)
    return Toolpath(kind=np.full(count, MoveKind.RAPID), tip=tip, axis=axis, feed=np.zeros(count),
                    source=np.zeros(count, dtype=np.int64), source_labels=(label,))


def post_transition(machine: Machine, before: Toolpath, after: Toolpath, lengths: tuple[float, float],
                    height: float, *, labels: tuple[str, str], tolerance: float = DEFAULT_TOLERANCE,
                    length_decimals: int | None = None) -> tuple[PostResult | None, PostResult]:
    """The transition between two operations (:func:`transition_paths`), checked: the lift with the
    first tool (None when the tool is already high enough) and the turn and approach with the next,
    the turn subdivided like any move whose axis changes (until the joint-space line between rows
    stays within ``tolerance`` of the fixed tip), then IK and limits on every row.

    Raises
    ------
    LimitError, ReachError
        A row of the transition outside a limit (the label names it).
    """
    lift, turn = transition_paths(before, after, lengths, height, labels=labels)
    lifted = None
    if len(lift):
        lifted = post_process(machine.with_tool_length(lengths[0]), lift, MACHINE_FRAME,
                              length_decimals=length_decimals,
                              tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    next_tool = machine.with_tool_length(lengths[1])
    as_feed = replace(turn, kind=np.full(len(turn), MoveKind.FEED))
    fine = subdivide_axis_changes(next_tool.geometry, as_feed, tolerance=tolerance,
                                  angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    fine = replace(fine, kind=np.full(len(fine), MoveKind.RAPID))
    keep = np.ones(len(fine), dtype=bool)
    keep[0] = False                                    # the lift's end again, for the subdivision to start from
    return lifted, post_process(next_tool, fine.take(keep), MACHINE_FRAME, length_decimals=length_decimals,
                                tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)


#: The identity setup: machine-frame rows (the transitions) go through the same post-processing.
MACHINE_FRAME = Setup((0.0, 0.0, 0.0), 0.0)
