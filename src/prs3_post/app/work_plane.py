"""A work plane as a user gives it (``--work-plane``): a face of an STL part, which is loaded here,
or numbers (:class:`~prs3_post.part.workplane.WorkPlane` is the plane itself, and loads nothing).
"""

from __future__ import annotations

import os
import re

from prs3_post.core.errors import InputError
from prs3_post.core.numbers import short_tuple
from prs3_post.part.workplane import WorkPlane, WorkPlaneError

__all__ = ["WorkPlaneError", "work_plane_from_part", "work_plane_from_text"]


def work_plane_from_part(path: str | os.PathLike[str], face: int | None = None, *, units: str = "mm",
                         up: str = "z") -> tuple[WorkPlane, str]:
    """The work plane on a face of an STL part: program X, Y, Z = the face frame u, v, w of the main job.

    Parameters
    ----------
    path : the STL file; units, up : as :func:`prs3_post.part.stl.load_part`
    face : int or None — the face's index (it must face up), or None: the face the main job picks
        automatically (the largest upward-facing inclined face)

    Returns
    -------
    plane : WorkPlane — named ``face N of NAME``
    note : str — how the face was picked (:func:`prs3_post.part.faces.select_face`'s note)

    Raises
    ------
    InputError, FeatureError
        From loading the part and selecting the face.
    """
    from prs3_post.part.faces import find_faces, select_face  # trimesh and shapely load only when needed
    from prs3_post.part.stl import load_part

    chosen, note = select_face(find_faces(load_part(path, units=units, up=up)), face)
    return WorkPlane.from_face(chosen, name=f"face {chosen.index} of {os.path.basename(os.fspath(path))}"), note


_NUMBERS = re.compile(r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*(?:,\s*[-+]?(?:\d+\.?\d*|\.\d+)"
                      r"(?:[eE][-+]?\d+)?\s*)*")


def work_plane_from_text(text: str, *, units: str = "mm", up: str = "z") -> tuple[WorkPlane, str]:
    """A work plane as a user writes it: ``PART.stl[:FACE]`` or ``OX,OY,OZ,NX,NY,NZ[,XX,XY,XZ]`` (mm).

    Returns
    -------
    plane : WorkPlane
    note : str — how it was made (the face selection's note, or the numbers read)

    Raises
    ------
    WorkPlaneError
        Numbers that make no plane (:meth:`WorkPlane.from_values`).
    InputError, FeatureError
        As :func:`work_plane_from_part`; ``TEXT: file not found, and not 6 or 9 plain decimal numbers: ...``
        for text that is neither numbers nor a file (``nan``).

    >>> work_plane_from_text("0,0,5,0,0,1")[0].origin.tolist()
    [0.0, 0.0, 5.0]
    """
    if _NUMBERS.fullmatch(text):
        plane = WorkPlane.from_values([float(v) for v in text.split(",")])
        return plane, f"{plane.name}: origin {short_tuple(plane.origin)} mm, normal {short_tuple(plane.normal)}"
    path, colon, index = text.rpartition(":")
    if not (colon and index.strip().isdigit() and index.strip().isascii()):
        if colon and os.path.lexists(path) and not os.path.lexists(text):     # `part.stl:-1`: the file is there
            raise InputError(f"the face after ':' must be a face number (0, 1, ... as `prs3-post faces` lists them), "
                             f"got {index!r}", path=text)
        path, index = text, ""
    if not os.path.lexists(path):                     # `nan`, `1,2,x`: say what a work plane is, not only "no file"
        raise InputError("file not found, and not 6 or 9 plain decimal numbers: a work plane is PART.stl[:FACE] or "
                         "OX,OY,OZ,NX,NY,NZ[,XX,XY,XZ] (mm)", path=text)
    return work_plane_from_part(path, int(index) if index else None, units=units, up=up)
