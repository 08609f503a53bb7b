"""The listing use cases: the shipped machines and source conventions, the bundled demo part, a part's faces."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from prs3_post.core.errors import FeatureError
from prs3_post.machine.loading import Machine, load_machine, load_source, postproc_dir, shipped_names

if TYPE_CHECKING:
    from prs3_post.machine.cam_conventions import SourceConvention

__all__ = ["demo_part", "faces_json", "faces_text", "shipped_machines", "shipped_sources"]


def shipped_machines() -> list[tuple[str, Machine]]:
    """Every shipped machine, by name (``postproc/machines``), loaded."""
    return [(name, load_machine(name)) for name in shipped_names("machines")]


def shipped_sources() -> list[tuple[str, SourceConvention]]:
    """Every shipped 5-axis source convention, by name (``postproc/sources``), loaded."""
    return [(name, load_source(name)) for name in shipped_names("sources")]


def demo_part() -> Path:
    """The bundled demo part: the paper's wedge."""
    return postproc_dir() / "parts" / "patel2020-wedge.stl"


def faces_json(part: str, *, units: str, up: str) -> str:
    """A part's faces as JSON (:func:`~prs3_post.part.faces.face_table`)."""
    from prs3_post.part.faces import face_table, find_faces
    from prs3_post.part.stl import load_part

    return json.dumps(face_table(find_faces(load_part(part, units=units, up=up))), indent=2, allow_nan=False)


def faces_text(part: str, *, units: str, up: str, spell: Callable[[str], str] = str) -> str:
    """A part's faces as a table, and the automatic choice (or why there is none) on the last line (the
    keys it names as ``spell`` words them: the command line's flags)."""
    from prs3_post.part.faces import find_faces, format_face_table, select_face
    from prs3_post.part.stl import load_part

    found = find_faces(load_part(part, units=units, up=up))
    try:
        choice = select_face(found, None)[1]
    except FeatureError as error:
        choice = f"auto: {error.worded(spell)}"
    return format_face_table(found) + choice + "\n"
