"""prs3-post: the post-processor for 3-PRS parallel-kinematic machines.

The library's front door: the use cases of :mod:`prs3_post.app`, each with typed parameters and a
docstring (see ``docs/api.md``). They load when first used, so ``import prs3_post`` stays cheap.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from prs3_post.core.version import __version__

if TYPE_CHECKING:
    from prs3_post.app.convert_files import convert_files
    from prs3_post.app.kinematics import forward_kinematics, inverse_kinematics
    from prs3_post.app.posting import post_toolpath
    from prs3_post.app.run import post_part, run_job_file
    from prs3_post.app.verify import verify_program_file
    from prs3_post.core.toolpath import Event, EventKind, MoveKind, Toolpath
    from prs3_post.part.setup_transform import Setup

#: Each public name and the module that holds it (imported on first use).
_HOMES = {
    "Event": "prs3_post.core.toolpath",
    "EventKind": "prs3_post.core.toolpath",
    "MoveKind": "prs3_post.core.toolpath",
    "Setup": "prs3_post.part.setup_transform",
    "Toolpath": "prs3_post.core.toolpath",
    "convert_files": "prs3_post.app.convert_files",
    "forward_kinematics": "prs3_post.app.kinematics",
    "inverse_kinematics": "prs3_post.app.kinematics",
    "post_part": "prs3_post.app.run",
    "post_toolpath": "prs3_post.app.posting",
    "run_job_file": "prs3_post.app.run",
    "verify_program_file": "prs3_post.app.verify",
}

__all__ = ["Event", "EventKind", "MoveKind", "Setup", "Toolpath", "__version__", "convert_files",
           "forward_kinematics", "inverse_kinematics", "post_part", "post_toolpath", "run_job_file",
           "verify_program_file"]


def __getattr__(name: str) -> Any:
    """A public name, imported from its module when first asked for."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'prs3_post' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(home), name)
    globals()[name] = value
    return value
