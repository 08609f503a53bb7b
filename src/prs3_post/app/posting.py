"""Post-process a toolpath of your own: part-frame tips, axes and feeds in, G-code text out.

The main job and ``convert`` make their toolpaths from a part or a CAM file; :func:`post_toolpath`
takes one made by the caller (:class:`~prs3_post.core.toolpath.Toolpath`, a struct of arrays) and
runs it through the same pipeline: the setup, the exact inverse kinematics, the subdivision of
moves that turn the tool axis, every point checked against every limit, and the emitter.
"""

from __future__ import annotations

from prs3_post.app.kinematics import machine_of
from prs3_post.app.streaming import program_text
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.toolpath import Toolpath
from prs3_post.machine.loading import DEFAULT_DIALECT, DEFAULT_MACHINE, Dialect, Machine, load_dialect
from prs3_post.part.setup_transform import Setup

__all__ = ["post_toolpath"]


def post_toolpath(path: Toolpath, *, machine: Machine | str = DEFAULT_MACHINE, dialect: Dialect | str = DEFAULT_DIALECT,
                  setup: Setup | None = None, tolerance: float = DEFAULT_TOLERANCE,
                  angle_tolerance: float = DEFAULT_ANGLE_TOLERANCE) -> str:
    """The G-code program of a part-frame toolpath, checked against every limit of the machine.

    Parameters
    ----------
    path : Toolpath — rows in part coordinates: ``kind`` (N,) MoveKind, ``tip`` (N, 3) mm, ``axis``
        (N, 3) unit from the tip toward the spindle, ``feed`` (N,) mm/min (0 on rapids), ``source`` (N,)
    machine : Machine | str — a loaded machine, a shipped machine's name or a machine TOML path
    dialect : Dialect | str — a loaded dialect, a shipped dialect's name or a dialect TOML path
    setup : Setup | None — where the part sits on the machine (None: the machine file's default setup)
    tolerance : float — mm, tip deviation allowed on moves whose axis changes
    angle_tolerance : float — rad, tool-axis deviation allowed on moves whose axis changes

    Returns
    -------
    str — the program, in actuator space (stage X, Y and the strokes), in the dialect's words

    Raises
    ------
    ReachError, LimitError
        A pose out of reach, or a point outside a machine limit (naming the row's ``source``).
    ConfigError
        A machine or dialect file that is wrong.
    """
    loaded = machine_of(machine)
    words = load_dialect(dialect) if isinstance(dialect, str) else dialect
    placed = Setup.resolve(loaded) if setup is None else setup
    return "".join(program_text(loaded, [path], placed, words, tolerance=tolerance, angle_tolerance=angle_tolerance))
